"""Motion-layer augmentation: trim, time warp, left/right mirror, body height, heading and start.

Every parameter may be a value or, for the continuous ones, a (low, high) range drawn uniformly from
``numpy.random.default_rng(seed)`` (mirror may be a probability); the values actually used are
recorded in ``motion.params["augment"]`` (a list, one entry per call, so chains stay traceable).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from rtchannel.motion.pose import Motion
from processing.errors import InputError


def _draw(value, rng, name):
    if value is None or np.isscalar(value):
        return value
    lo, hi = (float(v) for v in value)
    if not lo <= hi:
        raise InputError(f"{name} range must be (low, high) with low <= high, got {value}")
    return float(rng.uniform(lo, hi))


def mirror_index(names) -> np.ndarray:
    """Index of each joint's left/right counterpart (itself for central joints)."""
    def swap(n: str) -> str:
        for a, b in (("Left", "Right"), ("Right", "Left")):
            if n.startswith(a):
                return b + n[len(a):]
        for a, b in (("L", "R"), ("R", "L")):
            if len(n) > 1 and n[0] == a and n[1].isupper():
                return b + n[1:]
        return n
    names = list(names)
    return np.array([names.index(swap(n)) for n in names])


def trim(motion: Motion, t0: float = 0.0, t1: float | None = None) -> Motion:
    """The frames with t0 <= t <= t1 (s, from the first frame); t1 None = to the end."""
    i0 = int(np.ceil(max(0.0, t0) * motion.fps - 1e-9))
    i1 = motion.n_frames - 1 if t1 is None else int(np.floor(min(t1, motion.duration) * motion.fps + 1e-9))
    if i1 - i0 < 1:
        raise InputError(f"trim ({t0}, {t1}) s leaves fewer than two frames of a {motion.duration:.3f} s motion")
    return replace(motion, rotations=motion.rotations[i0:i1 + 1], positions=motion.positions[i0:i1 + 1])


def time_warp(motion: Motion, time_scale: float) -> Motion:
    """The motion played `time_scale` times longer (2 = half speed), resampled to the same frame rate."""
    if not time_scale > 0:
        raise InputError(f"time_scale must be positive, got {time_scale}")
    if time_scale == 1.0:
        return motion
    slowed = replace(motion, fps=motion.fps / time_scale)
    out = slowed.resampled(motion.fps)
    return replace(out, params=dict(motion.params))


def mirror(motion: Motion) -> Motion:
    """Left/right mirror image in the vertical plane y = 0 (the rig is left/right symmetric).

    Joint j takes its counterpart's pose reflected: p'_j = M p_m(j), R'_j = M R_m(j) M, M = diag(1, -1, 1),
    which is exactly the reflection of the skinned body.
    """
    m = np.diag([1.0, -1.0, 1.0])
    idx = mirror_index(motion.rig.names)
    rest = motion.rig.rest
    if not np.allclose(rest[idx] @ m, rest, atol=1e-6):
        raise InputError("mirroring needs a left/right symmetric rig")
    pos = motion.positions[:, idx] @ m
    rot = np.einsum("ab,fjbc,cd->fjad", m, motion.rotations[:, idx], m)
    return replace(motion, positions=pos, rotations=rot)


def scale_height(motion: Motion, height: float) -> Motion:
    """The motion re-targeted onto the rig scaled to `height` m: rotations kept, positions (hence stride
    and speed) scaled by the height ratio about the floor point under the first frame's hips."""
    rig = motion.rig.scaled(height)
    s = height / motion.rig.height
    c = np.array([*motion.positions[0, 0, :2], 0.0])
    return replace(motion, rig=rig, positions=c + s * (motion.positions - c))


_trim, _mirror = trim, mirror  # augment's keyword arguments shadow these names


def augment(motion: Motion, *, height=None, time_scale=1.0, mirror=False, heading_deg=0.0,
            start=None, trim=None, seed: int | None = None) -> Motion:
    """Augmented copy of `motion`.

    Args:
        motion: the input motion.
        height: body height [m] (or a (low, high) range); None keeps it.
        time_scale: duration factor (or range): 1.25 plays 25 % slower, speeds scale by 1/time_scale.
        mirror: swap left and right (bool, or a probability in [0, 1] drawn with the seed).
        heading_deg: rotation about the vertical through the first frame's hips [deg] (or a range).
        start: (x, y) [m] to move the first frame's hips to; None keeps the position.
        trim: (t0, t1) seconds of the input to keep (t1 None = to the end), applied first.
        seed: seed for the random draws (required when any argument is a range or a probability).

    Returns:
        A new Motion; ``params["augment"]`` lists the drawn values and the seed of each call.
    """
    rng = np.random.default_rng(seed)
    needs_seed = any(v is not None and not np.isscalar(v) for v in (height, time_scale, heading_deg))
    needs_seed |= not isinstance(mirror, (bool, np.bool_))
    if needs_seed and seed is None:
        raise InputError("random augmentation (a range or a mirror probability) needs an explicit seed")
    h = _draw(height, rng, "height")
    ts = float(_draw(time_scale, rng, "time_scale"))
    mir = bool(mirror) if isinstance(mirror, (bool, np.bool_)) else bool(rng.random() < float(mirror))
    hd = float(_draw(heading_deg, rng, "heading_deg"))
    out = motion
    if trim is not None:
        out = _trim(out, *trim)
    out = time_warp(out, ts)
    if mir:
        out = _mirror(out)
    if h is not None:
        out = scale_height(out, float(h))
    if hd:
        c = np.array([*out.positions[0, 0, :2], 0.0])
        out = out.transformed(0.0, -c).transformed(np.radians(hd), c)
    if start is not None:
        st = np.asarray(start, float).reshape(-1)[:2]
        out = out.transformed(0.0, np.array([*(st - out.positions[0, 0, :2]), 0.0]))
    record = {"height": None if h is None else float(h), "time_scale": ts, "mirror": mir, "heading_deg": hd,
              "start": None if start is None else [float(x) for x in np.asarray(start).reshape(-1)[:2]],
              "trim": None if trim is None else [None if x is None else float(x) for x in trim],
              "seed": seed,
              "requested": {"height": _jsonable(height), "time_scale": _jsonable(time_scale),
                            "mirror": _jsonable(mirror), "heading_deg": _jsonable(heading_deg)}}
    history = list(motion.params.get("augment", []))
    return replace(out, params={**motion.params, "augment": history + [record]})


def _jsonable(v):
    if v is None or isinstance(v, (bool, np.bool_)):
        return None if v is None else bool(v)
    return float(v) if np.ndim(v) == 0 else [float(x) for x in v]
