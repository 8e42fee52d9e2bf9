"""Atomic file writes: write a temporary sibling, then `os.replace` it over the target."""
from __future__ import annotations

import os
import uuid
from pathlib import Path


def temporary_sibling(path: Path) -> Path:
    """A unique temporary name next to `path` (same filesystem, so the final rename is atomic).

    Not `tempfile.mkstemp`: its 0600 mode would make files unreadable to other users of a shared folder.
    """
    path = Path(path)
    return path.with_name(f"{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
