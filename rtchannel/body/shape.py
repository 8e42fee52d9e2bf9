"""Body shapes: anthropometric parameters, their documented ranges, and motions driving shaped bodies.

`BodyShape` describes a person by sex, age, BMI (or mass), muscle and proportions; the stature is the motion
rig's height, drawn by the caller. `reshape_motion` puts a motion onto the avatar in that shape: MakeHuman's
macro targets on the same skinned mesh (`rtchannel.body.body_targets`), calibrated so that mesh volume x body
density / stature^2 is the requested BMI (`rtchannel.body.shape_fit`), the rig read off the shaped mesh
(`rtchannel.body.shaped_avatar`). The skinning picks the shape up from ``motion.rig.shape`` at every level of
detail, so every backend sees the shaped body.

    shape = draw_body_shape(np.random.default_rng(7))        # or BodyShape(sex="female", age_years=70, bmi=31)
    motion = reshape_motion(Motion.procedural("walk", height=1.62), shape)
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from processing.errors import InputError
from rtchannel.body.avatar import load_avatar
from rtchannel.body.body_targets import MacroValues
from rtchannel.body.shape_fit import fit_macro
from rtchannel.body.shaped_avatar import macro_key, shaped_rig
from rtchannel.body.skinning import skin_vertices
from rtchannel.motion.pose import JOINT_NAMES, Motion, avatar_rig

_FLOOR_LOD = "2k"  # the mesh whose lowest point keeps the body on the floor (1k vertices: cheap, within ~3 mm)
DEFAULT_BMI = 22.0  # kg/m^2: the middle of WHO's normal range (18.5-25)


class BodyShape(BaseModel):
    """A person's build, in physical units (frozen, hashable, JSON-able; `model_validate` takes a dict).

    Attributes:
        sex: 0 female .. 1 male (a mix in between, MakeHuman's gender slider); "female"/"male" accepted.
        age_years: age [years], 18-100. MakeHuman's adult anchors are 25 and 90 years: younger adults take
            the 25-year-old shape, older than 90 the 90-year-old's (`rtchannel.body.shape_fit`).
        bmi: body-mass index [kg/m^2], 13-60; give it or `mass_kg` (neither: `DEFAULT_BMI`).
        mass_kg: body mass [kg], 30-250, instead of `bmi` (BMI = mass / stature^2 at the motion's stature).
        muscle: MakeHuman's muscle slider, 0 (min) .. 0.5 (average) .. 1 (max); heavy bodies exist only on
            low-muscle anchors, so a BMI the requested muscle cannot reach moves it (the used value is in
            the rig's shape key as ``mh_muscle``).
        proportions: MakeHuman's body proportions, 0 uncommon .. 0.5 regular .. 1 ideal (artist-made
            variants: limb to trunk length, shoulder and hip width).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    sex: float = Field(0.5, ge=0.0, le=1.0)
    age_years: float = Field(30.0, ge=18.0, le=100.0)
    bmi: float | None = Field(None, ge=13.0, le=60.0)
    mass_kg: float | None = Field(None, ge=30.0, le=250.0)
    muscle: float = Field(0.5, ge=0.0, le=1.0)
    proportions: float = Field(0.5, ge=0.0, le=1.0)

    @field_validator("sex", mode="before")
    @classmethod
    def _sex_word(cls, v):
        words = {"female": 0.0, "f": 0.0, "male": 1.0, "m": 1.0}
        if isinstance(v, str):
            if v.strip().lower() not in words:
                raise ValueError("sex must be 'female', 'male' or a number from 0 (female) to 1 (male)")
            return words[v.strip().lower()]
        return v

    @model_validator(mode="before")
    @classmethod
    def _one_mass(cls, data):
        if isinstance(data, dict):
            if data.get("bmi") is not None and data.get("mass_kg") is not None:
                raise ValueError("give bmi or mass_kg, not both")
            if data.get("bmi") is None and data.get("mass_kg") is None:
                data = {**data, "bmi": DEFAULT_BMI}
        return data

    def bmi_at(self, stature_m: float) -> float:
        """The BMI [kg/m^2] of this body at stature `stature_m` (its `bmi`, or mass / stature^2).

        Args:
            stature_m: the person's stature [m].
        """
        if self.bmi is not None:
            return float(self.bmi)
        assert self.mass_kg is not None  # the validator sets bmi when mass_kg is not given
        return float(self.mass_kg) / float(stature_m) ** 2

    def macro(self, stature_m: float) -> MacroValues:
        """MakeHuman's macro values of this body at stature `stature_m` (`rtchannel.body.shape_fit.fit_macro`).

        Args:
            stature_m: the person's stature [m].

        Raises:
            InputError: the BMI at this stature is beyond the shape model (also for a mass whose BMI is
                outside 13-60 kg/m^2).
        """
        bmi = self.bmi_at(stature_m)
        if not 13.0 <= bmi <= 60.0:
            raise InputError(f"body mass {self.mass_kg} kg at {stature_m:.2f} m is a BMI of {bmi:.1f}, outside "
                             f"13-60 kg/m^2")
        return fit_macro(self.sex, self.age_years, bmi, self.muscle, self.proportions, float(stature_m))

    def key(self, stature_m: float) -> tuple:
        """The rig shape key: this shape's fields and its MakeHuman macro values at `stature_m`.

        Args:
            stature_m: the person's stature [m].
        """
        own = tuple((k, v) for k, v in self.model_dump().items())
        return own + macro_key(self.macro(stature_m))

    @classmethod
    def from_key(cls, key: tuple) -> "BodyShape":
        """The shape a rig shape key was made from.

        Args:
            key: a rig shape key (`BodyShape.key`): a tuple of (name, value) pairs.
        """
        return cls.model_validate({k: v for k, v in key if k in cls.model_fields})


class BodyShapeRanges(BaseModel):
    """Ranges a dataset draws body shapes from (uniform within each range; frozen, JSON-able).

    Attributes:
        male_fraction: share of male bodies (the rest female); 0.5, as in the adult population.
        age_years: [low, high] years. 18-98: adults; the Glasgow radar dataset's participants were 21-98
            years old ("Radar signatures of human activities", University of Glasgow 2019, DOI
            10.5525/gla.researchdata.848).
        bmi: [low, high] kg/m^2. 17-40: from WHO's moderate thinness (< 17) to obesity class III (>= 40);
            worldwide ~9-10 % of adults are below 18.5 and 0.6 % of men, 1.6 % of women at or above 40 (NCD Risk
            Factor Collaboration, Lancet 2016, 387:1377; 2017, 390:2627). Uniform, so that the thin and the
            heavy are not rare in training.
        muscle: [low, high] of MakeHuman's muscle slider; its whole range (no population data exists for it).
        proportions: [low, high] of MakeHuman's proportions slider; its whole range (likewise).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    male_fraction: float = Field(0.5, ge=0.0, le=1.0)
    age_years: tuple[float, float] = (18.0, 98.0)
    bmi: tuple[float, float] = (17.0, 40.0)
    muscle: tuple[float, float] = (0.0, 1.0)
    proportions: tuple[float, float] = (0.0, 1.0)

    @model_validator(mode="after")
    def _within_body_shape(self):
        limits = {"age_years": (18.0, 100.0), "bmi": (13.0, 60.0), "muscle": (0.0, 1.0), "proportions": (0.0, 1.0)}
        for name, (lo, hi) in limits.items():
            a, b = getattr(self, name)
            if not lo <= a <= b <= hi:
                raise ValueError(f"{name} range must be [low, high] with {lo:g} <= low <= high <= {hi:g}, "
                                 f"got [{a}, {b}]")
        return self


def draw_body_shape(rng: np.random.Generator, ranges: BodyShapeRanges | dict | None = None) -> BodyShape:
    """A body shape drawn from `ranges` (a `BodyShapeRanges` or its dict; default `BodyShapeRanges()`) with
    the numpy generator `rng`: sex, then age, BMI, muscle and proportions, uniform within their ranges (five
    uniform draws, always in this order, so a seeded generator gives the same shape).

    Args:
        rng: the numpy random generator to draw from.
        ranges: the ranges (`BodyShapeRanges`, its dict, or None for the documented defaults).
    """
    r = ranges if isinstance(ranges, BodyShapeRanges) else BodyShapeRanges.model_validate(ranges or {})
    u = rng.random(5)

    def pick(lo_hi: tuple[float, float], x: float) -> float:
        return float(lo_hi[0] + x * (lo_hi[1] - lo_hi[0]))

    return BodyShape(sex=float(u[0] < r.male_fraction), age_years=pick(r.age_years, u[1]), bmi=pick(r.bmi, u[2]),
                     muscle=pick(r.muscle, u[3]), proportions=pick(r.proportions, u[4]))


def reshape_motion(motion: Motion, shape: BodyShape | dict | None) -> Motion:
    """`motion` on the avatar in body shape `shape` at the same stature (None: the plain avatar).

    The rest-relative global joint rotations stay; joint positions follow by forward kinematics from the
    shaped rig's rest offsets; the root (hips) trajectory is scaled by the ratio of the two rigs' rest hip
    heights, about its mean horizontal position, so the feet stay on the floor and a step covers as much
    ground relative to the legs. Then each frame is lifted so that its lowest skin point (on the 2k mesh) is
    as high as before times that ratio: feet stay on the floor also with bent legs, a lying body stays on it.
    ``params["body_shape"]`` records the shape.

    Args:
        motion: a motion on the avatar's 31-joint rig (any height, shaped or not).
        shape: a `BodyShape` (or its dict), or None.

    Returns:
        A new Motion whose ``rig.shape`` is the shape's key (`BodyShape.key`).
    """
    if tuple(motion.rig.names) != JOINT_NAMES:
        raise InputError("reshape_motion needs a motion on the avatar's 31-joint rig")
    if shape is not None and not isinstance(shape, BodyShape):
        shape = BodyShape.model_validate(shape)
    height = motion.rig.height
    rig = avatar_rig(height) if shape is None else shaped_rig(shape.key(height), height)
    old, new = motion.rig.rest, rig.rest
    k = new[0, 2] / old[0, 2]
    root = motion.positions[:, 0]
    centre = root[:, :2].mean(axis=0)
    rot = motion.rotations
    pos = np.empty_like(motion.positions)
    pos[:, 0, :2] = centre + k * (root[:, :2] - centre)
    pos[:, 0, 2] = k * root[:, 2]
    for j, p in enumerate(rig.parents):
        if p >= 0:
            pos[:, j] = pos[:, p] + rot[:, p] @ (new[j] - new[p])
    params = {**motion.params, "body_shape": None if shape is None else shape.model_dump()}
    # Bent legs (sitting, stooping) drop the hips by the shin, not the hip height: lift each frame so that its
    # lowest skin point is k times as high as before (on the floor where it was on the floor).
    probe = load_avatar(_FLOOR_LOD)
    low_old = skin_vertices(probe, motion)[..., 2].min(axis=1)
    low_new = skin_vertices(probe, replace(motion, rig=rig, positions=pos))[..., 2].min(axis=1)
    lift = np.zeros_like(pos)
    lift[..., 2] = (k * low_old - low_new)[:, None]
    return replace(motion, rig=rig, positions=pos + lift, params=params)


__all__ = ["BodyShape", "BodyShapeRanges", "DEFAULT_BMI", "draw_body_shape", "reshape_motion"]
