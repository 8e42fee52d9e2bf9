"""The seed's 21 point scatterers on head, neck, torso and limbs, attached to the skeleton.

Each scatterer sits at a fixed fraction along one bone of the rest pose and moves rigidly with that
bone. Default amplitude gains are sqrt(body-surface-area fraction): a diffusely scattering patch has a
radar cross-section proportional to its area, and power is the squared amplitude. Area fractions follow
the Lund-Browder chart for adults (head 7 %, neck 2 %, trunk 26 %, buttocks and genitals 6 %, upper
arm 4 %, forearm 3 %, hand 2.5 %, thigh 9.5 %, lower leg 7 %, foot 3.5 %; see also Mance et al. 2020,
the seed's ref. [45]); the trunk is split over chest, abdomen and the shoulders.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rtchannel.motion.pose import Rig

# name, joint it moves with, bone whose head->tail segment locates it, fraction along that bone, area
_TABLE: tuple[tuple[str, str, str, float, float], ...] = (
    ("head", "Head", "Head", 0.5, 0.07),
    ("neck", "Neck", "Neck", 0.5, 0.02),
    ("chest", "Spine1", "Spine1", 0.5, 0.09),
    ("abdomen", "Spine", "Spine", 0.3, 0.13),
    ("pelvis", "Hips", "Hips", 0.0, 0.06),
) + tuple(
    (f"{side}_{part}", joint.format(S=S, s=s), bone.format(S=S, s=s), frac, area)
    for side, S, s in (("left", "Left", "L"), ("right", "Right", "R"))
    for part, joint, bone, frac, area in (
        ("shoulder", "{S}Arm", "{S}Arm", 0.0, 0.02),
        ("upper_arm", "{S}Arm", "{S}Arm", 0.5, 0.04),
        ("forearm", "{S}ForeArm", "{S}ForeArm", 0.5, 0.03),
        ("hand", "{S}Hand", "{S}FingerBase", 0.5, 0.025),
        ("thigh", "{S}UpLeg", "{S}UpLeg", 0.45, 0.095),
        ("shin", "{S}Leg", "{S}Leg", 0.5, 0.07),
        ("foot", "{S}Foot", "{S}Foot", 0.3, 0.025),
        ("toe", "{S}ToeBase", "{S}ToeBase", 0.5, 0.01),
    )
)

SCATTERER_NAMES: tuple[str, ...] = tuple(row[0] for row in _TABLE)


@dataclass(frozen=True)
class PointScatterers:
    """Point scatterers rigidly attached to skeleton joints.

    Attributes:
        names: scatterer names [M].
        joints: index of the joint each one moves with [M].
        rest_points: rest-pose positions [M, 3] in metres.
        gains: default amplitude gains [M] (dimensionless, sum of squares = 1).
    """

    names: tuple[str, ...]
    joints: np.ndarray
    rest_points: np.ndarray
    gains: np.ndarray


def seed_scatterers(rig: Rig) -> PointScatterers:
    """The seed's 21 scatterers placed on `rig` (any height: positions follow the scaled bones)."""
    joints = np.array([rig.index(row[1]) for row in _TABLE])
    bones = np.array([rig.index(row[2]) for row in _TABLE])
    frac = np.array([row[3] for row in _TABLE])[:, None]
    rest = rig.rest[bones] + frac * (rig.tails[bones] - rig.rest[bones])
    area = np.array([row[4] for row in _TABLE])
    return PointScatterers(SCATTERER_NAMES, joints, rest, np.sqrt(area / area.sum()))
