"""One entry point for motion files: `load_motion` dispatches on the extension and retargets."""
from __future__ import annotations

from pathlib import Path

from rtchannel.motion.errors import MotionImportError
from rtchannel.motion.retarget import drop_leading_discontinuities, retarget
from rtchannel.body.skeleton import Motion

FORMATS = (".bvh", ".c3d")


def load_motion(path, *, fps: float | None = None, units=None, up: str | None = None,
                height: float | None = None, activity: str = "", align: bool = True,
                floor: bool = True, max_gap_s: float = 0.2, on_long_gap: str = "error") -> Motion:
    """Import a BVH or C3D file and retarget it onto the avatar rig.

    Args:
        path: a ``.bvh`` (CMU/cgspeed 31-joint or iClone CC_Base rig) or ``.c3d`` (41-marker set) file.
        fps: resample to this frame rate [Hz] (default: the file's).
        units: file length unit ("m", "cm", "mm", "in", "cmu") or metres per unit; guessed if None.
        up: the file's up axis ("y", "z", "-y", ...); guessed if None.
        height: avatar height [m]; None keeps the source's leg length (stride and speed as recorded).
        activity: activity label stored in the Motion (``walk``, ``fall``, ...).
        align: start above the origin facing +x.
        floor: level the floor, put planted feet on z = 0 and correct floating/sinking stance feet
            frame by frame; False keeps the file's vertical placement.
        max_gap_s, on_long_gap: C3D marker-gap policy (see `rtchannel.motion.c3d.fill_gaps`).

    Returns:
        The retargeted `Motion` (metres, z up, soles on the floor); ``params`` records the file, the
        detected units and up axis, dropped leading frames, filled gaps and every scaling applied.

    Raises:
        MotionImportError: unreadable, truncated or corrupted file (message names file and line/frame).
    """
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in FORMATS:
        raise MotionImportError(p, f"unsupported motion file type {ext or '(none)'!r}; expected "
                                f"{' or '.join(FORMATS)}")
    if not p.is_file():
        raise MotionImportError(p, "no such file")
    if ext == ".bvh":
        from rtchannel.motion.bvh import read_bvh

        src = read_bvh(p, units=units, up=up)
    else:
        from rtchannel.motion.c3d import read_c3d

        src = read_c3d(p, units=units, up=up, max_gap_s=max_gap_s, on_long_gap=on_long_gap)
    src, dropped = drop_leading_discontinuities(src)
    src.info["dropped_leading_frames"] = dropped
    if src.n_frames < 2:
        raise MotionImportError(p, "fewer than two usable frames")
    try:
        motion = retarget(src, height=height, activity=activity, align=align, floor=floor)
    except ValueError as exc:  # e.g. an implausible height
        raise MotionImportError(p, str(exc)) from None
    if fps is not None and fps != motion.fps:
        motion = motion.resampled(fps)
    motion.params = {**motion.params, "file": str(p), "fps": float(motion.fps), "requested_height": height}
    return motion
