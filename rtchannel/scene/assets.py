"""Where the project's data files live (avatar, scenes). The package is installed in editable mode
from the repository, so the folders beside the package are the source of truth."""
from __future__ import annotations

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]


def avatar_dir() -> Path:
    """Folder holding the CC0 avatar mesh, rig and skinning weights."""
    return REPO_ROOT / "meshes" / "avatar"


def scenes_dir() -> Path:
    """Folder holding the Mitsuba scene files."""
    return REPO_ROOT / "scenes"

