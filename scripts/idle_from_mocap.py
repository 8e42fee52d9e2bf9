"""Idle-motion amplitudes measured on real standing motion capture (the glasgow preset's `idle` values).

A person "standing still" before or after an activity keeps moving a little; `rtchannel.motion.idle` adds
band-limited random rotations per joint group to every simulated clip. This measures those rotations where
real people stand: CMU take 77_02 (a person standing, 15.6 s) and the standing part of CMU 82_08 (the first
~8.5 s, before the walk), both C3D marker takes retargeted onto the avatar rig as every imported take is.
Quiet standing is an inverted pendulum about the ankles (Winter 1995): the whole body tilts together, so the
sway is measured as the tilt of the chest (`Spine1`) about the midpoint of the ankles, band-passed to the
idle band (0.3-1.5 Hz, 4th-order Butterworth, zero phase), RMS per horizontal axis [deg]. On top of it, for
each joint group of `rtchannel.motion.idle.GROUPS`, the joint's rotation relative to its parent, band-passed
the same way, RMS per rotation-vector component [deg], averaged over the group's joints.

The radar sees speeds, not angles. Real sway has most of its power at the low end of the band (a 1/f-like
spectrum), while `rtchannel.motion.idle` draws noise that is flat across the band, so the same angle gives a
faster motion in simulation (measured: 1.5x). The preset's amplitudes are therefore the measured ones times one
factor that makes the simulated band-limited RMS speeds of chest, head and hands equal the real ones in the
least-squares sense (`matched`); their ratios stay as measured.

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
    """({"sway" or group: deg RMS per axis or component}, hands' RMS speed [m/s]) of a standing `motion`."""
    m = motion.resampled(FPS)
    a, b = standing_span(m)
    rot, pos = m.rotations[a:b], m.positions[a:b]
    sos = butter(4, BAND_HZ, btype="band", fs=FPS, output="sos")
    d = pos[:, JOINT_INDEX["Spine1"]] - pos[:, [JOINT_INDEX["LeftFoot"], JOINT_INDEX["RightFoot"]]].mean(axis=1)
    tilt = np.stack([-np.arctan2(d[:, 1], d[:, 2]), np.arctan2(d[:, 0], d[:, 2])], axis=1)  # about x, about y
    out = {"sway": float(np.degrees(np.sqrt((sosfiltfilt(sos, tilt, axis=0) ** 2).mean(axis=0))).mean())}
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
    """The mean over `TAKES` of the sway's and each group's amplitude [deg], rounded to 0.01 deg (the preset's
    values)."""
    per_take = [idle_amplitudes(Motion.from_file(fetch(path, download=False)))[0] for path, _ in TAKES]
    return {g: round(float(np.mean([t[g] for t in per_take])), 2) for g in ("sway", *GROUPS)}


def matched(seeds: int = 8) -> tuple[dict[str, float], float]:
    """(the preset's amplitudes {"sway" or group: deg, rounded to 0.01}, the factor applied to `measured`)."""
    real = []
    for path, _ in TAKES:
        r = Motion.from_file(fetch(path, download=False)).resampled(FPS)
        a, b = standing_span(r)
        real.append(band_speeds(r.positions[a:b]))
    target = {k: float(np.mean([x[k] for x in real])) for k in real[0]}
    amps = measured()
    sim = simulated_speeds(amps, seeds)
    factor = sum(sim[k] * target[k] for k in sim) / sum(sim[k] ** 2 for k in sim)  # speeds scale with amplitude
    return {k: round(v * factor, 2) for k, v in amps.items()}, factor


def band_speeds(positions: np.ndarray) -> dict[str, float]:
    """Band-limited (`BAND_HZ`) RMS speeds [m/s] of chest, head and hands of joint positions [F, J, 3] at `FPS`."""
    sos = butter(4, BAND_HZ, btype="band", fs=FPS, output="sos")
    out = {}
    for part, joints in (("chest", ["Spine1"]), ("head", ["Head"]), ("hands", ["LeftHand", "RightHand"])):
        p = sosfiltfilt(sos, positions[:, [JOINT_INDEX[j] for j in joints]], axis=0)
        out[part] = float(np.sqrt((np.linalg.norm(np.gradient(p, 1 / FPS, axis=0), axis=-1) ** 2).mean()))
    return out


def simulated_speeds(amplitudes: dict[str, float], seeds: int = 8) -> dict[str, float]:
    """`band_speeds` of a procedural person standing still for 20 s with idle motion of `amplitudes`
    ({"sway" or group: deg}), RMS over `seeds` draws."""
    from rtchannel.motion.idle import IdleMotion, add_idle

    pose = Motion.procedural("stand", height=1.75, seed=0).resampled(FPS)
    still = Motion(rig=pose.rig, fps=FPS, rotations=np.repeat(pose.rotations[-1:], int(20 * FPS), 0),
                   positions=np.repeat(pose.positions[-1:], int(20 * FPS), 0), activity="stand")
    idle = IdleMotion(**{f"{k}_deg": v for k, v in amplitudes.items()})
    runs = [band_speeds(add_idle(still, idle, k).positions) for k in range(seeds)]
    return {p: float(np.sqrt(np.mean([r[p] ** 2 for r in runs]))) for p in runs[0]}


if __name__ == "__main__":
    real = []
    for path, what in TAKES:
        m = Motion.from_file(fetch(path, download=False))
        amps, hands = idle_amplitudes(m)
        r = m.resampled(FPS)
        a, b = standing_span(r)
        real.append(band_speeds(r.positions[a:b]))
        print(f"{path} ({what}): " + ", ".join(f"{g} {v:.2f} deg" for g, v in amps.items())
              + "; band-limited speeds " + ", ".join(f"{k} {v:.3f}" for k, v in real[-1].items()) + " m/s")
    amps = measured()
    print("mean angles:", {f"{g}_deg": v for g, v in amps.items()})
    sim = simulated_speeds(amps)
    print("speeds [m/s], real (mean of the takes) / simulated with the mean angles: " + ", ".join(
        f"{k} {np.mean([x[k] for x in real]):.3f} / {sim[k]:.3f}" for k in sim))
    preset, factor = matched()
    sim = simulated_speeds(preset)
    print(f"speed-matched (x {factor:.3f}; the glasgow preset's idle):", {f"{g}_deg": v for g, v in preset.items()})
    print("speeds [m/s], real / simulated with them: " + ", ".join(
        f"{k} {np.mean([x[k] for x in real]):.3f} / {sim[k]:.3f}" for k in sim))
