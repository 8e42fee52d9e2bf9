"""Procedural joint trajectories for five activities: fall, walk, stand (sit-to-stand), sit, pick.

Every generator drives the 31-joint avatar rig (`rtchannel.motion.pose`) with smooth joint-angle profiles
and returns a `Motion`: quiet standing (sitting for ``stand``) for `pad_before`, the activity, and a quiet
end pose for `pad_after`. The motion is built facing +x from the origin, then turned by `heading_deg`
about the vertical and moved to `start`. Lengths scale with ``height / 1.75 m``.

Biomechanical sources for the numbers used:

* Walking: Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed. (2009), ch. 2 and the
  normative gait data; Perry & Burnfield, *Gait Analysis* (2010): heel strike with the foot ~20 deg
  toes-up, foot flat at ~10 % and heel-off at ~40 % of the cycle, toe-off at ~60 % (less at higher
  speed), swing-knee flexion ~60 deg, hip +-20-25 deg, pelvic rotation/obliquity a few degrees, centre of
  mass rising and falling ~2-5 cm twice per stride and swaying +-2 cm sideways, arm swing opposite the
  legs. Bohannon (1997), Age Ageing 26:15-19: comfortable gait speed ~1.3-1.5 m/s. Step length ~0.41 x
  height at ~1.3 m/s and its growth with speed (Grieve & Gear 1966, Ergonomics 9:379) give cadences of
  ~1.4-2.1 steps/s over 0.8-1.8 m/s. Gait initiation reaches steady speed within about one stride
  (Jian et al. 1993, Gait Posture 1:9).
* Falls: Hsiao & Robinovitch (1998), J. Biomech. 31:1-9 (protective arm responses, impact ~0.7-1 s
  after onset); Lo, Ashton-Miller & co. and Robinovitch et al. (2013), Lancet 381:47 (forward falls onto
  hands and knees, sideways falls onto the hip; backward falls squat onto the buttocks before the trunk
  rolls back, Hsiao & Robinovitch 1998; Smeesters et al. (2001), J. Biomech. 34:589: slips mostly end
  backward or sideways); descent head speeds of ~2-4.5 m/s.
* Sit-to-stand / stand-to-sit: Schenkman et al. (1990), Phys. Ther. 70:638 (flexion-momentum, momentum
  transfer, extension and stabilisation phases, trunk flexion ~30-45 deg); Millington et al. (1992),
  Arch. Phys. Med. Rehabil. 73:609; durations ~1.5-3 s. Seat height 0.45 m for a 1.75 m adult.
* Lifting from the floor: combined stoop/squat with ~70-80 deg trunk flexion (Burgess-Limerick 2003,
  Occup. Ergon. 3:143).
"""
from __future__ import annotations

import numpy as np
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from rtchannel.motion import kinematics as km
from rtchannel.motion.kinematics import DEG, NOMINAL_HEIGHT_M, keyframes, step
from rtchannel.motion.pose import Motion, Rig, avatar_rig
from rtchannel.motion.activities import ACTIVITIES
from processing.errors import InputError

_DEFAULT_DURATION_S = {"fall": 1.5, "sit": 2.3, "stand": 1.9, "pick": 2.8}
_DURATION_RANGE_S = {"fall": (0.8, 3.0), "sit": (1.0, 5.0), "stand": (1.0, 5.0), "pick": (1.5, 8.0)}
PICK_HOLD = 0.13  # share of a pick spent still at the bottom unless hold_fraction says otherwise
_CADENCE_RANGE = (1.4, 2.3)  # steps/s accepted for an explicit step length
STAND_KNEE_DEG = 3.0  # geometric knee flexion of quiet standing
SEAT_HEIGHT_M = 0.45  # chair seat for a 1.75 m adult
SEAT_TO_HIP_M = 0.095  # hip joint centre above the seat when sitting (ischial tuberosities)
# Gait shape (Winter 2009; Perry & Burnfield 2010), lengths for a 1.75 m body:
_MID_STANCE = 0.40  # stance fraction at which the hips pass over the flat foot (heel lands ~0.3 m ahead)
_MID_KNEE_DEG = 15.0  # knee flexion that sets the pelvis' mid-stance height
_HEEL_STRIKE_DEG, _TOE_OFF_DEG = 20.0, 60.0  # foot-floor angles (toes up / heel up)
_SWING_LIFT_M = 0.065  # further ankle rise after toe-off: the heel peaks early in swing
_BOB_M = 0.04  # pelvis drop from mid-stance to loading response at 1.3 m/s (grows with speed)
_BOB_TOP = 0.35  # cycle fraction of the pelvis' highest point (left mid-stance)


class ProceduralParams(BaseModel):
    """Parameters of a procedural motion (units: metres, seconds, degrees, Hz).

    `duration` is the activity's length without the pads (for walk: distance = speed * duration);
    `distance` defaults to 4 m for walk; `step_length` defaults to `default_step_length`. `seed`
    varies amplitudes and timing by up to about +-10 % (identical seed, identical motion).
    """

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    height: float = Field(1.75, ge=1.2, le=2.2, description="body height [m]")
    # 0.3 m/s: frail older adults (Studenski et al. 2011, JAMA 305:50-58: gait speeds 0.2-1.6 m/s in people
    # aged 65+, < 0.6 m/s common in the over-85s); a slow walk has short steps, the cadence floor below
    speed: float = Field(1.3, ge=0.3, le=2.5, description="walking speed [m/s] (walk only)")
    duration: float | None = Field(None, gt=0, le=120, description="activity duration [s]")
    distance: float | None = Field(None, ge=0.5, le=200, description="walk distance [m]")
    step_length: float | None = Field(None, ge=0.2, le=1.6, description="walking step length [m]")
    # bounds: a heading beyond +-10 turns or a start beyond 100 m (MAX_COORD_M, the largest capture volume)
    # is a typo, and the seed is stored as a 64-bit integer in datasets and signature files
    heading_deg: float = Field(0.0, ge=-3600, le=3600,
                               description="facing/travel direction, deg counter-clockwise from +x")
    start: tuple[Annotated[float, Field(ge=-100, le=100)], Annotated[float, Field(ge=-100, le=100)]] = Field(
        (0.0, 0.0), description="start of the hips' ground projection [m]")
    seed: int = Field(0, ge=0, le=2**63 - 1, description="variation seed")
    fps: float = Field(60.0, ge=10, le=2000, description="frame rate [Hz]")
    pad_before: float = Field(0.5, ge=0, le=30, description="quiet time before the activity [s]")
    pad_after: float = Field(0.5, ge=0, le=30, description="quiet time after the activity [s]")
    hold_fraction: float | None = Field(None, ge=0, le=0.4, description="pick: share of the duration spent "
                                        "at the bottom (None: PICK_HOLD, 0.13)")
    arm_swing: float = Field(1.0, ge=0, le=2, description="walk: factor on the arm swing (older people swing "
                             "their arms less, at any speed)")
    # None keeps the seed's choice (seed mod 3: forward, left, right), so the seeds of earlier datasets make
    # the same falls; "backward" exists only by name
    fall_direction: Literal["forward", "left", "right", "backward"] | None = Field(
        None, description="fall: direction (None: from the seed, seed mod 3 = forward, left, right)")

    @model_validator(mode="after")
    def _cadence(self) -> "ProceduralParams":
        if self.step_length is not None:
            cadence = self.speed / self.step_length
            lo, hi = _CADENCE_RANGE
            if not lo <= cadence <= hi:
                raise InputError(f"step_length {self.step_length} m at speed {self.speed} m/s gives a cadence "
                                 f"of {cadence:.2f} steps/s, outside {lo}-{hi} steps/s")
        return self


def default_step_length(height: float, speed: float) -> float:
    """Step length [m] for a body `height` [m] walking at `speed` [m/s] (0.41 h at 1.3 m/s, ~sqrt(speed))."""
    step_len = 0.41 * height * np.sqrt(speed / 1.3)
    return float(speed / np.clip(speed / step_len, *_CADENCE_RANGE))


def generate(activity: str, params: ProceduralParams | None = None, **overrides) -> Motion:
    """Joint trajectories of one activity as a `Motion` on ``avatar_rig(height)``.

    Args:
        activity: one of `ACTIVITIES`. ``fall`` goes forward for ``seed % 3 == 0``, to the left for 1
            and to the right for 2; ``stand`` is sit-to-stand, ``sit`` stand-to-sit, ``pick`` picks an
            object up from the floor with the right hand.
        params: parameters (metres, seconds, degrees, Hz); `overrides` replace single fields.

    Returns:
        `Motion` at `fps` covering pad_before + activity + pad_after; activity durations default to
        fall 1.5 s, sit 2.3 s, stand 1.9 s, pick 2.8 s (+-8 % by seed) and distance/speed + 0.8
        stride for walk. ``params`` holds every field plus ``activity``.

    Raises:
        ValueError: unknown activity, a duration outside the activity's plausible range, or a walk
            given inconsistent distance and duration.
        pydantic.ValidationError: invalid or unknown parameters.
    """
    if activity not in ACTIVITIES:
        raise InputError(f"unknown activity {activity!r}; valid activities are {', '.join(ACTIVITIES)}")
    base = params.model_dump() if params is not None else {}
    p = ProceduralParams(**{**base, **overrides})
    rig = avatar_rig(p.height)
    rng = np.random.default_rng(p.seed)
    if activity == "walk":
        rot, pos = _walk(rig, p, rng)
    else:
        duration = p.duration
        if duration is None:
            duration = _DEFAULT_DURATION_S[activity] * (1 + 0.08 * rng.uniform(-1, 1))
        lo, hi = _DURATION_RANGE_S[activity]
        if not lo <= duration <= hi:
            raise InputError(f"duration of {activity!r} must be within {lo}-{hi} s, got {duration}")
        t = _times(p, duration)
        u = (t - p.pad_before) / duration
        if activity == "fall":
            rot, pos = _fall(rig, u, rng, direction=p.fall_direction or FALL_DIRECTIONS[p.seed % 3])
        elif activity == "pick":
            rot, pos = _pick(rig, u, rng, PICK_HOLD if p.hold_fraction is None else p.hold_fraction)
        else:
            rot, pos = {"sit": _sit, "stand": _stand}[activity](rig, u, rng)
    pos = pos - np.r_[pos[0, 0, :2], 0.0]  # the hips start over the origin, then over `start`
    motion = Motion(rig=rig, fps=float(p.fps), rotations=rot, positions=pos, activity=activity,
                    params={**p.model_dump(mode="json"), "activity": activity})
    return motion.transformed(p.heading_deg * DEG, (p.start[0], p.start[1], 0.0))


def _times(p: ProceduralParams, duration: float) -> np.ndarray:
    n = int(round((p.pad_before + duration + p.pad_after) * p.fps)) + 1
    return np.arange(max(n, 2)) / p.fps


def _jitter(rng, amount: float = 0.1) -> float:
    return float(1 + amount * rng.uniform(-1, 1))


# ----------------------------------------------------------------------------------------------- poses
def _standing(rig: Rig):
    """Ankle targets {side: [3]} and root height [m] of quiet standing with the root over the origin."""
    s = rig.height / NOMINAL_HEIGHT_M
    feet = {}
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        feet[side] = np.array([0.01 * s, sign * 0.10 * s, rig.rest[rig.index(f"{side}Foot"), 2]])
    caps = [km.root_height_cap(rig, side, np.zeros((1, 2)), np.eye(3)[None], a[None], STAND_KNEE_DEG)[0]
            for side, a in feet.items()]
    return feet, float(min(caps))


def _planted(rig: Rig, root, pelvis_pitch, spine_pitch, neck_pitch, arms: dict, feet: dict):
    """Pose with both feet flat at `feet`; angles in degrees, arrays over frames."""
    n = len(root)
    pelvis = km.rot_y(np.asarray(pelvis_pitch) * DEG)
    # Keep the hips within the legs' reach so the knees never snap straight (a velocity kink).
    caps = [km.root_height_cap(rig, side, root[:, :2], pelvis, np.broadcast_to(a, (n, 3)), STAND_KNEE_DEG)
            for side, a in feet.items()]
    root = np.column_stack([root[:, :2], km.softmin([root[:, 2], *caps], 0.004 * rig.height)])
    glob = {"Hips": pelvis}
    for side, ankle in feet.items():
        hip = km.hip_centre(rig, side, root, pelvis)
        glob.update(km.leg_ik(rig, side, hip, np.broadcast_to(ankle, (n, 3)), np.zeros(n)))
    loc = {**km.spine_local(spine_pitch), **km.spine_local(neck_pitch, joints=("Neck", "Neck1", "Head"),
                                                           shares=(0.3, 0.3, 0.4)), **arms}
    return km.pose(rig, n, glob, loc, root)


def _arms(rig: Rig, flex_l, flex_r, abd_l, abd_r, elbow_l, elbow_r) -> dict:
    return {**km.arm_local(rig, "Left", flex_l, abd_l, elbow_l),
            **km.arm_local(rig, "Right", flex_r, abd_r, elbow_r)}


def _sit(rig: Rig, u, rng):
    """Stand-to-sit: lean forward while the hips travel back and down onto the seat, then sit up."""
    return _chair(rig, u, rng, to_seat=True)


def _stand(rig: Rig, u, rng):
    """Sit-to-stand: flexion-momentum lean, seat-off, extension to upright (Schenkman 1990)."""
    return _chair(rig, u, rng, to_seat=False)


def _chair(rig: Rig, u, rng, to_seat: bool):
    s = rig.height / NOMINAL_HEIGHT_M
    feet, z_stand = _standing(rig)
    z_seat = (SEAT_HEIGHT_M + SEAT_TO_HIP_M) * s
    x_seat = -0.40 * s * _jitter(rng, 0.05)
    lean = 38.0 * _jitter(rng)  # peak trunk flexion [deg]
    if to_seat:
        move = step(u, 0.12, 0.80)  # hips leave standing height ... touch the seat
        back = step(u, 0.04, 0.72)
        trunk = keyframes(u, [0, 0.15, 0.5, 0.78, 1.0], [0, 0.35 * lean, lean, 0.8 * lean, 4.0])
        arm_f = keyframes(u, [0, 0.5, 0.85, 1.0], [2, 25, 24, 24])
        elbow = keyframes(u, [0, 0.5, 0.8, 1.0], [15, 30, 50, 55])
    else:
        move = 1 - step(u, 0.30, 0.88)  # seat-off after the trunk has gained forward momentum
        back = 1 - step(u, 0.22, 0.80)
        trunk = keyframes(u, [0, 0.35, 0.45, 0.9, 1.0], [4.0, lean, 0.95 * lean, 3.0, 0.0])
        arm_f = keyframes(u, [0, 0.3, 0.6, 1.0], [24, 26, 15, 2])
        elbow = keyframes(u, [0, 0.25, 0.6, 1.0], [55, 40, 25, 15])
    root = np.column_stack([back * x_seat, np.zeros_like(u), z_stand + move * (z_seat - z_stand)])
    pelvis = 0.7 * trunk - 6.0 * move  # most of the lean is hip flexion; the pelvis rolls back when seated
    arms = _arms(rig, arm_f, arm_f, 8.0, 8.0, elbow, elbow)
    return _planted(rig, root, pelvis, trunk - pelvis, -0.5 * trunk, arms, feet)


def _pick(rig: Rig, u, rng, hold: float):
    """Bend (trunk flexion + knee bend) until the right hand nears the floor, pause, return upright."""
    s = rig.height / NOMINAL_HEIGHT_M
    feet, z_stand = _standing(rig)
    target = 0.12 * s * _jitter(rng)  # right wrist height at the bottom [m]
    squat = _jitter(rng, 0.15)  # more knee bend (squat) or more trunk flexion (stoop)
    t_down, t_hold = 0.40 * _jitter(rng, 0.08), hold

    def posture(depth, w):
        trunk = 75.0 * depth / squat ** 0.5 * w
        root = np.column_stack([-0.14 * s * depth * w, 0 * w, z_stand - 0.28 * s * depth * squat * w])
        arms = _arms(rig, 0.75 * trunk + 5, trunk + 12 * w, 8 + 4 * w, 8 + 6 * w, 15 + 25 * w, 15 - 5 * w)
        arms["RightShoulder"] = km.rot_z(20 * DEG * w)  # protract the reaching shoulder
        return _planted(rig, root, 0.4 * trunk, 0.6 * trunk, -0.3 * trunk, arms, feet)

    hand = rig.index("RightHand")
    lo, hi = 0.2, 1.6
    for _ in range(30):  # bisection on the depth that brings the wrist to `target`
        mid = 0.5 * (lo + hi)
        if posture(mid, np.ones(1))[1][0, hand, 2] > target:
            lo = mid
        else:
            hi = mid
    w = step(u, 0.0, t_down) - step(u, t_down + t_hold, 1.0)
    return posture(0.5 * (lo + hi), w)


# ------------------------------------------------------------------------------------------------ fall
_FALL_U = (0.0, 0.25, 0.5, 0.7, 0.85, 1.0)  # key times as fractions of the fall
# Key values [deg]: roll = whole-body tilt sideways; shank/thigh/trunk/head/foot = global pitches (see
# kinematics: positive tilts a segment's upper end forward, the foot's toes down); near/far = the arm on
# the side the body falls to / the other one (flexion, abduction, elbow, see `kinematics.arm_local`).
_FALL_FORWARD = dict(  # onto hands and knees, then down to prone with the arms stretched ahead
    roll=(0, 0, 0, 0, 0, 0), head_roll=(0, 0, 0, 0, 0, 0),
    shank=(0, 8, 40, 88, 90, 90), thigh=(0, 8, -10, 5, 45, 88), trunk=(0, 12, 45, 80, 86, 88),
    head=(0, 10, 35, 55, 65, 72), foot=(0, 0, 25, 100, 140, 150),
    near_flex=(0, 30, 80, 72, 105, 175), near_abd=(8, 12, 20, 25, 30, 25), near_elbow=(15, 12, 5, 8, 30, 10),
    far_flex=(0, 30, 80, 72, 105, 175), far_abd=(8, 12, 20, 25, 30, 25), far_elbow=(15, 12, 5, 8, 30, 10))
_FALL_SIDE = dict(  # crouching while tipping sideways onto the hip, then lying on the side, head on the arm
    roll=(0, 10, 32, 66, 85, 90), head_roll=(0, -5, -10, 0, 10, 20),
    shank=(0, 3, 25, 25, 15, 10), thigh=(0, 2, -20, -35, -40, -40), trunk=(0, 5, 20, 20, 10, 5),
    head=(0, 3, 10, 10, 5, 0), foot=(0, 0, 10, 20, 15, 10),
    near_flex=(0, 10, 20, 20, 15, 10), near_abd=(8, 40, 90, 130, 160, 178), near_elbow=(15, 15, 10, 15, 20, 25),
    far_flex=(0, 10, 20, 30, 30, 30), far_abd=(8, 20, 30, 20, 10, 8), far_elbow=(15, 30, 40, 40, 40, 40))
# Backward (Hsiao & Robinovitch 1998, J Biomech 31:1-9: in backward falls people squat, land on the pelvis,
# reach back with the arms and tuck the chin; slips, which throw the feet forward, mostly end backward or
# sideways, Smeesters et al. 2001, J Biomech 34:589-595): knees and hips flex while the trunk leans forward to
# brake, impact on the buttocks (u ~ 0.7), then the trunk rolls back to supine with the legs out.
_FALL_BACKWARD = dict(  # the hip below the knee at landing: the thigh pitched back past horizontal (< -90)
    roll=(0, 0, 0, 0, 0, 0), head_roll=(0, 0, 0, 0, 0, 0),
    shank=(0, 15, 45, -15, -50, -85), thigh=(0, -25, -70, -135, -110, -92), trunk=(0, 6, 25, 15, -40, -88),
    head=(0, 8, 30, 25, -20, -80), foot=(0, 5, 20, 0, -30, -70),
    near_flex=(0, -15, -35, -45, -30, -10), near_abd=(8, 20, 30, 35, 40, 45), near_elbow=(15, 12, 10, 15, 30, 40),
    far_flex=(0, -15, -35, -45, -30, -10), far_abd=(8, 20, 30, 35, 40, 45), far_elbow=(15, 12, 10, 15, 30, 40))
_BACKWARD_LANDING_U = 0.62  # the buttocks reach the floor (key 0.7), the pelvis anchored from here to 0.72
FALL_DIRECTIONS = ("forward", "left", "right", "backward")  # the first three in the seed's order (mod 3)
# Joint centre to the skin that can touch the floor [m, for 1.75 m].
_CONTACT_RADII = {
    "Hips": 0.10, "LeftUpLeg": 0.10, "RightUpLeg": 0.10, "LeftLeg": 0.05, "RightLeg": 0.05,
    "LeftFoot": 0.07, "RightFoot": 0.07, "LeftToeBase": 0.025, "RightToeBase": 0.025, "LowerBack": 0.10,
    "Spine": 0.11, "Spine1": 0.11, "Neck": 0.06, "Head": 0.10, "LeftArm": 0.06, "RightArm": 0.06,
    "LeftForeArm": 0.04, "RightForeArm": 0.04, "LeftHand": 0.03, "RightHand": 0.03,
    "LeftHandFinger1": 0.01, "RightHandFinger1": 0.01}


def _fall(rig: Rig, u, rng, direction: str):
    """Topple from standing to lying: ``forward`` onto hands and knees, then prone; ``left``/``right``
    sideways onto the hip, then onto the side; ``backward`` squatting onto the buttocks, then supine. The toes
    stay where they stood (in a backward fall until the buttocks land; then the pelvis stays and the legs
    slide out) and the lowest skin point rests on the floor, so the body is always supported (Hsiao &
    Robinovitch 1998)."""
    s = rig.height / NOMINAL_HEIGHT_M
    n = len(u)
    table = {"forward": _FALL_FORWARD, "backward": _FALL_BACKWARD}.get(direction, _FALL_SIDE)
    # Seed variation of the key poses (not of the start and end postures' support geometry).
    k = {name: np.asarray(v, float) * np.r_[1.0, np.full(len(v) - 2, _jitter(rng, 0.08)), 1.0]
         for name, v in table.items()}
    curve = {name: keyframes(u, _FALL_U, v) for name, v in k.items()}
    sign = -1.0 if direction == "right" else 1.0
    feet, z_stand = _standing(rig)
    leg0 = {}
    for side, ankle in feet.items():
        hip = km.hip_centre(rig, side, np.array([[0, 0, z_stand]]), np.eye(3)[None])
        leg0.update(km.leg_ik(rig, side, hip, ankle[None], np.zeros(1)))

    def tilt(pitch_deg, rest=np.eye(3), roll_deg=0.0):
        return km.rot_x(-sign * (curve["roll"] + roll_deg) * DEG) @ km.rot_y(pitch_deg * DEG) @ rest

    pelvis = curve["thigh"] + 0.4 * (curve["trunk"] - curve["thigh"])
    glob = {"Hips": tilt(pelvis), "LowerBack": tilt(pelvis + (curve["trunk"] - pelvis) / 3),
            "Spine": tilt(pelvis + 2 * (curve["trunk"] - pelvis) / 3), "Spine1": tilt(curve["trunk"]),
            "Neck": tilt(0.5 * (curve["trunk"] + curve["head"]), roll_deg=0.5 * curve["head_roll"]),
            "Head": tilt(curve["head"], roll_deg=curve["head_roll"])}
    for side in ("Left", "Right"):
        glob[f"{side}UpLeg"] = tilt(curve["thigh"], leg0[f"{side}UpLeg"][0])
        glob[f"{side}Leg"] = tilt(curve["shank"], leg0[f"{side}Leg"][0])
        glob[f"{side}Foot"] = tilt(curve["foot"])
    near, far = ("Right", "Left") if direction == "right" else ("Left", "Right")
    loc = {**km.arm_local(rig, near, curve["near_flex"], curve["near_abd"], curve["near_elbow"]),
           **km.arm_local(rig, far, curve["far_flex"], curve["far_abd"], curve["far_elbow"])}
    rot, pos = km.pose(rig, n, glob, loc, np.zeros((n, 3)))
    toes = [rig.index("LeftToeBase"), rig.index("RightToeBase")]
    anchor = pos[:, toes, :2].mean(axis=1)
    if direction == "backward":  # once the buttocks land the pelvis stays put and the legs slide out ahead
        hips = pos[:, rig.index("Hips"), :2]
        land = min(int(np.searchsorted(u, _BACKWARD_LANDING_U)), n - 1)
        w = step(u, _BACKWARD_LANDING_U, _BACKWARD_LANDING_U + 0.1)[:, None]
        anchor = (1 - w) * anchor + w * (hips + anchor[land] - hips[land])
    radii = {name: r * s for name, r in _CONTACT_RADII.items()}
    shift = np.column_stack([anchor[0] - anchor, km.ground_lift(rig, pos, radii, tau=0.006 * s)])
    return rot, pos + shift[:, None, :]


# ------------------------------------------------------------------------------------------------ walk
def _walk(rig: Rig, p: ProceduralParams, rng):
    """Gait initiation from standing, steady walking at `speed`, and stopping with the feet together.

    The hips follow a minimum-jerk speed ramp (0.8 stride long at each end) whose integral is exactly
    `distance`; each footprint is placed where the hips will be at that foot's mid-stance, so stance feet
    stay planted for any speed profile and the legs follow from inverse kinematics. The pelvis bobs twice
    per stride (high at mid-stance, low after heel strike) and dips further wherever the legs could not
    otherwise reach their feet. A walk of `distance` lasts distance/speed + 0.8 stride.
    """
    s = rig.height / NOMINAL_HEIGHT_M
    v = p.speed
    if p.distance is not None and p.duration is not None and abs(p.distance / v - p.duration) > 1e-2 * p.duration:
        raise InputError(f"walk: distance {p.distance} m at {v} m/s does not last duration {p.duration} s; "
                         "give one of them")
    dist = p.distance if p.distance is not None else (v * p.duration if p.duration is not None else 4.0)
    step0 = p.step_length if p.step_length is not None else default_step_length(p.height, v) * _jitter(rng, 0.04)
    period0 = 2 * step0 / v
    # Whole number of steps between the first toe-off and the last heel strike: adjust the stride.
    n_steps = max(2, round(2 * (dist / (v * period0) + 0.7)))
    period = float(np.clip(dist / v / (n_steps / 2 - 0.7), 0.8 * period0, 1.25 * period0))
    # stance fraction of the cycle; below 0.8 m/s double support lengthens faster (slow, cautious gait: stance
    # ~67 % of the cycle at 0.3 m/s against ~60 % at normal speed, Winter 1991; Hollman et al. 2011)
    beta = float(np.clip(0.62 - 0.04 * (v - 0.8) + 0.06 * max(0.8 - v, 0.0), 0.56, 0.68))
    rock, rise, ramp = 0.10 * period, 0.22 * period, 0.8 * period
    t_toe_off = p.pad_before + rise  # the right heel starts rising when the pad ends
    t_r0 = t_toe_off - 0.1 * period
    t_r1 = t_r0 + dist / v

    def travel(tt):
        return v * (km.ramp_integral(tt - t_r0, ramp) - km.ramp_integral(tt - t_r1, ramp))

    def envelope(tt):
        return step(tt, t_r0, t_r0 + ramp) - step(tt, t_r1, t_r1 + ramp)

    feet, z_stand = _standing(rig)
    ax0, w_stand, w_walk = feet["Left"][0], feet["Left"][1], 0.065 * s
    hs_deg, to_deg = _HEEL_STRIKE_DEG * _jitter(rng), _TOE_OFF_DEG * _jitter(rng)
    stances = {}
    for side, sign, t_off in (("Right", -1.0, t_toe_off), ("Left", 1.0, t_toe_off + period / 2)):
        st = [[-np.inf, t_off, ax0, sign * w_stand, 0.0, 0.0]]
        while True:
            t_on = st[-1][1] + (1 - beta) * period
            t_mid = t_on + _MID_STANCE * beta * period
            x, final = float(travel(t_mid)), dist - float(travel(t_mid)) < 0.2 * step0
            x = dist if final else x
            y = sign * (w_stand + (w_walk - w_stand) * (0.0 if final else float(envelope(t_mid))))
            stride = float(np.clip((x + ax0 - st[-1][2]) / (v * period), 0.2, 1.0))
            st[-1][5] = to_deg * DEG * stride
            st.append([t_on, np.inf if final else t_on + beta * period, x + ax0, y, hs_deg * DEG * stride, 0.0])
            if final:
                break
        stances[side] = st
    t_end = max(t_r1 + ramp, *(st[-1][0] + rock for st in stances.values()))
    t = np.arange(int(round((t_end + p.pad_after) * p.fps)) + 1) / p.fps
    e = envelope(t)
    cyc = 2 * np.pi * ((t - t_toe_off) / period + beta - 0.5)  # left heel strike at multiples of 2 pi
    lag = 2 * np.pi * 0.05  # mid double support
    foot = rig.rest[rig.index("LeftFoot")]
    toe = (rig.rest[rig.index("LeftToeBase")] - foot)[[0, 2]]
    heel = np.array([-0.055 * s, -foot[2]])
    lift, clear = _SWING_LIFT_M * s * _jitter(rng), 0.025 * s * _jitter(rng)
    tracks = {side: km.foot_track(t, st, heel, toe, rock, rise, lift, clear) for side, st in stances.items()}

    yaw = -(3.0 + 2.0 * v) * _jitter(rng) * e * np.cos(cyc)  # the leading hip swings forward
    roll = 4.0 * _jitter(rng) * e * np.sin(cyc - lag)  # the swing side drops
    tilt = e * (2.0 + 1.5 * np.cos(2 * (cyc - lag)))
    pelvis = km.rot_z(yaw * DEG) @ km.rot_y(tilt * DEG) @ km.rot_x(roll * DEG)
    surge = 0.05 * v * period / (4 * np.pi)  # +-5 % speed fluctuation, fastest at double support
    root_xy = np.column_stack([travel(t) + e * surge * np.sin(2 * (cyc - lag)),
                               0.02 * s * _jitter(rng) * e * np.sin(cyc - lag)])
    z_mid = km.root_height_cap(rig, "Left", np.zeros((1, 2)), np.eye(3)[None], feet["Left"][None], _MID_KNEE_DEG)[0]
    caps = [km.root_height_cap(rig, side, root_xy, pelvis, tracks[side][0], 3.0) for side in tracks]
    # Highest at mid-stance, lowest just after each heel strike (loading response); the legs' reach
    # (caps) can only lower it further.
    bob = _BOB_M * s * (0.6 + 0.8 * (v - 0.8)) * _jitter(rng)
    z_des = z_stand + e * (z_mid - z_stand - bob * 0.5 * (1 - np.cos(2 * (cyc - 2 * np.pi * _BOB_TOP))))
    root = np.column_stack([root_xy, km.softmin([z_des, *caps], 0.01 * s)])

    glob = {"Hips": pelvis}
    for side, (ankle, pitch) in tracks.items():
        glob.update(km.leg_ik(rig, side, km.hip_centre(rig, side, root, pelvis), ankle, pitch))
    lean = (2.0 + 2.5 * v) * e
    swing = (6.0 + 8.0 * v) * p.arm_swing * _jitter(rng) * e
    arms = _arms(rig, 3 * e - swing * np.cos(cyc - lag), 3 * e + swing * np.cos(cyc - lag), 8 + 2 * e, 8 + 2 * e,
                 15 + e * (8 - 8 * np.cos(cyc - 2 * lag)), 15 + e * (8 + 8 * np.cos(cyc - 2 * lag)))
    loc = {**km.spine_local(lean - tilt, -0.8 * roll, -1.6 * yaw), **arms,
           **km.spine_local(-0.6 * lean, 0.0, 0.6 * yaw, joints=("Neck", "Neck1", "Head"), shares=(0.3, 0.3, 0.4))}
    return km.pose(rig, t.size, glob, loc, root)
