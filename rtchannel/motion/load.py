"""One entry point for motion files: `load_motion` dispatches on the extension and retargets."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from processing.errors import one_line
from rtchannel.errors import ConfigError
from rtchannel.motion.errors import MotionImportError
from rtchannel.motion.retarget import drop_leading_discontinuities, retarget
from rtchannel.motion.source import check_fps, check_resampled_frames, parse_units, up_rotation
from rtchannel.motion.pose import Motion

FORMATS = (".bvh", ".c3d", ".amc", ".json", ".npz", ".csv")
PLAUSIBLE_HEIGHT_M = (1.0, 2.3)  # a person's standing height as imported (children excluded)
HEAD_ABOVE_FEET = 0.5  # first frame: head above the ankles, share of the height (standing ~0.9, seated ~0.6)
MAX_GAP_LIMIT_S = 10.0  # filling a longer marker gap by interpolation invents the motion
DEFAULT_MAX_GAP_S = 0.2  # C3D: a marker hidden for a few frames (a limb passing the body) is filled


def load_motion(path, *, fps: float | None = None, units=None, up: str | None = None,
                height: float | None = None, activity: str = "", align: bool = True,
                floor: bool = True, max_gap_s: float = DEFAULT_MAX_GAP_S, on_long_gap: str = "error",
                skeleton=None) -> Motion:
    """Import a BVH or C3D file and retarget it onto the avatar rig.

    Args:
        path: a ``.bvh`` (CMU/cgspeed 31-joint or iClone CC_Base rig), ``.c3d`` (CMU 41-marker or Vicon
            plug-in-gait set), ``.amc`` file (with its ASF `skeleton`), OpenCap/OpenSim body kinematics
            (``.json``) or named joint positions (``.npz``/``.csv``, `rtchannel.motion.joint_tracks`).
        fps: resample to this frame rate [Hz] (default: the file's).
        units: file length unit ("m", "cm", "mm", "in", "cmu") or metres per unit; guessed if None.
        up: the file's up axis ("y", "z", "-y", ...); guessed if None.
        height: avatar height [m]; None keeps the source's leg length (stride and speed as recorded).
        activity: activity label stored in the Motion (``walk``, ``fall``, ...).
        align: start above the origin facing +x.
        floor: level the floor, put planted feet on z = 0 and correct floating/sinking stance feet
            frame by frame; False keeps the file's vertical placement.
        max_gap_s, on_long_gap: C3D marker-gap policy (see `rtchannel.motion.c3d.fill_gaps`).
        skeleton: the ASF skeleton file of an ``.amc`` motion (required for AMC, refused otherwise).

    Returns:
        The retargeted `Motion` (metres, z up, soles on the floor); ``params`` records the file, the
        detected units and up axis, dropped leading frames, filled gaps and every scaling applied.

    Raises:
        MotionImportError: unreadable, truncated or corrupted file (message names file and line/frame).
        ConfigError: an argument out of range (fps outside 10..2000 Hz or too many resampled frames,
            unknown units or up axis, max_gap_s outside 0..10 s) or for another format (a skeleton for
            anything but AMC, units for OpenCap JSON, gap options for anything but C3D).
    """
    p = Path(path)
    if fps is not None:
        fps = check_fps(fps)
    if up is not None:
        up_rotation(up)  # ConfigError for anything but x, y, z, -x, -y, -z
    parse_units(units)
    if not (isinstance(max_gap_s, (int, float)) and 0 <= max_gap_s <= MAX_GAP_LIMIT_S):  # nan fails too
        raise ConfigError(f"max_gap_s: must be a number of seconds in 0..{MAX_GAP_LIMIT_S:g}, got {max_gap_s!r}")
    if on_long_gap not in ("error", "warn"):
        raise ConfigError(f"on_long_gap: must be 'error' or 'warn', got {str(on_long_gap)[:40]!r}")
    ext = p.suffix.lower()
    if ext not in FORMATS:
        raise MotionImportError(p, f"unsupported motion file type {ext or '(none)'!r}; expected "
                                f"{' or '.join(FORMATS)}")
    if not p.is_file():
        raise MotionImportError(p, "no such file")
    if (ext == ".amc") != (skeleton is not None):
        raise ConfigError(f"{p.name}: an .amc motion needs its ASF skeleton (skeleton=, --skeleton) and only an "
                          ".amc motion takes one")
    if ext == ".json" and units is not None:
        raise ConfigError(f"{p.name}: units applies to BVH, C3D, ASF/AMC and joint positions; OpenCap body "
                          "kinematics are in metres")
    if ext != ".c3d" and (max_gap_s != DEFAULT_MAX_GAP_S or on_long_gap != "error"):
        raise ConfigError(f"{p.name}: max_gap_s and on_long_gap apply to C3D marker gaps only")
    if ext == ".bvh":
        from rtchannel.motion.bvh import read_bvh

        src = read_bvh(p, units=units, up=up)
    elif ext == ".amc":
        from rtchannel.motion.asf_amc import read_asf_amc

        src = read_asf_amc(p, Path(skeleton), units=units, up=up)
    elif ext == ".json":
        from rtchannel.motion.opencap import read_opencap

        src = read_opencap(p, up=up)
    elif ext in (".npz", ".csv"):
        from rtchannel.motion.joint_tracks import read_joint_tracks

        src = read_joint_tracks(p, units=units, up=up)
    else:
        from rtchannel.motion.c3d import read_c3d

        src = read_c3d(p, units=units, up=up, max_gap_s=max_gap_s, on_long_gap=on_long_gap)
    src, dropped = drop_leading_discontinuities(src)
    src.info["dropped_leading_frames"] = dropped
    if src.n_frames < 2:
        raise MotionImportError(p, "fewer than two usable frames")
    try:
        with np.errstate(invalid="ignore", divide="ignore"):  # degenerate input is reported below, not warned
            motion = retarget(src, height=height, activity=activity, align=align, floor=floor)
    except np.linalg.LinAlgError:  # a fit over coincident points (the importers refuse the cases they know)
        raise MotionImportError(p, "degenerate skeleton or markers (coincident joints?): the retargeting fit "
                                "failed") from None
    except ValueError as exc:  # e.g. an implausible height
        raise MotionImportError(p, one_line(exc)) from None
    except KeyError as exc:  # the joint map of the detected rig names a joint the file lacks
        raise MotionImportError(p, f"the {src.kind or 'detected'} skeleton lacks joint "
                                f"{str(exc.args[0] if exc.args else '?')[:60]!r} (renamed or missing joint?)") from None
    bad = ~(np.isfinite(motion.positions).all(axis=(1, 2)) & np.isfinite(motion.rotations).all(axis=(1, 2, 3)))
    if bad.any():
        raise MotionImportError(p, "retargeting gave non-finite joint positions (degenerate skeleton or markers: "
                                "zero-length bones, coincident joints?)", frame=int(np.argmax(bad)))
    check_plausible(p, motion, height is None)
    if fps is not None and fps != motion.fps:
        check_resampled_frames(motion.duration, fps)
        motion = motion.resampled(fps)
    motion = replace(motion, params={**motion.params, "file": str(p), "fps": float(motion.fps),
                                     "requested_height": height})
    return motion


def check_plausible(path: Path, motion: Motion, own_height: bool) -> None:
    """MotionImportError (one line saying which option fixes it) unless the imported person is 1.0-2.3 m tall
    (when the height came from the file's own scale) and upright at the first frame (head at least half the
    height above the ankles: standing or seated, not upside down or on their side, as a wrong up axis leaves
    them)."""
    h = motion.rig.height
    if own_height and not PLAUSIBLE_HEIGHT_M[0] <= h <= PLAUSIBLE_HEIGHT_M[1]:
        raise MotionImportError(path, f"the person would be {h:.2f} m tall (from the file's leg length), outside "
                                f"{PLAUSIBLE_HEIGHT_M[0]:g}-{PLAUSIBLE_HEIGHT_M[1]:g} m: wrong length unit? "
                                "pass units= (or a height)")
    head = motion.positions[0, motion.rig.index("Head"), 2]
    feet = max(motion.positions[0, motion.rig.index(f"{s}Foot"), 2] for s in ("Left", "Right"))
    if head - feet < HEAD_ABOVE_FEET * h:
        raise MotionImportError(path, f"the person is not upright at the start (head {head - feet:+.2f} m above the "
                                "feet): wrong up axis? pass up= (--up)")
