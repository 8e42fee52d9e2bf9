"""Where the project's own data files live: the CC0 avatar and furniture meshes (`meshes/`) and the Mitsuba
scenes (`scenes/`).

The repository keeps them at its top level; the build copies them into the package as
``rtchannel/_assets/{meshes,scenes}`` (`setup.py`), so an installed wheel reads them with
`importlib.resources`. A source checkout (editable install, or running from the repository) has no copy
inside the package and uses the folders beside it. Third-party data is not here: see `data_registry`.
"""
from __future__ import annotations

from functools import lru_cache
from importlib import resources
from pathlib import Path

from processing.errors import InputError

ASSET_FOLDERS = ("meshes", "scenes")
PACKAGED = "_assets"  # sub-folder of the installed package that holds the copies


@lru_cache(maxsize=None)
def asset_root(name: str) -> Path:
    """Folder of the asset tree `name` ("meshes" or "scenes"): packaged copy first, else the checkout's."""
    if name not in ASSET_FOLDERS:
        raise InputError(f"unknown asset folder {name!r} (one of {', '.join(ASSET_FOLDERS)})")
    packaged = resources.files("rtchannel").joinpath(PACKAGED, name)
    if packaged.is_dir():
        return Path(str(packaged))
    return Path(__file__).resolve().parents[1] / name


def avatar_dir() -> Path:
    """Folder holding the CC0 avatar mesh, rig and skinning weights."""
    return asset_root("meshes") / "avatar"


def furniture_dir() -> Path:
    """Folder holding the furniture meshes (the chair)."""
    return asset_root("meshes") / "furniture"


def scenes_dir() -> Path:
    """Folder holding the Mitsuba scene files."""
    return asset_root("scenes")
