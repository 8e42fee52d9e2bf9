"""Imported motion before retargeting (`SourceMotion`) and the axis/unit conventions of importers.

Importers convert to the project frame (metres, z up) first, so the retargeter sees one convention:
named points [F, 3] and, where the format has them, global joint orientations [F, 3, 3].
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from rtchannel.errors import ConfigError
from rtchannel.motion.errors import MotionImportError
from rtchannel.motion.pose import MAX_FRAMES, check_resampled_frames  # noqa: F401 - importers' frame guard

# Limits of imported motion, each with its reason (docs/validation.md):
MAX_COORD_M = 100.0  # capture volumes are < 100 m across: a point further out is corrupted data or wrong units
MAX_ANGLE_DEG = 1e5  # ~280 turns; BVH angles may exceed 360 deg when unwrapped, but not by this much
FILE_FPS_RANGE = (1.0, 10000.0)  # frame rates of motion files [Hz]: mocap systems run 24..2000 Hz
FPS_RANGE = (10.0, 2000.0)  # frame rates a motion is resampled to [Hz] (as ProceduralParams.fps)
MAX_DURATION_S = 3600.0  # one take; longer is a corrupted header (split long recordings)
MAX_SOURCE_FRAMES = 200_000  # frames of one file (28 min at 120 Hz); memory ~ frames x joints x 100 B
TIME_STEP_TOLERANCE = 0.01  # share of the median step: a dropped frame or a variable rate changes speeds by more
UNIT_RANGE_M = (1e-6, 1e3)  # metres per file unit accepted for units= (micrometre .. kilometre)

# metres per file unit; "cmu" is the CMU/cgspeed BVH unit (1/0.45 inch)
UNIT_SCALE = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254, "cmu": 0.0254 / 0.45}
# leg length (hip -> knee -> ankle) in each unit for an adult body, used to guess the unit
_LEG_RANGES = (("m", 0.3, 1.5), ("cmu", 8.0, 22.0), ("in", 22.0, 38.0), ("cm", 38.0, 150.0),
               ("mm", 380.0, 1500.0))
_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass
class SourceMotion:
    """A motion as imported, in the project frame (metres, z up), before retargeting.

    Attributes:
        path: file it came from (for messages).
        fps: frame rate [Hz].
        points: named point trajectories [F, 3] (m): joints, end sites or virtual joint centres.
        orientations: named global orientations [F, 3, 3] (rotation from the source joint's local
            axes to the project frame), where the format defines them (BVH), else empty.
        neutral: neutral-pose (T-pose or anatomical zero) global orientation [3, 3] per entry of
            `orientations`, in the project frame with the body facing +x; entries may be missing.
        kind: which joint map applies ("cc", "cmu", "c3d").
        info: provenance (units, up axis, dropped frames, filled gaps, ...).
    """

    path: str
    fps: float
    points: dict[str, np.ndarray]
    orientations: dict[str, np.ndarray] = field(default_factory=dict)
    neutral: dict[str, np.ndarray] = field(default_factory=dict)
    kind: str = ""
    info: dict = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return len(next(iter(self.points.values())))

    def sliced(self, start: int, stop: int | None = None) -> "SourceMotion":
        sl = slice(start, stop)
        return replace(self, points={k: v[sl] for k, v in self.points.items()},
                       orientations={k: v[sl] for k, v in self.orientations.items()})


def parse_units(units) -> float | None:
    """Metres per file unit from a name ("m", "cm", "mm", "in", "cmu") or a number; None if not given."""
    if units is None:
        return None
    if isinstance(units, str):
        if units.lower() not in UNIT_SCALE:
            raise ConfigError(f"units: unknown unit {units[:40]!r}; use one of {', '.join(UNIT_SCALE)} or metres "
                              "per unit")
        return UNIT_SCALE[units.lower()]
    try:
        scale = float(units)
    except (TypeError, ValueError):
        raise ConfigError(f"units: expected a unit name or metres per file unit, got {str(units)[:40]!r}") from None
    if not UNIT_RANGE_M[0] <= scale <= UNIT_RANGE_M[1]:  # also refuses nan and inf
        raise ConfigError(f"units: {scale:g} metres per file unit is outside {UNIT_RANGE_M[0]:g}..{UNIT_RANGE_M[1]:g}")
    return scale


def check_fps(fps, what: str = "fps") -> float:
    """`fps` [Hz] as a float if finite and within `FPS_RANGE`, else `ConfigError` naming `what`."""
    try:
        f = float(fps)
    except (TypeError, ValueError):
        raise ConfigError(f"{what}: expected a frame rate in Hz, got {str(fps)[:40]!r}") from None
    if not FPS_RANGE[0] <= f <= FPS_RANGE[1]:
        raise ConfigError(f"{what}: {f:g} Hz is outside {FPS_RANGE[0]:g}..{FPS_RANGE[1]:g} Hz")
    return f


def check_times(path, t) -> float:
    """The frame rate [Hz] of time stamps `t` [F] (s): `MotionImportError` naming the file (and frame) unless
    they are finite, at least two, increasing with a uniform step (each within `TIME_STEP_TOLERANCE` of the
    median: the importers assume one rate), at most `MAX_SOURCE_FRAMES` over at most `MAX_DURATION_S`, at a
    rate within `FILE_FPS_RANGE`."""
    t = np.asarray(t, dtype=float).reshape(-1)
    if not 2 <= t.size <= MAX_SOURCE_FRAMES:
        raise MotionImportError(path, f"{t.size} time stamps; need 2..{MAX_SOURCE_FRAMES}")
    if not np.isfinite(t).all():
        raise MotionImportError(path, "non-finite time stamp", frame=int(np.argmax(~np.isfinite(t))))
    with np.errstate(over="ignore", invalid="ignore"):  # 1e308 - (-1e308) overflows: refused below
        step = np.diff(t)
        duration = t[-1] - t[0]
    if not (step > 0).all():
        raise MotionImportError(path, "time must increase", frame=int(np.argmax(~(step > 0))) + 1)
    if not duration <= MAX_DURATION_S:
        raise MotionImportError(path, f"the time stamps span {duration:.4g} s, more than {MAX_DURATION_S:g} s")
    median = float(np.median(step))
    off = np.abs(step - median) > TIME_STEP_TOLERANCE * median
    if off.any():
        k = int(np.argmax(off))
        raise MotionImportError(path, f"time steps are not uniform ({step[k]:.4g} s after frame {k}, median "
                                f"{median:.4g} s): resample to one rate first", frame=k + 1)
    fps = float((t.size - 1) / duration)
    if not FILE_FPS_RANGE[0] <= fps <= FILE_FPS_RANGE[1]:
        raise MotionImportError(path, f"time stamps give {fps:.4g} frames/s, outside {FILE_FPS_RANGE[0]:g}.."
                                f"{FILE_FPS_RANGE[1]:g} (seconds expected)")
    return fps


def check_extent(path, points: dict[str, np.ndarray], line_of_frame=None) -> None:
    """`MotionImportError` (file, frame and line) if any point [F, 3] (m) is non-finite or beyond `MAX_COORD_M`."""
    for name, p in points.items():
        bad = ~(np.abs(p) <= MAX_COORD_M).all(axis=1)  # nan compares False: caught too
        if bad.any():
            k = int(np.argmax(bad))
            line = int(line_of_frame[k]) if line_of_frame is not None else None
            raise MotionImportError(path, f"{name[:40]} is {np.abs(p[k]).max():.3g} m from the origin (limit "
                                    f"{MAX_COORD_M:g} m): corrupted data or wrong units", line=line, frame=k)


def guess_units(leg_length: float) -> str | None:
    """Unit name whose adult leg-length range contains `leg_length` (file units), else None."""
    for name, lo, hi in _LEG_RANGES:
        if lo <= leg_length < hi:
            return name
    return None


def up_rotation(up: str) -> np.ndarray:
    """Rotation [3, 3] taking file coordinates with the given up axis ("y", "-z", ...) to z up.

    y up uses the project's convention for the seed's y-up data: (x, y, z) -> (x, -z, y).
    """
    if not isinstance(up, str) or up.lstrip("+-").lower() not in _AXES or len(up) > 2:
        raise ConfigError(f"up: must be one of x, y, z, -x, -y, -z; got {str(up)[:40]!r}")
    sign = -1.0 if up.startswith("-") else 1.0
    axis = up.lstrip("+-").lower()
    basis = {"z": np.eye(3), "y": np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]),
             "x": np.array([[0, 0, -1.0], [0, 1.0, 0], [1.0, 0, 0]])}[axis]
    if sign < 0:  # turn upside down about the forward (x) axis, keeping the frame right-handed
        basis = np.diag([1.0, -1.0, -1.0]) @ basis if axis != "x" else np.diag([-1.0, 1.0, -1.0]) @ basis
    return basis


def guess_up(top: np.ndarray, bottom: np.ndarray) -> str:
    """Up axis ("x", "-y", ...) along which `top` [F, 3] lies above `bottom` [F, 3] on average."""
    d = np.nanmean(np.asarray(top) - np.asarray(bottom), axis=0)
    k = int(np.argmax(np.abs(d)))
    return ("-" if d[k] < 0 else "") + "xyz"[k]
