"""The user-error types of the whole tool, collected in `USER_ERRORS`.

Every one of them carries a one-line message naming the file and line/field at fault; the command line
(`rtchannel.cli.main`) prints it after ``error:`` and exits with status 2. Any other exception is a bug.

* `processing.errors.InputError` (a ValueError) and its subclasses:
  `MotionImportError` (BVH/C3D files), `AncortekFormatError` (`.dat` recordings), `CheckpointError`,
  `TrainingError`, `DatasetFormatError` (index/plan/shards), `PlanMismatchError`, `ConfigError`
  (radar/plan/option files and values), `SceneFileError` (scene XML sandbox and Mitsuba load errors),
  `RadarPlacementError` (an antenna inside or touching the scene or the body);
* pydantic's `ValidationError` (a configuration field out of range; the CLI names the first field).

Import-light on purpose (no numpy/torch/h5py): the CLI imports it before any command runs.
"""
from __future__ import annotations

from pydantic import ValidationError

from processing.errors import CheckpointError, DatasetFormatError, InputError, TrainingError


class ConfigError(InputError):
    """A configuration file or value that cannot be used (syntax, type, size or range)."""


class SceneFileError(InputError):
    """A scene file outside the sandbox, malformed, or rejected by Mitsuba (message never quotes file content)."""


class RadarPlacementError(InputError):
    """An antenna is too close to (or inside) scene geometry or the body."""


# appended to errors about the body reaching an antenna: the options that move the person
MOVE_THE_PERSON = ("; move the person (CLI --start X Y / --heading DEG / --trim, plan motion starts and "
                   "headings_deg, API Motion.transformed) or the radar")


USER_ERRORS: tuple[type[BaseException], ...] = (InputError, ValidationError)

__all__ = ["MOVE_THE_PERSON", "USER_ERRORS", "InputError", "ConfigError", "SceneFileError", "RadarPlacementError",
           "CheckpointError", "TrainingError", "DatasetFormatError"]
