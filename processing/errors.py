"""Errors that mean "the user's input is wrong", as opposed to a bug in this code.

Every reader and validator of user input raises a subclass of `InputError` whose message is one line
naming the file and the line, frame or field at fault (and never echoing file content beyond a short
token). The command line prints that line and exits with status 2; anything else is a bug and keeps
its traceback. This module is import-free (no numpy, torch, h5py) so the CLI can catch these types
without loading the libraries that raise them. `rtchannel.errors.USER_ERRORS` collects them.
"""
from __future__ import annotations


class InputError(ValueError):
    """Bad user input (file, configuration or argument); the message is one line naming where."""


class CheckpointError(InputError):
    """A classifier checkpoint that is missing, unreadable, incomplete or inconsistent."""


class TrainingError(InputError):
    """Training that cannot give a usable model (non-finite loss or inputs); nothing is saved."""


class DatasetFormatError(InputError):
    """A dataset folder whose index, plan or shards cannot be read as written by the runner."""


def one_line(text: object, limit: int = 200) -> str:
    """`text` as a single line of at most `limit` characters (for messages quoting library errors)."""
    s = " ".join(str(text).split())
    return s if len(s) <= limit else s[:limit - 3] + "..."


__all__ = ["InputError", "CheckpointError", "TrainingError", "DatasetFormatError", "one_line"]
