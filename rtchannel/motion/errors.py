"""Errors raised by the motion importers."""
from __future__ import annotations

from processing.errors import InputError


class MotionImportError(InputError):
    """A motion file cannot be imported; the message names the file and the line or frame at fault."""

    def __init__(self, path, message: str, *, line: int | None = None, frame: int | None = None) -> None:
        where = f", line {line}" if line is not None else ""
        where += f", frame {frame}" if frame is not None else ""
        super().__init__(f"{path}{where}: {message}")
        self.path = str(path)
        self.line = line
        self.frame = frame
