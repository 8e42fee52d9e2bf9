"""Third-party test data (motion capture, real Glasgow images) through the data registry.

A test that needs such a file runs when the local mirror (``../shared`` beside the checkout or
``RTCHANNEL_DATA_MIRROR``) or the user cache holds it, and otherwise skips with a reason saying how to
get it (``rtchannel data fetch``). Tests never download.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from rtchannel.data_registry import DataUnavailableError, entries, fetch

# the twelve real images the image-reader tests use: P36 and P46, activities 1-6, repetition 1
GLASGOW_TEST_IMAGES = [f"realdata/glasgow848/1Dataset/{k}P{p}A0{k}R01.png" for p in (36, 46) for k in range(1, 7)]
# the list of all 360 campaign-1 images (file names only; made for this project, no image data)
GLASGOW_INDEX = Path(__file__).parent / "data" / "glasgow_index.csv"


def data_path(relpath: str) -> Path:
    """Local path of a registered file, or skip the calling test with how to get it."""
    try:
        return fetch(relpath, download=False)
    except DataUnavailableError as e:
        pytest.skip(str(e))


def registered(pattern: str) -> list[str]:
    """Registry paths matching `pattern` (known without the data, so tests can be parametrised on them)."""
    return [e.path for e in entries(pattern)]


def glasgow_folder(dest: Path) -> Path:
    """A folder holding (links to) the twelve test images, for commands that read a folder of images."""
    dest.mkdir(parents=True, exist_ok=True)
    for rel in GLASGOW_TEST_IMAGES:
        link = dest / Path(rel).name
        if not link.exists():
            link.symlink_to(data_path(rel))
    return dest


def where(relpath: str) -> Path:
    """Local path of a registered file if present, else where the mirror would hold it (for module-level
    constants; pair with `needs`, which skips when it is absent)."""
    from rtchannel.data_registry import local_path, mirror_dir

    found = local_path(relpath)
    return found if found is not None else (mirror_dir() or Path("missing-mirror")) / relpath


def needs(*relpaths: str):
    """A skipif mark: skip unless every registered file in `relpaths` is present locally."""
    from rtchannel.data_registry import how_to_get, local_path

    missing = [p for p in relpaths if local_path(p) is None]
    return pytest.mark.skipif(bool(missing), reason=how_to_get(missing[0]) if missing else "")


def glasgow_folder_if_available() -> Path:
    """For module-level constants: a temporary folder of the twelve test images when they are available
    (else a path that does not exist); tests using it carry `needs(*GLASGOW_TEST_IMAGES)`."""
    import atexit
    import shutil
    import tempfile

    from rtchannel.data_registry import local_path

    if any(local_path(p) is None for p in GLASGOW_TEST_IMAGES):
        return Path("glasgow-test-images-not-available")
    dest = Path(tempfile.mkdtemp(prefix="glasgow-"))
    atexit.register(shutil.rmtree, dest, True)
    return glasgow_folder(dest)
