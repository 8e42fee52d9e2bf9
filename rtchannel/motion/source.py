"""Imported motion before retargeting (`SourceMotion`) and the axis/unit conventions of importers.

Importers convert to the project frame (metres, z up) first, so the retargeter sees one convention:
named points [F, 3] and, where the format has them, global joint orientations [F, 3, 3].
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

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
            raise ValueError(f"unknown units {units!r}; use one of {', '.join(UNIT_SCALE)} or metres per unit")
        return UNIT_SCALE[units.lower()]
    scale = float(units)
    if not scale > 0:
        raise ValueError(f"units must be a positive number of metres per file unit, got {units}")
    return scale


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
    sign = -1.0 if up.startswith("-") else 1.0
    axis = up.lstrip("+-").lower()
    if axis not in _AXES:
        raise ValueError(f"up must be one of x, y, z, -x, -y, -z; got {up!r}")
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
