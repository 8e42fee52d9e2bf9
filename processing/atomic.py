"""Atomic file writes: every output of the tool goes through `atomic_path` (or a helper built on it).

The writer fills a temporary sibling with a unique name (pid + random), the file is fsynced, renamed
over the target with `os.replace`, and the folder is fsynced, so a reader (or a resumed run) sees the
old file or the complete new one, never a torn one, even after a power cut; a failed write (full disk,
killed process, exception) leaves no partial target and removes its temporary file. Temporary files
end in ``.tmp`` so `processing.io.dataset_store.remove_orphans` can clean up after a killed writer.
"""
from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def temporary_sibling(path: Path) -> Path:
    """A unique temporary name next to `path` (same filesystem, so the final rename is atomic).

    Not `tempfile.mkstemp`: its 0600 mode would make files unreadable to other users of a shared folder.
    """
    path = Path(path)
    return path.with_name(f"{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def fsync_dir(folder: Path) -> None:
    """Make a rename inside `folder` durable (no-op where directories cannot be opened, e.g. Windows)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextmanager
def atomic_path(path: str | Path, *, mkdir: bool = True) -> Iterator[Path]:
    """Context manager yielding a temporary path to write; on success it replaces `path` atomically.

    ``with atomic_path(out) as tmp: h5py.File(tmp, "w") ...`` - the writer must have closed the file
    when the block ends. Raises what the writer raised (the temporary file is removed).
    """
    path = Path(path)
    if mkdir:
        path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temporary_sibling(path)
    try:
        yield tmp
        _fsync(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    fsync_dir(path.parent)


def write_bytes_atomic(path: str | Path, data: bytes) -> Path:
    """Write `data` to `path` atomically; returns the path."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)
    return Path(path)


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write `text` (UTF-8) to `path` atomically; returns the path."""
    return write_bytes_atomic(path, text.encode("utf-8"))


def savefig_atomic(fig, path: str | Path, **kwargs) -> Path:
    """`fig.savefig` to `path` atomically (the format comes from the target's suffix, not the .tmp)."""
    path = Path(path)
    kwargs.setdefault("format", path.suffix.lstrip(".").lower() or "png")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, **kwargs)
    return path


__all__ = ["atomic_path", "fsync_dir", "savefig_atomic", "temporary_sibling", "write_bytes_atomic",
           "write_text_atomic"]
