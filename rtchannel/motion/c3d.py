"""C3D marker import (ezc3d): gap filling, joint centres from the 41-marker Vicon/CMU set.

Joint centres (project frame, metres) from marker clusters:
- pelvis: origin mid-ASIS (CMU's LFWT/RFWT, alias LASI/RASI), axes from ASIS and PSIS (LBWT/RBWT,
  alias LPSI/RPSI); hip joint centres by Harrington et al. 2007 (J. Biomech. 40:595) from pelvis width
  and depth;
- knee and ankle centres: the lateral knee / ankle marker moved medially by half a joint width
  (`KNEE_OFFSET_M`, `ANKLE_OFFSET_M`) along the pelvis' lateral axis made perpendicular to the segment;
- shoulder centre: acromion marker lowered by `SHOULDER_DROP_M` along the thorax axis; elbow: the
  lateral epicondyle marker itself (a few degrees of abduction bias); wrist: mid of the two wrist markers;
- segment frames for pelvis, thorax (C7, T10, CLAV, STRN) and feet (heel, toe, fifth metatarsal), whose
  anatomical zero is the avatar's rest orientation, and the head (four head markers), calibrated.
"""
from __future__ import annotations

import struct
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from processing.errors import one_line
from rtchannel.motion.errors import MotionImportError
from rtchannel.motion.source import (FILE_FPS_RANGE, MAX_DURATION_S, MAX_SOURCE_FRAMES, SourceMotion,
                                     check_extent, guess_units, guess_up, parse_units, up_rotation)

KNEE_OFFSET_M = 0.055
ANKLE_OFFSET_M = 0.045
SHOULDER_DROP_M = 0.055
MAX_GAP_S = 0.2
ALIASES = {"LASI": "LFWT", "RASI": "RFWT", "LPSI": "LBWT", "RPSI": "RBWT", "RBAK": "RBAC"}
MAX_C3D_BYTES = 1 << 30  # a 41-marker take at 120 Hz is ~1 MB per minute: 1 GiB is ~16 h
LEG_RANGE_M = (0.3, 1.5)  # hip-to-ankle marker distance of an adult [m]: outside it the units are wrong
REQUIRED = ("LFWT", "RFWT", "LBWT", "RBWT", "LTHI", "LKNE", "LSHN", "LANK", "LHEE", "LMT5", "LTOE",
            "RTHI", "RKNE", "RSHN", "RANK", "RHEE", "RMT5", "RTOE", "CLAV", "STRN", "C7", "T10",
            "LFHD", "RFHD", "LBHD", "RBHD", "LSHO", "LUPA", "LELB", "LWRA", "LWRB", "LFIN",
            "RSHO", "RUPA", "RELB", "RWRA", "RWRB", "RFIN")
# Marker sets the importer knows, tried in order (labels after ALIASES; extend the table for another set):
# what each must have. The joint centres use the pelvis (ASIS/PSIS), knee, ankle, heel, toe, shoulder,
# elbow, wrist, head and trunk markers; the shin/tibia and upper-arm markers only steady the gap filling.
#   cmu41: the CMU database's 41 Vicon markers (MT5 on the fifth metatarsal sets each foot's lateral axis);
#   plug-in-gait: Vicon's Plug-in Gait (LTIB/RTIB instead of LSHN/RSHN, no MT5: the foot's lateral axis is
#   then the pelvis's, feet pointing where the pelvis does).
MARKER_SETS: dict[str, tuple[str, ...]] = {
    "cmu41": REQUIRED,
    "plug-in-gait": tuple(n for n in REQUIRED if n[1:] not in ("SHN", "MT5")) + ("LTIB", "RTIB"),
}


def _header_frames(path: Path) -> int | None:
    """Frame count stated in the C3D header (words 4 and 5: first and last frame), if readable."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(10)
        first, last = struct.unpack("<HH", head[6:10])
        return last - first + 1 if last >= first else None
    except (OSError, struct.error):
        return None


# ezc3d (C++) crashes with a segmentation fault on some corrupted headers or parameter sections (byte
# flips in the first 3 kB: 3 of 3 fuzz runs crashed) and may allocate what a corrupt header asks for, so
# it runs in a child process with an address-space limit; a crash there is a one-line import error.
C3D_CHILD_MEMORY = 8 << 30  # address space of the parsing process [bytes], or the environment's lower limit
C3D_CHILD_TIMEOUT_S = 600.0
_CHILD = r"""
import resource, sys
# lower the address-space limit only: never above what the environment already allows (batch clusters and
# `ulimit -v` set one; raising it, even the soft limit above the hard one, fails)
soft, hard = resource.getrlimit(resource.RLIMIT_AS)
want = int(sys.argv[3])
for cap in (soft, hard):
    if cap != resource.RLIM_INFINITY:
        want = min(want, cap)
try:
    resource.setrlimit(resource.RLIMIT_AS, (want, hard))
except (ValueError, OSError) as exc:
    print(f"could not limit the parser's address space to {want} bytes: {exc}")
    sys.exit(3)
import numpy as np
try:
    import ezc3d
    c = ezc3d.c3d(sys.argv[1])
    point = c["parameters"]["POINT"]
    units = str(point["UNITS"]["value"][0]) if "UNITS" in point and len(point["UNITS"]["value"]) else ""
    stated = int(point["FRAMES"]["value"][0]) if "FRAMES" in point and len(point["FRAMES"]["value"]) else -1
    np.savez(sys.argv[2], points=np.asarray(c["data"]["points"], dtype=float),
             rate=float(c["header"]["points"]["frame_rate"]),
             labels=np.array([str(x) for x in point["LABELS"]["value"]], dtype=str),
             units=units, residuals=np.asarray(c["data"]["meta_points"]["residuals"], dtype=float), stated=stated)
except MemoryError:
    print("MemoryError: the file asks for more memory than allowed")
    sys.exit(3)
except Exception as exc:
    print(f"{type(exc).__name__}: {' '.join(str(exc).split())[:120]}")
    sys.exit(3)
"""


def _read_c3d_isolated(path: Path) -> dict:
    """ezc3d's reading of `path` (points [4, M, F], rate, labels, units, residuals, stated frames), done in a
    child process; MotionImportError if it fails, crashes, runs out of memory or time."""
    import os
    import subprocess
    import sys
    import tempfile

    with tempfile.TemporaryDirectory(prefix="rtchannel-c3d-") as tmp:
        out = Path(tmp) / "markers.npz"
        env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
        try:
            proc = subprocess.run([sys.executable, "-c", _CHILD, str(path), str(out), str(C3D_CHILD_MEMORY)],
                                  capture_output=True, text=True, timeout=C3D_CHILD_TIMEOUT_S, env=env)
        except subprocess.TimeoutExpired:
            raise MotionImportError(path, "not a readable C3D file (parsing took over "
                                    f"{C3D_CHILD_TIMEOUT_S:.0f} s)") from None
        if proc.returncode != 0 or not out.is_file():
            why = proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else (
                f"the C3D parser crashed (signal {-proc.returncode})" if proc.returncode < 0
                else f"the C3D parser failed (exit status {proc.returncode})")
            raise MotionImportError(path, f"not a readable C3D file ({one_line(why, 160)})")
        with np.load(out, allow_pickle=False) as z:
            got = {k: z[k] for k in z.files}
    got["units"] = str(got["units"]) or None
    got["stated"] = int(got["stated"]) if int(got["stated"]) >= 0 else None
    got["labels"] = [str(x) for x in got["labels"]]
    return got


def read_markers(path) -> tuple[dict[str, np.ndarray], float, str | None]:
    """Marker trajectories {label: [F, 3]} in file units (NaN where missing), frame rate [Hz], units."""
    path = Path(path)
    if not path.is_file():
        raise MotionImportError(path, "no such file")
    try:
        size = path.stat().st_size
        with open(path, "rb"):
            pass
    except OSError as exc:
        raise MotionImportError(path, f"cannot read file: {exc.strerror or exc}") from None
    if size > MAX_C3D_BYTES:
        raise MotionImportError(path, f"file of {size / 2**20:.0f} MiB exceeds the {MAX_C3D_BYTES >> 20} MiB limit")
    got = _read_c3d_isolated(path)
    pts, rate, labels, units, residuals, stated = (got["points"], float(got["rate"]), list(got["labels"]),
                                                   got["units"], got["residuals"], got["stated"])
    n = pts.shape[2] if pts.ndim == 3 else 0
    expected = max(x for x in (stated or 0, _header_frames(path) or 0))
    if n == 0 or len(labels) < pts.shape[1]:
        raise MotionImportError(path, "C3D file holds no marker frames or fewer labels than markers")
    if expected and n < expected:
        raise MotionImportError(path, f"truncated: header says {expected} frames, file holds {n} "
                                f"(frame {n} is missing)", frame=n)
    if not FILE_FPS_RANGE[0] <= rate <= FILE_FPS_RANGE[1]:  # also refuses nan
        raise MotionImportError(path, f"point frame rate {rate:g} Hz is outside {FILE_FPS_RANGE[0]:g}.."
                                f"{FILE_FPS_RANGE[1]:g} Hz")
    if n > MAX_SOURCE_FRAMES or n / rate > MAX_DURATION_S:
        raise MotionImportError(path, f"{n} frames at {rate:g} Hz exceed the limits ({MAX_SOURCE_FRAMES} frames, "
                                f"{MAX_DURATION_S:.0f} s)")
    if pts.shape[0] < 3:
        raise MotionImportError(path, "marker data has fewer than 3 coordinates")
    xyz = np.transpose(pts[:3], (2, 1, 0))  # [F, M, 3]
    if residuals.shape[-2:] == xyz.shape[1::-1] and residuals.ndim == 3:
        xyz[np.transpose(residuals[0] < 0)] = np.nan  # a negative residual marks an invalid sample
    with np.errstate(invalid="ignore"):
        xyz[~np.isfinite(xyz).all(axis=2)] = np.nan
    out = {}
    for k, lab in enumerate(labels[:xyz.shape[1]]):
        name = lab.split(":")[-1].strip().upper()
        out[ALIASES.get(name, name)] = xyz[:, k]
    return out, rate, units


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index runs where mask is True."""
    d = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def fill_gaps(markers: dict[str, np.ndarray], fps: float, names, max_gap_s: float = MAX_GAP_S,
              on_long_gap: str = "error", path="") -> dict:
    """Fill NaN gaps of the named markers in place; returns a report {marker: [[first, last], ...]}.

    Gaps up to `max_gap_s` seconds are filled (interior: PCHIP through the valid samples; at the ends:
    the nearest valid sample). Longer gaps raise `MotionImportError` listing marker and frames
    (``on_long_gap="error"``) or are filled the same way with a warning (``"warn"``).
    """
    from scipy.interpolate import PchipInterpolator

    max_len = int(np.floor(max_gap_s * fps + 1e-9))
    filled, long = {}, []
    for name in names:
        x = markers[name]
        bad = np.isnan(x).any(axis=1)
        if not bad.any():
            continue
        if bad.all():
            long.append(f"{name}: no valid frame")
            continue
        runs = _runs(bad)
        for s, e in runs:
            if e - s > max_len:
                long.append(f"{name}: frames {s}-{e - 1} ({(e - s) / fps:.2f} s)")
        t = np.flatnonzero(~bad)
        interp = PchipInterpolator(t, x[t], axis=0, extrapolate=False)
        for s, e in runs:
            idx = np.arange(s, e)
            x[idx] = interp(idx) if s > 0 and e < len(x) else x[t[0] if s == 0 else t[-1]]
        filled[name] = [[int(s), int(e - 1)] for s, e in runs]
    if long:
        msg = f"marker gaps longer than {max_gap_s} s: " + "; ".join(long[:12]) + (" ..." if len(long) > 12 else "")
        if on_long_gap == "error" or any("no valid frame" in m for m in long):
            raise MotionImportError(path, msg + " (raise max_gap_s or pass on_long_gap='warn' to fill them)")
        warnings.warn(f"{path}: {msg}; filled by interpolation", stacklevel=3)
    return filled


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _perp(v, axis):
    return v - np.sum(v * axis, axis=-1, keepdims=True) * axis


def _frame_xy(x, y_hint):
    """Right-handed frames [F, 3, 3] (columns x, y, z) from x and an approximate y."""
    x = _unit(x)
    y = _unit(_perp(y_hint, x))
    return np.stack([x, y, np.cross(x, y)], axis=-1)


def joint_centres(m: dict[str, np.ndarray]) -> tuple[dict, dict]:
    """Virtual joints [F, 3] and segment frames [F, 3, 3] from markers already in metres, z up."""
    def mid(*names: str) -> np.ndarray:
        total = m[names[0]]
        for k in names[1:]:
            total = total + m[k]
        return total / len(names)

    asis, psis = mid("LFWT", "RFWT"), mid("LBWT", "RBWT")
    pelvis = _frame_xy(asis - psis, m["LFWT"] - m["RFWT"])
    pw = float(np.median(np.linalg.norm(m["LFWT"] - m["RFWT"], axis=1)))
    pd = float(np.median(np.linalg.norm(asis - psis, axis=1)))
    pts = dict(m)
    for s, sign in (("L", 1.0), ("R", -1.0)):
        local = np.array([-0.24 * pd - 0.0099, sign * (0.33 * pw + 0.0073), -0.30 * pw - 0.0109])
        pts[f"{s}HJC"] = asis + pelvis @ local
        lateral = sign * pelvis[..., 1]
        thigh = _unit(m[f"{s}KNE"] - pts[f"{s}HJC"])
        pts[f"{s}KJC"] = m[f"{s}KNE"] - KNEE_OFFSET_M * _unit(_perp(lateral, thigh))
        shank = _unit(m[f"{s}ANK"] - pts[f"{s}KJC"])
        pts[f"{s}AJC"] = m[f"{s}ANK"] - ANKLE_OFFSET_M * _unit(_perp(lateral, shank))
    up = _unit(mid("C7", "CLAV") - mid("T10", "STRN"))
    fwd = _unit(_perp(mid("CLAV", "STRN") - mid("C7", "T10"), up))
    thorax = np.stack([fwd, np.cross(up, fwd), up], axis=-1)
    pts["UTHORAX"] = pts["NECK"] = mid("C7", "CLAV")
    pts["HEADC"] = mid("LFHD", "RFHD", "LBHD", "RBHD")
    for s in ("L", "R"):
        pts[f"{s}SJC"] = m[f"{s}SHO"] - SHOULDER_DROP_M * thorax[..., 2]
        pts[f"{s}EJC"] = m[f"{s}ELB"]
        pts[f"{s}WJC"] = mid(f"{s}WRA", f"{s}WRB")
    head = _frame_xy(mid("LFHD", "RFHD") - mid("LBHD", "RBHD"), mid("LFHD", "LBHD") - mid("RFHD", "RBHD"))
    frames = {"pelvis": pelvis, "thorax": thorax, "head": head}
    for s, sign in (("L", 1.0), ("R", -1.0)):
        lateral_hint = sign * (m[f"{s}MT5"] - m[f"{s}TOE"]) if f"{s}MT5" in m else pelvis[..., 1]
        frames[f"{s}foot"] = _frame_xy(m[f"{s}TOE"] - m[f"{s}HEE"], lateral_hint)
    for k, frac in (("lumbar1", 1 / 3), ("lumbar2", 2 / 3)):
        rel = Rotation.from_matrix(np.einsum("fba,fbc->fac", pelvis, thorax))
        frames[k] = pelvis @ Rotation.from_rotvec(rel.as_rotvec() * frac).as_matrix()
    return pts, frames


def read_c3d(path, *, units=None, up=None, max_gap_s: float = MAX_GAP_S, on_long_gap: str = "error") -> SourceMotion:
    """Import a C3D marker file (41-marker Vicon/CMU set) as joint centres in the project frame.

    Args:
        path: the .c3d file.
        units: marker unit ("mm", "m", ...) or metres per unit; default: the file's POINT:UNITS, else
            guessed from the leg length.
        up: the file's up axis ("z", "y", ...); guessed from head-above-ankle markers when None.
        max_gap_s: longest marker gap (s) filled silently.
        on_long_gap: "error" (default) or "warn" for longer gaps.
    """
    path = Path(path)
    markers, fps, file_units = read_markers(path)
    missing = {k: [n for n in need if n not in markers] for k, need in MARKER_SETS.items()}
    marker_set = next((k for k, miss in missing.items() if not miss), None)
    if marker_set is None:
        closest = min(missing, key=lambda k: len(missing[k]))
        raise MotionImportError(path, f"marker set lacks {', '.join(missing[closest])} (closest known set: "
                                f"{closest}; known: {', '.join(MARKER_SETS)}; labels found: "
                                f"{', '.join(sorted(markers))})")
    required = MARKER_SETS[marker_set]
    filled = fill_gaps(markers, fps, required, max_gap_s, on_long_gap, path)
    scale = parse_units(units) if units is not None else None
    unit_name = units if isinstance(units, str) else None
    if scale is None and file_units and file_units.strip().lower() in ("mm", "cm", "m"):
        unit_name = file_units.strip().lower()
        scale = parse_units(unit_name)
    up_axis = up or guess_up(0.5 * (markers["LFHD"] + markers["RFHD"]), 0.5 * (markers["LANK"] + markers["RANK"]))
    rough = float(np.nanmedian(np.linalg.norm(markers["LFWT"] - markers["LANK"], axis=1)))
    if scale is None:
        unit_name = guess_units(rough)
        if unit_name is None:
            raise MotionImportError(path, "cannot guess the marker unit; pass units=")
        scale = parse_units(unit_name)
    elif units is None and not LEG_RANGE_M[0] <= rough * scale <= LEG_RANGE_M[1]:
        raise MotionImportError(path, f"hip-to-ankle marker distance is {rough * scale:.3g} m with the file's "
                                f"POINT:UNITS {(file_units or '').strip()!r} "
                                f"(expected {LEG_RANGE_M[0]}..{LEG_RANGE_M[1]} m): wrong units in the file? "
                                "pass units=")
    c = up_rotation(up_axis) * scale
    needed = {k: markers[k] @ c.T for k in required}
    check_extent(path, needed)
    with np.errstate(invalid="ignore", divide="ignore"):
        pts, frames = joint_centres(needed)
    for name, v in (*pts.items(), *frames.items()):
        bad = ~np.isfinite(v).reshape(len(v), -1).all(axis=1)
        if bad.any():
            raise MotionImportError(path, f"{name}: degenerate marker geometry (coincident markers?)",
                                    frame=int(np.argmax(bad)))
    info = {"format": "c3d", "rig": "c3d", "units": unit_name or f"{scale} m/unit", "metres_per_unit": scale,
            "up": up_axis, "source_frames": int(len(next(iter(markers.values())))),
            "markers": len(markers), "marker_set": marker_set, "filled_gaps": filled, "max_gap_s": max_gap_s}
    # Head markers sit on a headband whose tilt varies between subjects (the raw frame looks ~15 deg up),
    # so the head's neutral is its mean orientation relative to the neck over the take instead.
    neutral = {k: np.eye(3) for k in frames if k != "head"}
    return SourceMotion(str(path), fps, pts, frames, neutral, "c3d", info)
