"""Joint maps from known source skeletons onto the avatar's CMU-named rig, and their neutral poses.

Each avatar bone maps to (source point from, source point to, twist) with twist ("orient", joint) for
the joint whose orientation carries the bone, ("vec", a, b) for a marker vector a -> b rigid with the
bone, ("only", joint) for an orientation without a usable direction, or None. "|" separates
alternative source names. Bones in `POSTURE` copy the source orientation relative to its neutral pose
(their bone directions are rig-specific: the iClone lumbar bone leans 36 deg forward, its ankle sits
higher); the other (limb) bones are matched by direction, which is rig-independent.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

POSTURE = frozenset({"Hips", "LowerBack", "Spine", "Spine1", "Neck", "Neck1", "Head",
                     "LeftFoot", "RightFoot", "LeftToeBase", "RightToeBase"})

_CC = "CC_Base_"
_SIDES = (("Left", "L"), ("Right", "R"))

JOINT_MAPS: dict[str, dict] = {
    "cc": {
        "hips": ("CC_Base_L_Thigh", "CC_Base_R_Thigh"),
        "leg": ("CC_Base_L_Thigh", "CC_Base_L_Calf", "CC_Base_L_Foot"),
        "bones": {
            "Hips": ("CC_Base_R_Thigh", "CC_Base_L_Thigh", ("orient", "CC_Base_Pelvis")),
            **{f"{S}{a}": (f"{_CC}{s}_{b}", f"{_CC}{s}_{c}", ("orient", f"{_CC}{s}_{b}"))
               for S, s in _SIDES
               for a, b, c in (("UpLeg", "Thigh", "Calf"), ("Leg", "Calf", "Foot"), ("Foot", "Foot", "ToeBase"),
                               ("ToeBase", "ToeBase", "MidToe1"), ("Shoulder", "Clavicle", "Upperarm"),
                               ("Arm", "Upperarm", "Forearm"), ("ForeArm", "Forearm", "Hand"),
                               ("Hand", "Hand", "Mid1"), ("FingerBase", "Mid1", "Mid2"),
                               ("HandFinger1", "Mid2", "Mid3"))},
            **{f"{s}Thumb": (f"{_CC}{s}_Thumb1", f"{_CC}{s}_Thumb2", ("orient", f"{_CC}{s}_Thumb1"))
               for _, s in _SIDES},
            "LowerBack": ("CC_Base_Waist", "CC_Base_Spine01", ("orient", "CC_Base_Waist")),
            "Spine": ("CC_Base_Spine01", "CC_Base_Spine02", ("orient", "CC_Base_Spine01")),
            "Spine1": ("CC_Base_Spine02", "CC_Base_NeckTwist01", ("orient", "CC_Base_Spine02")),
            "Neck": ("CC_Base_NeckTwist01", "CC_Base_NeckTwist02", ("orient", "CC_Base_NeckTwist01")),
            "Neck1": ("CC_Base_NeckTwist02", "CC_Base_Head", ("orient", "CC_Base_NeckTwist02")),
            "Head": (None, None, ("only", "CC_Base_Head")),
        },
    },
    "cmu": {
        "hips": ("LeftUpLeg", "RightUpLeg"),
        "leg": ("LeftUpLeg", "LeftLeg", "LeftFoot"),
        "bones": {
            "Hips": ("RightUpLeg", "LeftUpLeg", ("orient", "Hips")),
            **{f"{S}{a}": (f"{S}{a}", f"{S}{b}", ("orient", f"{S}{a}"))
               for S, _ in _SIDES
               for a, b in (("UpLeg", "Leg"), ("Leg", "Foot"), ("Foot", "ToeBase"), ("Shoulder", "Arm"),
                            ("Arm", "ForeArm"), ("ForeArm", "Hand"), ("Hand", "FingerBase"))},
            **{f"{S}ToeBase": (f"{S}ToeBase", f"{S}ToeBase/End", ("orient", f"{S}ToeBase")) for S, _ in _SIDES},
            **{f"{S}FingerBase": (f"{S}FingerBase", f"{S}HandIndex1|{S}HandFinger1", ("orient", f"{S}FingerBase"))
               for S, _ in _SIDES},
            **{f"{S}HandFinger1": (f"{S}HandIndex1|{S}HandFinger1", f"{S}HandIndex1/End|{S}HandFinger1/End",
                                   ("orient", f"{S}HandIndex1|{S}HandFinger1")) for S, _ in _SIDES},
            **{f"{s}Thumb": (f"{s}Thumb", f"{s}Thumb/End", ("orient", f"{s}Thumb")) for _, s in _SIDES},
            **{f"{s}HipJoint": (f"{s}HipJoint", f"{S}UpLeg", ("orient", f"{s}HipJoint")) for S, s in _SIDES},
            "LowerBack": ("LowerBack", "Spine", ("orient", "LowerBack")),
            "Spine": ("Spine", "Spine1", ("orient", "Spine")),
            "Spine1": ("Spine1", "Neck", ("orient", "Spine1")),
            "Neck": ("Neck", "Neck1", ("orient", "Neck")),
            "Neck1": ("Neck1", "Head", ("orient", "Neck1")),
            "Head": ("Head", "Head/End", ("orient", "Head")),
        },
    },
    # cgspeed's "Daz-friendly" CMU conversion (Daz/Genesis names): hip, abdomen, chest, neck, head; lCollar,
    # lShldr, lForeArm, lHand, fingers; lButtock, lThigh, lShin, lFoot (no toe joint: the toes follow the foot)
    "daz": {
        "hips": ("lThigh", "rThigh"),
        "leg": ("lThigh", "lShin", "lFoot"),
        "bones": {
            "Hips": ("rThigh", "lThigh", ("orient", "hip")),
            **{f"{S}{a}": (f"{s}{b}", f"{s}{c}", ("orient", f"{s}{b}"))
               for S, s in (("Left", "l"), ("Right", "r"))
               for a, b, c in (("UpLeg", "Thigh", "Shin"), ("Leg", "Shin", "Foot"), ("Shoulder", "Collar", "Shldr"),
                               ("Arm", "Shldr", "ForeArm"), ("ForeArm", "ForeArm", "Hand"), ("Hand", "Hand", "Mid1"),
                               ("FingerBase", "Mid1", "Mid2"))},
            **{f"{S}Foot": (f"{s}Foot", f"{s}Foot/End", ("orient", f"{s}Foot"))
               for S, s in (("Left", "l"), ("Right", "r"))},
            **{f"{S}HandFinger1": (f"{s}Mid2", f"{s}Mid2/End", ("orient", f"{s}Mid2"))
               for S, s in (("Left", "l"), ("Right", "r"))},
            **{f"{s.upper()}Thumb": (f"{s}Thumb1", f"{s}Thumb2", ("orient", f"{s}Thumb1")) for s in ("l", "r")},
            **{f"{s.upper()}HipJoint": (f"{s}Buttock", f"{s}Thigh", ("orient", f"{s}Buttock")) for s in ("l", "r")},
            "LowerBack": ("abdomen", "chest", ("orient", "abdomen")),
            "Spine": ("chest", "neck", ("orient", "chest")),
            "Spine1": ("chest", "neck", ("orient", "chest")),
            "Neck": ("neck", "head", ("orient", "neck")),
            "Neck1": ("neck", "head", ("orient", "neck")),
            "Head": (None, None, ("only", "head")),
        },
    },
    # Mixamo (Adobe) rigs, namespace prefix removed: three spine bones, one neck, no hip joints
    "mixamo": {
        "hips": ("LeftUpLeg", "RightUpLeg"),
        "leg": ("LeftUpLeg", "LeftLeg", "LeftFoot"),
        "bones": {
            "Hips": ("RightUpLeg", "LeftUpLeg", ("orient", "Hips")),
            **{f"{S}{a}": (f"{S}{b}", f"{S}{c}", ("orient", f"{S}{b}"))
               for S, _ in _SIDES
               for a, b, c in (("UpLeg", "UpLeg", "Leg"), ("Leg", "Leg", "Foot"), ("Foot", "Foot", "ToeBase"),
                               ("Shoulder", "Shoulder", "Arm"), ("Arm", "Arm", "ForeArm"),
                               ("ForeArm", "ForeArm", "Hand"))},
            **{f"{S}Hand": (f"{S}Hand", f"{S}HandMiddle1|{S}HandIndex1", ("orient", f"{S}Hand")) for S, _ in _SIDES},
            **{f"{S}ToeBase": (f"{S}ToeBase", f"{S}ToeBase/End|{S}Toe_End", ("orient", f"{S}ToeBase"))
               for S, _ in _SIDES},
            "LowerBack": ("Spine", "Spine1", ("orient", "Spine")),
            "Spine": ("Spine1", "Spine2", ("orient", "Spine1")),
            "Spine1": ("Spine2", "Neck", ("orient", "Spine2")),
            "Neck": ("Neck", "Head", ("orient", "Neck")),
            "Neck1": ("Neck", "Head", ("orient", "Neck")),
            "Head": (None, None, ("only", "Head")),
        },
    },
    "c3d": {
        "hips": ("LHJC", "RHJC"),
        "leg": ("LHJC", "LKJC", "LAJC"),
        "bones": {
            "Hips": ("RHJC", "LHJC", ("orient", "pelvis")),
            "LowerBack": (None, None, ("orient", "lumbar1")),
            "Spine": (None, None, ("orient", "lumbar2")),
            "Spine1": (None, None, ("orient", "thorax")),
            "Neck": ("NECK", "HEADC", None),
            "Neck1": ("NECK", "HEADC", None),
            "Head": (None, None, ("orient", "head")),
            **{f"{S}{a}": (f"{s}{b}".replace(f"{s}UTHORAX", "UTHORAX"), f"{s}{c}", tw)
               for S, s in _SIDES for a, b, c, tw in (
                ("UpLeg", "HJC", "KJC", ("vec", f"{s}KJC", f"{s}KNE")),
                ("Leg", "KJC", "AJC", ("vec", f"{s}AJC", f"{s}ANK")),
                ("Shoulder", "UTHORAX", "SJC", None),
                ("Arm", "SJC", "EJC", ("vec", f"{s}EJC", f"{s}ELB")),
                ("ForeArm", "EJC", "WJC", ("vec", f"{s}WRB", f"{s}WRA")),
                ("Hand", "WJC", "FIN", ("vec", f"{s}WRB", f"{s}WRA")))},
            **{f"{S}Foot": (None, None, ("orient", f"{s}foot")) for S, s in _SIDES},
        },
    },
}

# Neutral (T-pose) global orientations of the iClone CC_Base rig, as quaternions (x, y, z, w) in the
# project frame with the body facing +x: the converter's T-pose (frame 0 of CMU 07_03 as converted by
# iClone), which is the rig's bind pose; the BVH zero pose of this rig is not a T-pose.
_CC_NEUTRAL_Q = {
    "Hip": (0.499155, 0.500842, 0.499160, 0.500840),
    "Pelvis": (0.547878, 0.549384, 0.445175, 0.447019),
    "Waist": (0.565590, 0.565593, 0.424391, 0.424387),
    "Spine01": (0.477645, 0.477649, 0.521398, 0.521393),
    "Spine02": (0.452987, 0.452961, 0.542968, 0.542968),
    "NeckTwist01": (0.546543, 0.546500, 0.448667, 0.448695),
    "NeckTwist02": (0.540255, 0.540211, 0.456210, 0.456254),
    "Head": (0.499953, 0.499941, 0.500051, 0.500054),
    "L_Thigh": (0.479577, -0.477374, 0.522010, -0.519255),
    "L_Calf": (0.521496, -0.518059, 0.480788, -0.478016),
    "L_Foot": (-0.086726, 0.072011, -0.663843, 0.739328),
    "L_ToeBase": (0.048971, -0.019712, -0.683284, 0.728242),
    "L_Clavicle": (-0.082149, 0.703079, 0.102044, 0.698941),
    "L_Upperarm": (-0.012113, 0.707117, -0.018456, 0.706751),
    "L_Forearm": (-0.003415, 0.707238, -0.011675, 0.706871),
    "L_Hand": (-0.050019, 0.705623, -0.020541, 0.706522),
    "L_Mid1": (-0.018806, 0.704724, -0.032198, 0.708501),
    "L_Mid2": (-0.024294, 0.707318, -0.029058, 0.705880),
    "L_Thumb1": (0.229427, 0.554894, -0.300093, 0.741215),
    "R_Thigh": (-0.479015, 0.482982, -0.517565, 0.519037),
    "R_Calf": (-0.515121, 0.519983, -0.481107, 0.482497),
    "R_Foot": (0.071717, -0.086832, 0.740307, -0.662768),
    "R_ToeBase": (-0.019822, 0.049038, 0.729320, -0.682125),
    "R_Clavicle": (0.703091, -0.082141, 0.698936, 0.101997),
    "R_Upperarm": (0.708538, -0.011241, 0.705317, -0.019367),
    "R_Forearm": (0.708644, -0.002606, 0.705451, -0.012484),
    "R_Hand": (0.707059, -0.050315, 0.705068, -0.020374),
    "R_Mid1": (0.706162, -0.017948, 0.707057, -0.032911),
    "R_Mid2": (0.708751, -0.023310, 0.704444, -0.029782),
    "R_Thumb1": (0.556380, 0.230091, 0.740052, -0.299704),
}


def cc_neutral() -> dict[str, np.ndarray]:
    """Neutral global orientations [3, 3] of the CC_Base rig's joints (project frame, facing +x)."""
    return {_CC + k: Rotation.from_quat(q).as_matrix() for k, q in _CC_NEUTRAL_Q.items()}
