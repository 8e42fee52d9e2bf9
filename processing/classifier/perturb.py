"""Perturbations of a real image's signature, and the robustness grid of a classifier under them (issue 27).

Each function takes a `Signature` read from a spectrogram image (`processing.realdata.real_images`) and
returns a new one with the same axes. The work is done on the image's power, S(v,t) = p(v,t) * power(t)
(the pixel powers the reader found, one scale for the whole image), and the result goes back through the
reader's own steps (`_rebuild`): column normalisation (`_normalise`), eq.-8 mean velocity on the cropped axis
and the noise-aware `valid` mask (`noise_aware`: columns weaker than `NOISE_COLUMN_DB` below the strongest
are not valid and get mean velocity 0). So p_vt, valid, power and mean velocity stay consistent. As in the
reader, that threshold refers to the strongest column *of the perturbed image*: a shift or stretch that
pushes an image's strongest columns out of the clip (a fall at the very start) lowers the reference, and
noise columns can then count as valid, as they would in an image rendered from the shifted recording.

Noise floor: columns that enter the clip (a time shift, a stretch reaching past the recording) are filled
with copies of the image's own quietest columns (the 10 % with the lowest column power, taken in time
order and cycled), never zeros: a real recording has receiver noise everywhere, and a black band would be
a cue no recording carries.

Units: seconds for shifts, dimensionless factors for stretch and velocity scale, dB for the floor.
"""
from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass

import numpy as np

from processing.dsp.signatures import DSPConfig, Signature, _normalise, mean_velocity
from processing.errors import InputError
from processing.realdata.real_images import RealImageError, noise_aware

QUIET_FRACTION = 0.1  # share of columns (lowest power) that stand for the image's noise floor


def _power_image(sig: Signature) -> np.ndarray:
    """S [V, T]: p(v,t) back on the image's one power scale (columns p_vt[:, t] * power[t])."""
    p = np.asarray(sig.p_vt, dtype=np.float64)
    power = np.asarray(sig.power, dtype=np.float64)
    if power.shape != (p.shape[1],):  # a signature without column power: every column weighs the same
        power = np.ones(p.shape[1])
    return p * power[None, :]


def _rebuild(sig: Signature, s: np.ndarray) -> Signature:
    """`sig` with p_vt, power, valid and mean velocity recomputed from the power image S [V, T] exactly as
    the image reader does (`spectrogram_image._read` then `noise_aware`)."""
    s = np.nan_to_num(np.maximum(s, 0.0), nan=0.0, posinf=0.0)
    p_vt, valid, total = _normalise(s, DSPConfig().empty_floor)
    v = np.asarray(sig.velocity, dtype=np.float64)
    v_max = float(np.max(np.abs(v))) if v.size else 0.0
    mean_v = mean_velocity(p_vt, v, v_max, DSPConfig(mean_velocity="seed"), periodic=False)  # cropped axis
    return noise_aware(dataclasses.replace(sig, p_vt=p_vt, valid=valid, power=total, mean_velocity=mean_v))


def quiet_columns(sig: Signature, fraction: float = QUIET_FRACTION) -> np.ndarray:
    """Indices (ascending time) of the `fraction` of columns with the lowest power, among columns with any
    power (all columns if none has): the image's noise floor. At least one column."""
    power = np.asarray(sig.power, dtype=np.float64)
    if power.shape != (sig.p_vt.shape[1],):
        power = np.asarray(sig.p_vt, dtype=np.float64).sum(axis=0)
    cand = np.flatnonzero(power > 0)
    if cand.size == 0:
        cand = np.arange(power.size)
    n = max(1, round(fraction * cand.size))
    return np.sort(cand[np.argsort(power[cand], kind="stable")[:n]])


def _fill(s: np.ndarray, quiet: np.ndarray, n: int) -> np.ndarray:
    """n noise-floor columns [V, n]: the quiet columns of S cycled in time order."""
    return s[:, quiet[np.arange(n) % quiet.size]]


def _dt(sig: Signature) -> float:
    t = np.asarray(sig.time, dtype=np.float64)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    if not (np.isfinite(dt) and dt > 0):
        raise InputError("signature needs an ascending time axis of 2 or more bins to be shifted in time")
    return dt


def _check_factor(factor: float, what: str) -> float:
    factor = float(factor)
    if not (np.isfinite(factor) and 0.05 <= factor <= 20):
        raise InputError(f"{what} factor must be a finite number in 0.05..20, got {factor}")
    return factor


def shift_time(sig: Signature, seconds: float) -> Signature:
    """The content moved by k = round(seconds / dt) columns (positive = later). Columns pushed past the end
    are dropped; the k columns that enter are the image's noise floor (`quiet_columns`, cycled)."""
    k = round(float(seconds) / _dt(sig))
    if k == 0:
        return dataclasses.replace(sig)
    s = _power_image(sig)
    t = s.shape[1]
    n = min(abs(k), t)
    out = np.empty_like(s)
    if k > 0:
        out[:, n:] = s[:, :t - n]
        out[:, :n] = _fill(s, quiet_columns(sig), n)
    else:
        out[:, :t - n] = s[:, n:]
        out[:, t - n:] = _fill(s, quiet_columns(sig), n)
    return _rebuild(sig, out)


def stretch_time(sig: Signature, factor: float) -> Signature:
    """Pace change about the clip centre: the activity takes `factor` times as long (1.33: slower), on the
    same T columns. Output column j takes the input at column c + (j - c) / factor, c = (T - 1) / 2, linearly
    interpolated between the two neighbouring columns of S; columns whose source lies outside the recording
    (factor < 1) are the noise floor (`quiet_columns`, cycled). What is stretched past the ends is lost."""
    factor = _check_factor(factor, "stretch")
    if factor == 1.0:
        return dataclasses.replace(sig)
    s = _power_image(sig)
    t = s.shape[1]
    if t < 2:
        return dataclasses.replace(sig)
    c = (t - 1) / 2
    src = c + (np.arange(t) - c) / factor
    inside = (src >= -1e-9) & (src <= t - 1 + 1e-9)
    i0 = np.clip(np.floor(src), 0, t - 2).astype(int)
    w = np.clip(src - i0, 0.0, 1.0)
    out = s[:, i0] * (1 - w) + s[:, i0 + 1] * w
    n_out = int((~inside).sum())
    if n_out:
        out[:, ~inside] = _fill(s, quiet_columns(sig), n_out)
    return _rebuild(sig, out)


def scale_velocity(sig: Signature, factor: float) -> Signature:
    """Every column's distribution stretched along velocity about 0 (v -> factor * v), mass-conserving: input
    bin [e_i, e_i+1] is spread over [factor e_i, factor e_i+1] and rebinned onto the same axis
    (`preprocess._rebin`), so the mean velocity of a column scales by `factor` (to within half a bin). Mass
    that lands beyond the axis (factor > 1) is lost; bins beyond factor * v_max (factor < 1) get none."""
    from processing.classifier.preprocess import _rebin
    from processing.realdata.spectrogram_image import cell_edges

    factor = _check_factor(factor, "velocity scale")
    if factor == 1.0:
        return dataclasses.replace(sig)
    v = np.asarray(sig.velocity, dtype=np.float64)
    if v.size < 2 or np.any(np.diff(v) <= 0):
        raise InputError("velocity scale needs an ascending velocity axis of 2 or more bins")
    edges = cell_edges(v, "velocity")
    return _rebuild(sig, _rebin(_power_image(sig), factor * edges, edges, axis=0))


def change_floor(sig: Signature, db: float) -> Signature:
    """Noise floor moved by `db` dB against the peak. Floor level F = mean pixel power of the quiet columns
    (`quiet_columns`). db > 0: a flat pedestal (10^(db/10) - 1) F is added to every pixel, so the quiet
    columns' mean power rises by exactly db dB and the peak by far less. db < 0: the pedestal
    (1 - 10^(db/10)) F is subtracted and pixels clipped at 0 (spectral subtraction, like a display with less
    noise: pixels below it fall to the colour floor), so the quiet columns drop by at most |db| dB."""
    db = float(db)
    if not (np.isfinite(db) and abs(db) <= 60):
        raise InputError(f"floor change must be a finite number within +-60 dB, got {db}")
    if db == 0.0:
        return dataclasses.replace(sig)
    s = _power_image(sig)
    floor = float(s[:, quiet_columns(sig)].mean())
    return _rebuild(sig, s + (10 ** (db / 10) - 1) * floor)


@dataclass(frozen=True)
class Perturbation:
    """One perturbation: `kind` 'none', 'shift' (value in s), 'stretch' (factor), 'velocity' (factor) or
    'floor' (dB); `name` labels it in tables and figures."""

    name: str
    kind: str
    value: float

    @classmethod
    def make(cls, kind: str, value: float = 0.0) -> Perturbation:
        """The perturbation with its standard name (e.g. 'shift +0.5 s', 'stretch x1.33', 'floor -5 dB')."""
        if kind not in NEUTRAL:
            raise InputError(f"unknown perturbation kind {kind!r} (use {', '.join(NEUTRAL)})")
        name = {"none": "none", "shift": f"shift {value:+g} s", "stretch": f"stretch x{value:g}",
                "velocity": f"velocity x{value:g}", "floor": f"floor {value:+g} dB"}[kind]
        return cls(name, kind, float(value))


NEUTRAL = {"none": 0.0, "shift": 0.0, "stretch": 1.0, "velocity": 1.0, "floor": 0.0}  # value that changes nothing
_APPLY = {"shift": shift_time, "stretch": stretch_time, "velocity": scale_velocity, "floor": change_floor}

DEFAULT_GRID: tuple[Perturbation, ...] = (
    Perturbation.make("none"),
    *(Perturbation.make("shift", s) for s in (-1.5, -1.0, -0.5, 0.5, 1.0, 1.5)),
    *(Perturbation.make("stretch", f) for f in (0.75, 0.85, 1.15, 1.33)),
    *(Perturbation.make("velocity", f) for f in (0.8, 0.9, 1.1, 1.25)),
    *(Perturbation.make("floor", d) for d in (-5.0, 5.0, 10.0)),
)
# one value per kind, the strongest of the default grid: a fast check (`rtchannel robustness --quick`)
QUICK_GRID: tuple[Perturbation, ...] = (
    Perturbation.make("none"), Perturbation.make("shift", 1.0), Perturbation.make("stretch", 1.33),
    Perturbation.make("velocity", 1.25), Perturbation.make("floor", 10.0))


def apply(sig: Signature, perturbation: Perturbation) -> Signature:
    """`sig` under `perturbation` (a copy for kind 'none')."""
    if perturbation.kind == "none":
        return dataclasses.replace(sig)
    if perturbation.kind not in _APPLY:
        raise InputError(f"unknown perturbation kind {perturbation.kind!r} (use {', '.join(NEUTRAL)})")
    return _APPLY[perturbation.kind](sig, perturbation.value)


MOTION_V = 0.5  # m/s: a person standing still (postural sway, breathing) stays well under it; limbs in motion exceed it
INTACT = 0.5  # an image counts as intact under a perturbation when it keeps at least half of its motion power


def _kept_cells(sig: Signature, perturbation: Perturbation) -> np.ndarray:
    """Boolean [V, T]: cells of `sig` whose content `perturbation` keeps inside the image's axes (a shift or
    stretch moves columns past the clip's ends, a velocity scale above 1 moves bins past the axis)."""
    shape = np.asarray(sig.p_vt).shape
    kind, value = perturbation.kind, perturbation.value
    if kind == "shift":
        dest = np.arange(shape[1]) + round(value / _dt(sig))
        return np.broadcast_to((dest >= 0) & (dest <= shape[1] - 1), shape)
    if kind == "stretch":
        c = (shape[1] - 1) / 2
        dest = c + (np.arange(shape[1]) - c) * _check_factor(value, "stretch")
        return np.broadcast_to((dest >= -1e-9) & (dest <= shape[1] - 1 + 1e-9), shape)
    if kind == "velocity":
        from processing.realdata.spectrogram_image import cell_edges

        v = np.asarray(sig.velocity, dtype=np.float64)
        edges = cell_edges(v, "velocity")
        f = _check_factor(value, "velocity scale")
        inside = (f * edges[:-1] >= edges[0] - 1e-12) & (f * edges[1:] <= edges[-1] + 1e-12)
        return np.broadcast_to(inside[:, None], shape)
    return np.ones(shape, dtype=bool)


def motion_power(sig: Signature) -> np.ndarray:
    """[V, T] motion power of an image: S(v,t) minus the noise floor (the quiet columns' mean per velocity bin,
    `quiet_columns`), clipped at 0, and 0 where |v| < `MOTION_V`."""
    s = _power_image(sig)
    floor = s[:, quiet_columns(sig)].mean(axis=1, keepdims=True)
    moving = np.abs(np.asarray(sig.velocity, dtype=np.float64)) >= MOTION_V
    return np.maximum(s - floor, 0.0) * moving[:, None]


def motion_kept(sig: Signature, perturbation: Perturbation, motion: np.ndarray | None = None) -> float:
    """Share (0..1) of the image's motion power (`motion_power`; pass it as `motion` when evaluating several
    perturbations of one image) that `perturbation` keeps inside the image.

    A time shift of -1.5 s keeps none of a fall that is over within the clip's first 1.5 s: no classifier can
    recognise what is no longer in the image, so the robustness table reports accuracy on the images that keep
    at least `INTACT` of it apart from the total. An image without motion power above its floor keeps all of
    it (1.0)."""
    m = motion_power(sig) if motion is None else motion
    total = float(m.sum())
    if not (total > 0 and np.isfinite(total)):
        return 1.0
    return float(m[_kept_cells(sig, perturbation)].sum() / total)


def robustness_grid(clf, images, grid=DEFAULT_GRID, progress: bool = False) -> list[dict]:
    """Accuracy of `clf` on the known-class `images` (RealImage) under each perturbation of `grid`.

    Returns one row per perturbation: perturbation (name), kind, value, n, accuracy, macro_f1 (fractions),
    delta_accuracy (against the 'none' row, if the grid has one; else None), truncated (share of the images
    keeping less than `INTACT` of their motion power, `motion_kept`), accuracy_intact (accuracy over the
    others; None if there are none) and recall_<class> for every model class that has images (classes
    without images are left out: their recall says nothing).
    Images of classes the model does not know are not used. Raises RealImageError if none is known.
    """
    from processing.classifier.images import evaluate_images

    known = [im for im in images if im.activity in clf.classes]
    if not known:
        raise RealImageError(f"no images of a class the model knows ({', '.join(clf.classes)})")
    present = [c for c in clf.classes if any(im.activity == c for im in known)]
    rows = []
    motions = [motion_power(im.signature) for im in known]  # the clean images' motion, once per image
    for k, pert in enumerate(grid):
        moved = [dataclasses.replace(im, signature=apply(im.signature, pert)) for im in known]
        ev = evaluate_images(clf, moved)
        rep = ev.report
        assert rep is not None  # `known` holds only images of the model's classes
        intact = np.array([motion_kept(im.signature, pert, m) >= INTACT for im, m in zip(known, motions)])
        right = np.array([clf.classes[int(p.argmax())] == im.activity for im, p in zip(ev.known, ev.known_proba)])
        row = {"perturbation": pert.name, "kind": pert.kind, "value": pert.value, "n": rep.n,
               "accuracy": rep.accuracy, "macro_f1": rep.macro_f1, "truncated": float(1 - intact.mean()),
               "accuracy_intact": float(right[intact].mean()) if intact.any() else None}
        row.update({f"recall_{c}": float(rep.recall[clf.classes.index(c)]) for c in present})
        rows.append(row)
        if progress:
            print(f"[{k + 1}/{len(grid)}] {pert.name}: accuracy {100 * rep.accuracy:.1f} %", file=sys.stderr)
    base = next((r["accuracy"] for r in rows if r["kind"] == "none"), None)
    for r in rows:
        r["delta_accuracy"] = None if base is None else r["accuracy"] - base
    return rows


__all__ = ["DEFAULT_GRID", "INTACT", "MOTION_V", "NEUTRAL", "QUICK_GRID", "Perturbation", "apply", "change_floor",
           "motion_kept", "motion_power", "quiet_columns", "robustness_grid", "scale_velocity", "shift_time",
           "stretch_time"]
