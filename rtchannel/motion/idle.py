"""Idle motion: the small, slow, random movements of a person who is "standing still" (or sitting, or walking).

Real people never hold a pose: they shift, look around, move their arms and hands. A held pose is removed
completely by a radar's clutter filter (the Glasgow MTI cuts below 0.1 m/s), so a simulated clip is blank
before and after its activity, where real recordings keep a weak line near 0 m/s. This adds band-limited
Gaussian joint rotations to the upper body (spine, neck and head, shoulders, arms, forearms, hands) on top
of any motion. The legs and the hips are left alone, so planted feet stay planted. A body lying on the floor
(after a fall) lies still: the amplitude fades from full to none as the hips go from `lying_fade` of their
standing height down to 2/3 of that (real falls in the Glasgow recordings are blank after the impact, while sit,
stand and pick recordings keep their 0 m/s line to the end).

On top of the joints, `sway_deg` tilts the whole body about the midpoint of its ankles by band-limited angles
about both horizontal axes: quiet standing is an inverted pendulum (Winter 1995), so trunk, head and arms sway
together with the hips, which the joint rotations alone (hips fixed) cannot give.

Each perturbed joint gets three independent rotation-vector components (axes of the world-aligned rest frame),
each Gaussian noise band-passed to `band_hz` (4th-order Butterworth, zero phase) and scaled to `rms_deg` of
its group, so a clip's realised RMS per component is exactly the requested one. The perturbation is applied to
the joint's local rotation (relative to its parent), so children follow their parents as in a real body.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator
from scipy.signal import butter, sosfiltfilt
from scipy.spatial.transform import Rotation

from rtchannel.motion.pose import Motion
from processing.errors import InputError

# joint groups of the avatar rig (CMU naming) whose local rotations are perturbed
GROUPS = {
    "spine": ("LowerBack", "Spine", "Spine1"),
    "neck": ("Neck", "Neck1", "Head"),
    "shoulder": ("LeftArm", "RightArm"),
    "elbow": ("LeftForeArm", "RightForeArm"),
    "wrist": ("LeftHand", "RightHand"),
}


class IdleMotion(BaseModel):
    """Amplitudes [deg RMS per rotation axis] per joint group and the frequency band [Hz] of idle motion.

    Defaults: plausible fidgeting rather than a measurement - trunk 0.7 deg per joint (three spine joints:
    ~1.2 deg at the chest; postural sway is ~0.5-1 deg), head 1 deg, upper arms 1.7 deg, forearms 2 deg, hands
    2.7 deg, at 0.3-1.5 Hz: the hands move at ~0.15 m/s RMS, above the Glasgow MTI cut-off (0.1 m/s), unlike
    postural sway (~0.01 m/s). The glasgow preset used these until they were found to have been chosen while
    looking at real test recordings; it now uses amplitudes measured on real standing motion capture
    (`scripts/idle_from_mocap.py`: trunk 0.21, head 1.41, upper arms 0.33, forearms 0.89, hands 0.42 deg).
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    sway_deg: float = Field(0.0, ge=0, le=10, description="whole-body sway about the ankles [deg RMS per "
                            "horizontal axis]: quiet standing is an inverted pendulum (Winter 1995, Gait Posture "
                            "3:193), so the trunk, head and arms move together with the hips")
    spine_deg: float = Field(0.7, ge=0, le=20)
    neck_deg: float = Field(1.0, ge=0, le=30)
    shoulder_deg: float = Field(1.7, ge=0, le=30)
    elbow_deg: float = Field(2.0, ge=0, le=30)
    wrist_deg: float = Field(2.7, ge=0, le=30)
    band_hz: tuple[float, float] = Field((0.3, 1.5), description="pass band [Hz] of the joint angles")
    lying_fade: float = Field(0.45, ge=0, le=1, description="hips height (share of standing) below which idle "
                              "motion fades out, to none at 2/3 of it")

    @model_validator(mode="after")
    def _band(self):
        lo, hi = self.band_hz
        if not 0 < lo < hi <= 10:
            raise InputError(f"band_hz must be 0 < low < high <= 10 Hz, got {list(self.band_hz)}")
        return self

    def scaled(self, factor: float) -> "IdleMotion":
        """These settings with every amplitude times `factor` (validated: ValidationError when out of range)."""
        return IdleMotion(**{**self.model_dump(), "sway_deg": self.sway_deg * factor,
                             **{f"{g}_deg": getattr(self, f"{g}_deg") * factor for g in GROUPS}})

    def rms(self) -> dict[str, float]:
        """{group: deg RMS}."""
        return {g: getattr(self, f"{g}_deg") for g in GROUPS}


def band_noise(n: int, fps: float, band_hz, rng: np.random.Generator, size: int = 1) -> np.ndarray:
    """[size, n] Gaussian noise band-passed to `band_hz` [Hz] at `fps` [Hz], each row scaled to unit RMS."""
    lo, hi = band_hz
    nyq = fps / 2
    if hi >= nyq:
        raise InputError(f"idle band {lo}-{hi} Hz needs a frame rate above {2 * hi} Hz, got {fps}")
    pad = int(np.ceil(3 * fps / lo))  # filter settling either side, so the clip's ends are not damped
    x = rng.standard_normal((size, n + 2 * pad))
    y = sosfiltfilt(butter(4, [lo / nyq, hi / nyq], btype="band", output="sos"), x, axis=1)[:, pad:pad + n]
    return y / np.sqrt(np.mean(y ** 2, axis=1, keepdims=True))


def add_idle(motion: Motion, idle: IdleMotion, seed: int) -> Motion:
    """`motion` with idle joint rotations added (see the module docstring); recorded in params["idle"].

    Args:
        motion: any motion on a rig with the CMU joint names of `GROUPS` (missing joints are skipped).
        idle: amplitudes [deg RMS] and band [Hz].
        seed: random seed of the noise.
    """
    rig, n = motion.rig, motion.n_frames
    if n < 2:
        return motion
    rot, pos = motion.rotations, motion.positions
    names = list(rig.names)
    rng = np.random.default_rng(seed)
    ratio = pos[:, 0, 2] / max(float(rig.rest[0, 2]), 1e-6)
    lo = idle.lying_fade * 2 / 3
    weight = np.clip((ratio - lo) / max(idle.lying_fade - lo, 1e-9), 0.0, 1.0)[:, None]
    delta = {}
    for group, deg in idle.rms().items():
        for name in GROUPS[group]:
            if deg > 0 and name in names:
                rv = np.deg2rad(deg) * weight * band_noise(n, motion.fps, idle.band_hz, rng, 3).T  # [n, 3]
                delta[names.index(name)] = Rotation.from_rotvec(rv).as_matrix()
    new_rot, new_pos = rot.copy(), pos.copy()
    moved = np.zeros(rig.n_joints, bool)
    for j, p in enumerate(rig.parents):  # parents come before children
        if p < 0 or not (moved[p] or j in delta):
            continue
        moved[j] = True
        # the parent's change of orientation carries the joint's offset and its own rotation along; the
        # stored bone vector is kept (whatever bone lengths the source has)
        turn = new_rot[:, p] @ np.swapaxes(rot[:, p], -1, -2)
        local = np.swapaxes(rot[:, p], -1, -2) @ rot[:, j]
        if j in delta:
            local = local @ delta[j]
        new_rot[:, j] = new_rot[:, p] @ local
        new_pos[:, j] = new_pos[:, p] + np.einsum("fab,fb->fa", turn, pos[:, j] - pos[:, p])
    if idle.sway_deg > 0:  # drawn after the joints' noise: motions without sway keep their draws
        new_rot, new_pos = _sway(new_rot, new_pos, names, idle, weight, motion.fps, rng)
    params = {**motion.params, "idle": {**idle.model_dump(mode="json"), "seed": int(seed)}}
    return replace(motion, rotations=new_rot, positions=new_pos, params=params)


def _sway(rot: np.ndarray, pos: np.ndarray, names: list[str], idle: IdleMotion, weight: np.ndarray, fps: float,
          rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Rotations [F, J, 3, 3] and positions [F, J, 3] (m) turned as one body by band-limited angles about the
    two horizontal axes through the midpoint of the ankles (`LeftFoot`, `RightFoot`; the hips' ground point
    without them): the inverted pendulum of quiet standing. A 0.3 deg tilt moves the toes by < 1 mm."""
    n = pos.shape[0]
    tilt = np.deg2rad(idle.sway_deg) * weight * band_noise(n, fps, idle.band_hz, rng, 2).T  # [F, 2] about x, y
    turn = Rotation.from_rotvec(np.concatenate([tilt, np.zeros((n, 1))], axis=1)).as_matrix()
    ankles = [names.index(j) for j in ("LeftFoot", "RightFoot") if j in names]
    pivot = pos[:, ankles].mean(axis=1) if ankles else pos[:, 0] * (1.0, 1.0, 0.0)
    new_pos = pivot[:, None] + np.einsum("fab,fjb->fja", turn, pos - pivot[:, None])
    return np.einsum("fab,fjbc->fjac", turn, rot), new_pos
