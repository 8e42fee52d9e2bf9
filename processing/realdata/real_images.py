"""Folders of real micro-Doppler spectrogram images (Glasgow campaign-1 layout) as labelled signatures.

Used by sim-to-real evaluation (`processing.classifier.images`) and the real-data Table I
(`processing.metrics.sim_real_table`). Labels come from Glasgow file names (``1P36A01R01.png``: leading digit
= activity, P<n> = subject) or from a CSV ``file,activity[,subject]`` for other names.

Noise-only columns: the reader (`processing.realdata.spectrogram_image`) marks a column valid when any pixel is
above the 40 dB colour floor, but in these renders the radar's own noise sits inside the 40 dB span.
Measured on all 360 campaign-1 images (column power relative to the image's strongest column): the
quiet parts of 5 s recordings (before/after a fall, sit, stand, pick, drink) have column power -35 to
-48 dB (5th percentile per image), the active parts -2 to -17 dB (median per image) and walks never
drop below -22 dB. `NOISE_COLUMN_DB` = -30 dB sits between the two, about 6 dB above the loudest quiet
parts (the same 6 dB margin as `DSPConfig.detection_snr_db` for simulated signatures). Columns below it
are not valid and, as for simulated signatures (`processing.dsp.signatures`), keep their spectrum but get mean
velocity 0.
"""
from __future__ import annotations

import csv
import dataclasses
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from processing.dsp.signatures import Signature
from processing.errors import InputError

NOISE_COLUMN_DB = -30.0  # column power below this (re the strongest column) is noise only; see above
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
MAX_IMAGES = 100_000  # a folder walk must not run away on a wrong path (the Glasgow set has 360)
_RANGE = re.compile(r"^P?(\d{1,9})(?:\s*-\s*P?(\d{1,9}))?$", re.IGNORECASE)  # int() of 4301+ digits raises


class RealImageError(InputError):
    """A real-image folder, image, label file or people filter that cannot be used (one line)."""


@dataclass
class RealImage:
    """One labelled real recording read from an image.

    Attributes:
        name: the image's path relative to the folder it was loaded from (sub-folders kept: the Glasgow
            campaigns reuse subject numbers, so a file name alone does not identify a recording).
        path: the image file.
        activity: label (project names: walk, sit, stand, pick, drink, fall).
        subject: person number (P36 -> 36), or None if unknown.
        signature: p(v,t) [V, T] on the image's pixel grid (m/s, s), noise-aware `valid`, mean velocity
            [T] m/s (0 where not valid), column `power`.
    """

    name: str
    path: Path
    activity: str
    subject: int | None
    signature: Signature


def parse_people(text: str | None) -> frozenset[int] | None:
    """Subject numbers of a filter such as ``P36-P45``, ``36-45`` or ``P36,P40-P42`` (None: everyone)."""
    if text is None or not str(text).strip():
        return None
    out: set[int] = set()
    for part in str(text).split(","):
        m = _RANGE.match(part.strip())
        if m is None:
            raise RealImageError(f"bad --people part {part.strip()!r} (use e.g. P36-P45 or P36,P40-P42)")
        lo, hi = int(m.group(1)), int(m.group(2) or m.group(1))
        if hi < lo or hi - lo > 100_000:
            raise RealImageError(f"bad --people range {part.strip()!r} (first must not exceed last)")
        out.update(range(lo, hi + 1))
    return frozenset(out)


def read_labels_csv(path: str | Path) -> dict[str, tuple[str, int | None]]:
    """{file name: (activity, subject or None)} from a CSV with columns ``file``, ``activity`` and
    optionally ``subject`` (P36 or 36). File names are matched without their folder."""
    path = Path(path)
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise RealImageError(f"{path}: cannot read labels ({type(e).__name__})") from None
    if not rows or not {"file", "activity"} <= set(rows[0]):
        raise RealImageError(f"{path}: needs a header with columns file,activity[,subject]")
    out = {}
    for k, r in enumerate(rows, start=2):
        name, act, subj = (r.get("file") or "").strip(), (r.get("activity") or "").strip().lower(), \
            (r.get("subject") or "").strip()
        if not name or not act:
            raise RealImageError(f"{path}:{k}: empty file or activity")
        m = re.fullmatch(r"P?(\d{1,9})", subj, re.IGNORECASE) if subj else None  # int() of 4301+ digits raises
        if subj and m is None:
            raise RealImageError(f"{path}:{k}: subject {subj!r} is not like P36 or 36")
        out[Path(name).name] = (act, int(m.group(1)) if m else None)
    return out


def list_images(folder: str | Path) -> list[Path]:
    """Image files under `folder` (recursively), sorted by path; one-line error if there are none."""
    folder = Path(folder)
    if not folder.is_dir():
        raise RealImageError(f"image folder not found: {folder}")
    paths = []
    for p in folder.rglob("*"):
        if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file():
            paths.append(p)
            if len(paths) > MAX_IMAGES:
                raise RealImageError(f"{folder}: more than {MAX_IMAGES} images; point at the dataset's folder")
    if not paths:
        raise RealImageError(f"no images ({', '.join(IMAGE_SUFFIXES)}) in {folder}")
    return sorted(paths)


def image_label(path: Path, labels: dict | None) -> tuple[str, int | None]:
    """(activity, subject) of an image: from `labels` if it names the file, else from its Glasgow name."""
    from processing.realdata.spectrogram_image import (ContradictoryNameError, SpectrogramImageError,
                                                       parse_glasgow_name)

    if labels is not None and path.name in labels:
        return labels[path.name]
    try:
        g = parse_glasgow_name(path)
    except ContradictoryNameError:
        raise
    except SpectrogramImageError as e:
        hint = "" if labels is None else " and it is not in --labels"
        raise RealImageError(f"{e}{hint}; pass --labels CSV (file,activity[,subject])") from None
    return g.activity, g.subject


def noise_aware(sig: Signature, noise_column_db: float = NOISE_COLUMN_DB) -> Signature:
    """`sig` with columns weaker than `noise_column_db` below its strongest column marked not valid and
    their mean velocity set to 0 (p(v,t) unchanged)."""
    power = np.asarray(sig.power, dtype=np.float64)
    peak = float(power.max()) if power.size else 0.0
    valid = np.asarray(sig.valid, bool) & (power >= peak * 10 ** (noise_column_db / 10)) & (peak > 0)
    return dataclasses.replace(sig, valid=valid, mean_velocity=np.where(valid, sig.mean_velocity, 0.0))


def read_real_image(path: str | Path, noise_column_db: float = NOISE_COLUMN_DB) -> Signature:
    """Noise-aware signature of one Glasgow-layout image (pixel grid: 317 velocity bins over +-6 m/s,
    377 or 383 time bins over 10 or 5 s). Raises RealImageError (one line naming the file)."""
    from processing.realdata.spectrogram_image import SpectrogramImageError, read_glasgow_image

    try:
        return noise_aware(read_glasgow_image(Path(path), name=Path(path).name).signature, noise_column_db)
    except SpectrogramImageError as e:
        raise RealImageError(str(e)) from None


def load_real_images(folder: str | Path, labels: dict | None = None, people: frozenset[int] | None = None,
                     activities=None, noise_column_db: float = NOISE_COLUMN_DB
                     ) -> tuple[list[RealImage], list[tuple[str, str]]]:
    """(images, skipped) of every image under `folder` whose subject is in `people` (None: all) and whose
    activity is in `activities` (None: all). Unreadable images, and Glasgow names that contradict themselves
    (activity digit against A-code, when --labels does not name the file), are skipped with a warning and
    listed as (path relative to `folder`, reason); any other image without a usable label is an error
    (RealImageError), as is an empty selection."""
    import warnings

    from processing.realdata.spectrogram_image import ContradictoryNameError

    folder = Path(folder)
    paths = list_images(folder)
    chosen, bad = [], []
    for p in paths:
        rel = p.relative_to(folder).as_posix()
        try:
            act, subj = image_label(p, labels)
        except ContradictoryNameError as e:  # documented rule: such a label is trusted neither way
            warnings.warn(f"{rel}: skipped, its name contradicts itself ({str(e).split(': ', 1)[-1]})", stacklevel=2)
            bad.append((rel, f"name contradicts itself: {e}"))
            continue
        if people is not None and (subj is None or subj not in people):
            continue
        if activities is not None and act not in activities:
            continue
        chosen.append((p, rel, act, subj))
    if not chosen:
        what = "" if people is None else f" of people {_people_text(people)}"
        raise RealImageError(f"no images{what} in {folder} ({len(paths)} images in all)")
    out = []
    for p, rel, act, subj in chosen:
        try:
            out.append(RealImage(rel, p, act, subj, read_real_image(p, noise_column_db)))
        except RealImageError as e:
            bad.append((rel, str(e)))
    if not out:
        raise RealImageError(f"none of the {len(chosen)} images in {folder} could be read (first: {bad[0][1]})")
    return out, bad


def _people_text(people: frozenset[int]) -> str:
    s = sorted(people)
    return f"P{s[0]}-P{s[-1]}" if s[-1] - s[0] + 1 == len(s) else ",".join(f"P{k}" for k in s[:8])
