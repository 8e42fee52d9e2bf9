"""Idle-motion amplitudes measured on real standing motion capture (the glasgow preset's `idle` values).

A person "standing still" before or after an activity keeps moving a little; `rtchannel.motion.idle` adds
band-limited random rotations per joint group to every simulated clip. This measures those rotations where
real people stand: CMU take 77_02 (a person standing, 15.6 s) and the standing part of CMU 82_08 (the first
~8.5 s, before the walk), both C3D marker takes retargeted onto the avatar rig as every imported take is.
For each joint group of `rtchannel.motion.idle.GROUPS` it takes the joint's rotation relative to its parent,
band-passes its rotation vector to the idle band (0.3-1.5 Hz, 4th-order Butterworth, zero phase) and reports
the RMS per component [deg], averaged over the group's joints; plus the RMS speed of the hands [m/s].

Run: python scripts/idle_from_mocap.py   (needs the takes: `rtchannel data fetch mocap/cmu`)
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.signal import butter, sosfiltfilt
from scipy.spatial.transform import Rotation

from rtchannel.data_registry import fetch
from rtchannel.motion.idle import GROUPS
from rtchannel.motion.pose import JOINT_INDEX, Motion

BAND_HZ = (0.3, 1.5)
FPS = 60.0
TAKES = (("mocap/cmu/stand/77_02.c3d", "standing"), ("mocap/cmu/walk/82_08.c3d", "standing, then a walk"))


def standing_span(motion: Motion, speed_mps: float = 0.3) -> tuple[int, int]:
    """Frames [start, stop) where the person stands: from 0.5 s in to 0.5 s before the 1 s-smoothed hips first
    move faster than `speed_mps` horizontally (the whole take if they never do)."""
    hips = uniform_filter1d(motion.positions[:, 0, :2], int(motion.fps), axis=0)
    speed = np.linalg.norm(np.gradient(hips, 1 / motion.fps, axis=0), axis=1)
    moving = np.flatnonzero(speed > speed_mps)
    stop = motion.n_frames if not moving.size else int(moving[0] - 0.5 * motion.fps)
    return int(0.5 * motion.fps), stop


def idle_amplitudes(motion: Motion) -> tuple[dict[str, float], float]:
    """({group: deg RMS per rotation-vector component}, hands' RMS speed [m/s]) of a standing `motion`."""
    m = motion.resampled(FPS)
    a, b = standing_span(m)
    rot, pos = m.rotations[a:b], m.positions[a:b]
    sos = butter(4, BAND_HZ, btype="band", fs=FPS, output="sos")
    out = {}
    for group, joints in GROUPS.items():
        rms = []
        for name in joints:
            j = JOINT_INDEX[name]
            local = np.einsum("fba,fbc->fac", rot[:, m.rig.parents[j]], rot[:, j])  # R_parent^T R_joint
            rv = sosfiltfilt(sos, np.unwrap(Rotation.from_matrix(local).as_rotvec(), axis=0), axis=0)
            rms.append(np.degrees(np.sqrt((rv ** 2).mean(axis=0))).mean())
        out[group] = float(np.mean(rms))
    hands = pos[:, [JOINT_INDEX["LeftHand"], JOINT_INDEX["RightHand"]]]
    speed = np.linalg.norm(np.gradient(hands, 1 / FPS, axis=0), axis=-1)
    return out, float(np.sqrt((speed ** 2).mean()))


def measured() -> dict[str, float]:
    """The mean over `TAKES` of each group's amplitude [deg], rounded to 0.01 deg (the preset's values)."""
    per_take = [idle_amplitudes(Motion.from_file(fetch(path, download=False)))[0] for path, _ in TAKES]
    return {g: round(float(np.mean([t[g] for t in per_take])), 2) for g in GROUPS}


if __name__ == "__main__":
    for path, what in TAKES:
        amps, hands = idle_amplitudes(Motion.from_file(fetch(path, download=False)))
        print(f"{path} ({what}): " + ", ".join(f"{g} {v:.2f} deg" for g, v in amps.items())
              + f"; hands {hands:.3f} m/s RMS")
    print("mean (the glasgow preset's idle):", {f"{g}_deg": v for g, v in measured().items()})
