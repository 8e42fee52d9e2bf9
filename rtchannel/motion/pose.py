"""The CMU-named 31-joint skeleton of the avatar and the pose-sequence contract (`Motion`).

Pose convention (used by every motion source, the skinning and the point scatterers): a pose is a
*rest-relative* global rotation ``R_j`` and a global joint position ``p_j`` per joint, such that a point
``x`` rigidly attached to joint ``j`` in the rest pose moves to ``p_j + R_j (x - rest_j)``. This is the
linear-blend-skinning transform, so skinning and the point backend see exactly the same body.

Frame: the project's (z up, metres); in the rest pose the avatar stands at the origin facing +x, its
left side on +y, soles on z = 0.
"""
from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np

from rtchannel.assets import avatar_dir
from rtchannel.errors import ConfigError
from processing.errors import InputError

# Topological order: every parent precedes its children.
JOINT_NAMES: tuple[str, ...] = (
    "Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase",
    "RHipJoint", "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase",
    "LowerBack", "Spine", "Spine1", "Neck", "Neck1", "Head",
    "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand", "LeftFingerBase", "LeftHandFinger1", "LThumb",
    "RightShoulder", "RightArm", "RightForeArm", "RightHand", "RightFingerBase", "RightHandFinger1",
    "RThumb",
)
JOINT_INDEX = {n: i for i, n in enumerate(JOINT_NAMES)}

# Blender metres (body facing -y) -> project frame (facing +x): rotate +90 deg about z, lift soles to 0.
_BLENDER_TO_PROJECT = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
SOLE_OFFSET_M = 0.81676  # lowest skin vertex of the body group in Blender z [m]
REST_HEIGHT_M = 1.66589  # soles to top of the head of the rest mesh [m]


@dataclass(frozen=True)
class Rig:
    """Joint hierarchy and rest pose.

    Attributes:
        names: joint names (CMU/cgspeed BVH names).
        parents: parent index per joint, -1 for the root.
        rest: rest-pose joint (bone head) positions [J, 3] in metres, project frame.
        tails: rest-pose bone tail positions [J, 3] in metres.
        height: standing height (soles to top of head) of the body this rig drives [m].
        shape: the body shape it drives, as hashable (name, value) pairs written by
            `rtchannel.body.shape.reshape_motion` (the skinning shapes the avatar from them), or None for
            the plain avatar. Scaling keeps the shape: the body stays geometrically similar.
    """

    names: tuple[str, ...]
    parents: np.ndarray
    rest: np.ndarray
    tails: np.ndarray
    height: float
    shape: tuple | None = None

    @property
    def n_joints(self) -> int:
        return len(self.names)

    def __repr__(self) -> str:
        return f"<Rig: {self.n_joints} joints ({self.names[0]} .. {self.names[-1]}), height {self.height:.3g} m>"

    def index(self, name: str) -> int:
        """Index of a joint (ValueError if the rig has none).

        Args:
            name: the joint's name (e.g. "Hips").
        """
        return self.names.index(name)

    def scaled(self, height: float) -> "Rig":
        """This rig uniformly scaled about the floor point under the origin.

        Args:
            height: the new standing height [m], 0.3-3 m.
        """
        if not np.isfinite(height) or height <= 0.3 or height > 3.0:
            raise InputError(f"height must be a plausible body height in metres (0.3-3 m), got {height}")
        s = height / self.height
        return replace(self, rest=self.rest * s, tails=self.tails * s, height=float(height))

    def children(self, j: int) -> list[int]:
        """Indices of the joints whose parent is a joint.

        Args:
            j: the parent's joint index.
        """
        return [k for k, p in enumerate(self.parents) if p == j]


@lru_cache(maxsize=1)
def _load_avatar_rig() -> Rig:
    raw = json.loads((avatar_dir() / "rig.cmu_mb.json").read_text())
    missing = set(JOINT_NAMES) - set(raw)
    if missing:
        raise InputError(f"rig.cmu_mb.json lacks joints {sorted(missing)}")
    heads = np.array([raw[n]["head"]["default_position"] for n in JOINT_NAMES], dtype=float)
    tails = np.array([raw[n]["tail"]["default_position"] for n in JOINT_NAMES], dtype=float)
    lift = np.array([0.0, 0.0, SOLE_OFFSET_M])
    heads = heads @ _BLENDER_TO_PROJECT.T + lift
    tails = tails @ _BLENDER_TO_PROJECT.T + lift
    parents = np.array([JOINT_INDEX[raw[n]["parent"]] if raw[n]["parent"] else -1 for n in JOINT_NAMES])
    return Rig(JOINT_NAMES, parents, heads, tails, REST_HEIGHT_M)


def avatar_rig(height: float | None = None) -> Rig:
    """The avatar's rig in the project frame, optionally scaled to `height` metres."""
    rig = _load_avatar_rig()
    return rig if height is None else rig.scaled(height)


# Frames per block of `blend_points`: keeps the blended [V, frames, 12] matrices near 50 MB for the full mesh.
_BLOCK_ELEMENTS = 6_000_000
MAX_FRAMES = 200_000  # frames of a resampled motion: 31 joints x 96 B = 0.6 GB at the limit

# How `Motion.procedural` / `Motion.from_file` are made: registered by the package `rtchannel.motion` (its
# generators and importers build on this module, so this module cannot import them).
FACTORIES: dict[str, Callable[..., "Motion"]] = {}


def _factory(kind: str) -> Callable[..., "Motion"]:
    return FACTORIES[kind]  # the package's __init__ runs (and registers) before this module is imported


def check_resampled_frames(duration_s: float, fps: float, what: str = "fps") -> int:
    """Frame count of a `duration_s` motion resampled to `fps`; `ConfigError` above `MAX_FRAMES`."""
    n = math.floor(duration_s * fps + 1e-9) + 1
    if n > MAX_FRAMES:
        raise ConfigError(f"{what}: {duration_s:.1f} s at {fps:g} Hz gives {n} frames, more than {MAX_FRAMES}")
    return n


@dataclass(frozen=True, eq=False)
class Motion:
    """A pose sequence sampled at a constant frame rate.

    Immutable: fields cannot be reassigned and the arrays are read-only views (a shape check at
    construction cannot be bypassed later); `dataclasses.replace(motion, positions=...)` makes a changed,
    validated copy. Equality is identity.

    Attributes:
        rig: the skeleton (rest pose, hierarchy, height).
        fps: frame rate [Hz].
        rotations: rest-relative global joint rotations [F, J, 3, 3] float64 (read-only).
        positions: global joint positions [F, J, 3] float64 in metres (read-only).
        activity: activity label (``walk``, ``fall``, ``sit``, ``stand``, ``pick``) or "".
        params: every parameter that produced this motion (JSON-serialisable; a private copy).
    """

    rig: Rig
    fps: float
    rotations: np.ndarray
    positions: np.ndarray
    activity: str = ""
    params: dict = field(default_factory=dict)

    @classmethod
    def procedural(cls, activity: str, **params) -> "Motion":
        """A procedural activity ("walk", "fall", "sit", "stand", "pick") on the avatar rig.

        A walk without an explicit `start` is centred on the origin along its heading, so the default 4 m walk
        toward the seed's Radar 1 (3 m away) stops 1 m short of it; other activities happen over the origin.

        Args:
            activity: "walk", "fall", "sit", "stand" or "pick".
            **params: `rtchannel.motion.procedural.ProceduralParams` fields: height [m], speed [m/s], duration
                [s], distance [m], heading_deg [deg], start (x, y) [m], seed (int), fps [Hz], ...
        """
        return _factory("procedural")(activity, **params)

    @classmethod
    def from_file(cls, path, **options) -> "Motion":
        """A motion-capture take retargeted onto the avatar rig (metres, z up, soles on the floor, starting
        over the origin facing +x).

        Args:
            path: the take (BVH, C3D, ...; see `rtchannel.motion.load.load_motion`).
            **options: `load_motion` options (height [m], activity, fps [Hz], units, up, ...).
        """
        return _factory("file")(path, **options)

    def __post_init__(self) -> None:
        f, j = self.positions.shape[:2]
        if self.rotations.shape != (f, j, 3, 3) or j != self.rig.n_joints:
            raise InputError(
                f"Motion shapes disagree: positions {self.positions.shape}, rotations "
                f"{self.rotations.shape}, rig has {self.rig.n_joints} joints")
        if f < 2:
            raise InputError("a Motion needs at least two frames")
        if not (np.isfinite(self.positions).all() and np.isfinite(self.rotations).all()):
            raise InputError("Motion contains NaN or infinite joint data")
        if not self.fps > 0:
            raise InputError(f"fps must be positive, got {self.fps}")
        for name in ("rotations", "positions"):
            view = np.asarray(getattr(self, name)).view()  # the caller's array stays writeable
            view.flags.writeable = False
            object.__setattr__(self, name, view)
        object.__setattr__(self, "params", dict(self.params))

    def __repr__(self) -> str:
        label = self.activity or "motion"
        return (f"<Motion {label!r}: {self.n_frames} frames at {self.fps:g} Hz ({self.duration:.2f} s), "
                f"{self.rig.n_joints} joints, height {self.rig.height:.2f} m; positions [frames, joints, 3] m>")

    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]

    @property
    def times(self) -> np.ndarray:
        """Frame times [s], starting at 0."""
        return np.arange(self.n_frames) / self.fps

    @property
    def duration(self) -> float:
        """Time from the first to the last frame [s]."""
        return (self.n_frames - 1) / self.fps

    def attached_points(self, joints: np.ndarray, rest_points: np.ndarray) -> np.ndarray:
        """Trajectories [F, M, 3] float64 (m) of points rigidly attached to joints.

        Args:
            joints: joint index of each point [M] (int).
            rest_points: the points in the rest pose [M, 3] float (m).
        """
        joints = np.asarray(joints)
        local = rest_points - self.rig.rest[joints]
        return self.positions[:, joints] + np.einsum("fmab,mb->fma", self.rotations[:, joints], local)

    def skinning_matrices(self) -> np.ndarray:
        """Per-frame linear-blend-skinning transforms [F, J, 3, 4]: x -> R_j x + (p_j - R_j rest_j)."""
        t = self.positions - np.einsum("fjab,jb->fja", self.rotations, self.rig.rest)
        return np.concatenate([self.rotations, t[..., None]], axis=-1)

    def resampled(self, fps: float) -> "Motion":
        """The same motion at another frame rate: slerp for rotations, cubic splines for positions.

        Args:
            fps: the new frame rate [Hz] (finite, > 0).
        """
        if fps == self.fps:
            return self
        if not (isinstance(fps, (int, float, np.number)) and 0 < fps < float("inf")):
            raise ConfigError(f"fps: must be a positive finite frame rate in Hz, got {fps!r}")
        t_old = self.times
        n_new = check_resampled_frames(self.duration, fps)
        t_new = np.arange(n_new) / fps
        from scipy.interpolate import CubicSpline  # here: the CLI's parser imports this module
        from scipy.spatial.transform import Rotation, Slerp

        pos = CubicSpline(t_old, self.positions, axis=0)(t_new)
        rot = np.empty((n_new, self.rig.n_joints, 3, 3))
        for j in range(self.rig.n_joints):
            rot[:, j] = Slerp(t_old, Rotation.from_matrix(self.rotations[:, j]))(t_new).as_matrix()
        return replace(self, fps=float(fps), rotations=rot, positions=pos,
                       params={**self.params, "resampled_fps": float(fps)})

    def transformed(self, yaw_rad: float = 0.0, offset=(0.0, 0.0, 0.0)) -> "Motion":
        """The motion rotated about the vertical through the origin, then shifted.

        Args:
            yaw_rad: rotation about +z [rad], counter-clockwise seen from above.
            offset: shift (x, y, z) [m] applied after the rotation.
        """
        rz = _yaw_matrix(yaw_rad)
        pos = self.positions @ rz.T + np.asarray(offset, dtype=float)
        rot = np.einsum("ab,fjbc->fjac", rz, self.rotations)
        return replace(self, positions=pos, rotations=rot)


def _yaw_matrix(yaw_rad: float) -> np.ndarray:
    """The rotation matrix [3, 3] about +z by `yaw_rad` [rad], from the unit quaternion (0, 0, sin, cos) of
    half the angle, in the operations of `scipy.spatial.transform.Rotation.from_euler("z", yaw).as_matrix()`
    (bit-identical, tests/test_cubic.py), without importing scipy.spatial."""
    z, w = np.sin(0.5 * yaw_rad), np.cos(0.5 * yaw_rad)
    z2, w2, zw = z * z, w * w, z * w
    # x = y = 0: the quaternion formula's other terms vanish exactly
    return np.array([[0.0 - 0.0 - z2 + w2, 2 * (0.0 - zw), 2 * (0.0 + 0.0)],
                     [2 * (0.0 + zw), -0.0 + 0.0 - z2 + w2, 2 * (0.0 - 0.0)],
                     [2 * (0.0 - 0.0), 2 * (0.0 + 0.0), -0.0 - 0.0 + z2 + w2]])


def forward_kinematics(rig: Rig, local_rotations: np.ndarray, root_positions: np.ndarray) -> tuple[
        np.ndarray, np.ndarray]:
    """Global rest-relative rotations and joint positions from local ones.

    Args:
        rig: the skeleton.
        local_rotations: [F, J, 3, 3] rotation of each joint relative to its parent, expressed in the
            world-aligned rest frame (identity everywhere gives the rest pose).
        root_positions: [F, 3] position of the root joint (Hips) in metres.

    Returns:
        (rotations [F, J, 3, 3], positions [F, J, 3]) as `Motion` expects them.
    """
    f = local_rotations.shape[0]
    rot = np.empty_like(local_rotations)
    pos = np.empty((f, rig.n_joints, 3))
    for j, p in enumerate(rig.parents):
        if p < 0:
            rot[:, j] = local_rotations[:, j]
            pos[:, j] = root_positions
        else:
            rot[:, j] = rot[:, p] @ local_rotations[:, j]
            pos[:, j] = pos[:, p] + rot[:, p] @ (rig.rest[j] - rig.rest[p])
    return rot, pos


def blend_points(weights, rest: np.ndarray, mats: np.ndarray) -> np.ndarray:
    """Apply blended affine transforms to points.

    Args:
        weights: skinning weights [P, J] (sparse or dense).
        rest: rest positions [P, 3] (m).
        mats: per-frame joint transforms [F, J, 3, 4] (skinning matrices or their derivatives).

    Returns:
        [F, P, 3]: sum_j w_pj mats[f, j] [rest_p; 1].
    """
    f, j = mats.shape[:2]
    p = rest.shape[0]
    from scipy import sparse

    w = sparse.csr_matrix(weights)
    xh = np.concatenate([rest, np.ones((p, 1))], axis=1)
    out = np.empty((f, p, 3))
    block = max(1, _BLOCK_ELEMENTS // max(1, 12 * p))
    for s in range(0, f, block):
        m = mats[s:s + block]
        nb = m.shape[0]
        # [J, nb*12] so one sparse product blends every frame of the block at once.
        blended = (w @ m.transpose(1, 0, 2, 3).reshape(j, nb * 12)).reshape(p, nb, 3, 4)
        out[s:s + nb] = np.einsum("pfab,pb->fpa", blended, xh, optimize=True)
    return out
