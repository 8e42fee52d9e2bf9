"""Third-party data (motion capture, real radar images) fetched on demand, never shipped.

Every file the project may use is listed in `data_registry.csv` (package data): its path in the data
layout (``mocap/cmu/walk/02_01_iclone.bvh``, ``realdata/glasgow848/1Dataset/1P36A01R01.png``), sha256,
size, the origin URL (a fixed commit of a public repository) and its licence. A file is looked for, in
this order, and used only if its sha256 matches:

1. a local mirror laid out like the registry paths: the folder named by ``RTCHANNEL_DATA_MIRROR``, else a
   folder ``shared`` beside the checkout (found automatically; machines without internet use it);
2. the user cache: ``RTCHANNEL_DATA_CACHE``, else platformdirs' user cache folder ``rtchannel/data``;
3. the origin URL, downloaded with pooch into the cache (checked by sha256, with a progress bar).

Why pooch and a mirror: scikit-image and MNE fetch their data the same way; the mirror is how CI and
offline machines get the data, since none of them reaches the origins. Import-light (no numpy).
"""
from __future__ import annotations

import csv
import fnmatch
import hashlib
import os
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path

from processing.errors import InputError

MIRROR_ENV = "RTCHANNEL_DATA_MIRROR"
CACHE_ENV = "RTCHANNEL_DATA_CACHE"
DATA_PREFIX = "data:"  # how plans and options name a registry path instead of a local file


class DataUnavailableError(InputError):
    """A registered third-party file that is neither in the mirror nor in the cache and cannot be fetched."""


@dataclass(frozen=True)
class Entry:
    """One registered file: `path` in the data layout, its sha256 and size [bytes], origin URL and licence."""

    path: str
    sha256: str
    size: int
    url: str
    licence: str


@lru_cache(maxsize=1)
def registry() -> dict[str, Entry]:
    """Every registered file by path (read once from the packaged `data_registry.csv`)."""
    text = resources.files("rtchannel").joinpath("data_registry.csv").read_text(encoding="utf-8")
    rows = csv.DictReader(text.splitlines())
    return {r["path"]: Entry(r["path"], r["sha256"], int(r["bytes"]), r["origin_url"], r["licence"]) for r in rows}


def mirror_dir() -> Path | None:
    """The local mirror folder, or None: ``RTCHANNEL_DATA_MIRROR``, else ``shared`` beside the checkout."""
    env = os.environ.get(MIRROR_ENV)
    if env:
        return Path(env).expanduser()
    beside = Path(__file__).resolve().parents[1].parent / "shared"  # <checkout>/../shared
    return beside if beside.is_dir() else None


def cache_dir() -> Path:
    """The user cache folder for fetched files (``RTCHANNEL_DATA_CACHE`` overrides platformdirs')."""
    env = os.environ.get(CACHE_ENV)
    if env:
        return Path(env).expanduser()
    import platformdirs

    return Path(platformdirs.user_cache_dir("rtchannel")) / "data"


def entries(pattern: str = "*") -> list[Entry]:
    """Registered files whose path matches the glob `pattern` (a bare folder prefix matches everything
    under it), sorted by path."""
    pattern = pattern.rstrip("/")
    reg = registry()
    if pattern in reg:
        return [reg[pattern]]
    return [e for p, e in sorted(reg.items()) if fnmatch.fnmatch(p, pattern) or p.startswith(pattern + "/")]


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


@lru_cache(maxsize=None)
def _verified(path: str, mtime_ns: int, size: int, sha256: str) -> bool:
    # keyed on mtime and size, so each file is hashed once per process unless it changes
    return _sha256(Path(path)) == sha256


def _good(path: Path, entry: Entry) -> bool:
    try:
        st = path.stat()
    except OSError:
        return False
    return st.st_size == entry.size and _verified(str(path), st.st_mtime_ns, st.st_size, entry.sha256)


def local_path(relpath: str) -> Path | None:
    """Where a registered file already is with the right checksum (mirror first, then cache), or None."""
    entry = _entry(relpath)
    mirror = mirror_dir()
    for root in ([mirror] if mirror else []) + [cache_dir()]:
        p = root / entry.path
        if _good(p, entry):
            return p
    return None


def _entry(relpath: str) -> Entry:
    try:
        return registry()[relpath]
    except KeyError:
        raise InputError(f"{relpath}: not a registered data file (rtchannel data list shows them)") from None


def cache_file(relpath: str) -> Path:
    """Where the cache keeps the registered file `relpath`. InputError if a folder between the cache root and
    the file is a symbolic link: the cache never writes through a link (one planted there would send a
    download or a copy outside it). A link in the file's own place is replaced, never written through."""
    root = cache_dir()
    folder = root
    for part in Path(relpath).parts[:-1]:
        folder = folder / part
        if folder.is_symlink():
            raise InputError(f"data cache: {folder} is a symbolic link; the cache never writes through a link "
                             "(remove it, or set RTCHANNEL_DATA_CACHE to another folder)")
    return root / relpath


def how_to_get(relpath: str) -> str:
    """The one-line advice shown when a file is missing."""
    return (f"third-party data {relpath} is not available: run 'rtchannel data fetch {relpath}' (needs "
            f"internet), or set {MIRROR_ENV} to a folder laid out like the data registry")


def fetch(relpath: str, *, download: bool = True, progress: bool = False) -> Path:
    """Local path of a registered third-party file, downloading it into the cache if needed.

    Raises DataUnavailableError (one line saying how to get it) when it is in neither the mirror nor the
    cache and `download` is False or the download fails; InputError for a path that is not registered.

    Args:
        relpath: the file's path in the registry (e.g. "mocap/cmu/sit/75_17.bvh"; `rtchannel data list`).
        download: fetch it from its origin when neither the mirror nor the cache has it.
        progress: show a download progress bar.
    """
    found = local_path(relpath)
    if found is not None:
        return found
    entry = _entry(relpath)
    if not download:
        raise DataUnavailableError(how_to_get(relpath))
    import pooch

    target = cache_file(entry.path)  # pooch renames its download over the target: a link there is replaced
    try:
        got = pooch.retrieve(entry.url, known_hash=f"sha256:{entry.sha256}", fname=target.name,
                             path=target.parent, progressbar=progress)
    except Exception as e:  # noqa: BLE001 - no network, HTTP error, checksum mismatch: all mean "not here"
        raise DataUnavailableError(f"{how_to_get(relpath)} (download failed: {type(e).__name__})") from None
    return Path(got)


def fetch_many(pattern: str, *, download: bool = True, progress: bool = False) -> list[Path]:
    """Local paths of every registered file matching `pattern` (see `entries`); InputError if none does."""
    found = entries(pattern)
    if not found:
        raise InputError(f"{pattern}: no registered data file matches (rtchannel data list shows them)")
    return [fetch(e.path, download=download, progress=progress) for e in found]


def fetch_folder(prefix: str, *, download: bool = True, progress: bool = False) -> Path:
    """A local folder holding every registered file under the folder `prefix` (e.g.
    ``realdata/glasgow848/1Dataset``), for tools that read a whole folder: the mirror's when it has them
    all, else the cache's (files missing there are downloaded, or copied from the mirror)."""
    import shutil

    paths = fetch_many(prefix.rstrip("/"), download=download, progress=progress)
    folders = {p.parent for p in paths}
    if len(folders) == 1:
        return folders.pop()
    from processing.atomic import atomic_path

    for e, p in zip(entries(prefix.rstrip("/")), paths):
        target = cache_file(e.path)
        if p != target:  # copied beside and renamed over the target: a link planted there is replaced
            with atomic_path(target) as tmp:
                shutil.copyfile(p, tmp)
    return cache_dir() / prefix.rstrip("/")


def resolve_spec(spec: str, *, download: bool = True) -> list[Path]:
    """Files named by a plan/option value: ``data:PATTERN`` through the registry, else a local path as is."""
    if spec.startswith(DATA_PREFIX):
        return fetch_many(spec[len(DATA_PREFIX):], download=download)
    return [Path(spec).expanduser()]


def status(entry: Entry) -> str:
    """'mirror', 'cache' or 'missing' for one registered file (checksum verified)."""
    mirror = mirror_dir()
    if mirror is not None and _good(mirror / entry.path, entry):
        return "mirror"
    if _good(cache_dir() / entry.path, entry):
        return "cache"
    return "missing"


def licences() -> dict[str, list[str]]:
    """Registered paths grouped by licence text (for `rtchannel data list --licences` and the README)."""
    out: dict[str, list[str]] = {}
    for e in registry().values():
        out.setdefault(e.licence, []).append(e.path)
    return out


__all__ = ["DataUnavailableError", "Entry", "registry", "entries", "fetch", "fetch_many", "fetch_folder",
           "resolve_spec", "local_path", "mirror_dir", "cache_dir", "cache_file", "status", "licences", "how_to_get",
           "DATA_PREFIX", "MIRROR_ENV", "CACHE_ENV"]
