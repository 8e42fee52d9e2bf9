"""The plan schema: the validated fields of a dataset plan's motion, physical and signal layers, backend and
storage (pydantic models; a bad field is one error naming it). The physical layer is in `plan_physical`.
Loading and expansion: `rtchannel.dataset.plan`.
"""
from __future__ import annotations

import hashlib
import json
from typing import Any, Literal

from pydantic import Field, ValidationError, field_validator, model_validator

from processing.errors import InputError, one_line
from processing.labels import Activity
from rtchannel.body.scatterers import SCATTERER_NAMES
from rtchannel.dataset.plan_fields import _NAME, Scalar, _Model, _per_activity, _within, for_activity, unique_names  # noqa: F401
from rtchannel.body.shape import BodyShapeRanges
from rtchannel.dataset.plan_physical import LinkSet, PhysicalLayer, RoomDraw  # noqa: F401 - re-exported
from rtchannel.motion.compose import MAX_HEADING_DEG, MAX_START_M
from rtchannel.motion.idle import IdleMotion
from rtchannel.motion.procedural import ACTIVITIES, ProceduralParams

# `load_motion` options a files source may give, with their types
_FILE_OPTIONS = {"units": (str, int, float), "up": (str,), "align": (bool,), "floor": (bool,),
                 "max_gap_s": (int, float), "on_long_gap": (str,), "skeleton": (str,)}
# fields the motion layer sets itself (height, heading, start, mirror, seed) or that must be common (fps)
_RESERVED_PROC = {"height", "heading_deg", "start", "seed", "fps"}


class Source(_Model):
    """One motion source: a procedural generator (``procedural: walk``) or motion files (``files: PATH``)."""

    procedural: Activity | None = Field(None, description="activity of a procedural generator")
    variants: int = Field(1, ge=1, le=100000, description="procedural: number of generator seeds (motions)")
    params: dict[str, Scalar] = Field(default_factory=dict,
                                      description="procedural: ProceduralParams values or [low, high] ranges")
    files: str | None = Field(None, description="a .bvh/.c3d file or a folder (relative to the plan file)")
    pattern: str = Field("**/*", description="files: glob inside a folder (only .bvh/.c3d are used)")
    activity: str | None = Field(None, description="files: label, or 'from_folder' (the parent folder name)")
    options: dict[str, Any] = Field(default_factory=dict, description="files: load_motion keyword arguments")
    trim: tuple[float, float | None] | None = Field(None, description="files: (t0, t1) seconds of each file to "
                                                    "keep (t1 null = to the end), e.g. one part of a take")
    fall_directions: list[Literal["forward", "left", "right", "backward"]] = Field(
        ["forward", "left", "right"], min_length=1, description="procedural fall: directions the variants "
        "cycle through")

    @model_validator(mode="after")
    def _one_kind(self) -> "Source":
        if (self.procedural is None) == (self.files is None):
            raise InputError("give exactly one of 'procedural' (an activity) or 'files' (a path)")
        if self.trim is not None and not (0 <= self.trim[0] and (self.trim[1] is None or self.trim[0] < self.trim[1])):
            raise InputError(f"trim {list(self.trim)}: need 0 <= START < END seconds (END null: to the end), as "
                             "--trim")
        if self.procedural is not None:
            if self.trim is not None:
                raise InputError("trim applies to motion files; procedural motions take params (duration, pads)")
            bad = sorted(set(self.params) - (set(ProceduralParams.model_fields) - _RESERVED_PROC))
            if bad:
                raise InputError(f"params: {bad[0]!r} is not a procedural parameter here (height, heading, "
                                 f"start, mirror, seed and fps belong to the motion layer)")
        else:
            if self.activity is None:
                raise InputError("files: 'activity' is required (an activity or 'from_folder')")
            if self.activity != "from_folder" and self.activity not in ACTIVITIES:
                raise InputError(f"activity must be one of {', '.join(ACTIVITIES)} or 'from_folder'")
            bad = sorted(set(self.options) - set(_FILE_OPTIONS))
            if bad:
                raise InputError(f"options: {bad[0]!r} is not a load_motion option")
            for key, value in self.options.items():
                types = _FILE_OPTIONS[key]
                if not isinstance(value, types) or (isinstance(value, bool) and bool not in types):
                    raise InputError(f"options.{key}: expected {' or '.join(t.__name__ for t in types)}, got "
                                     f"{type(value).__name__}")
        return self


class MotionLayer(_Model):
    """Motion-layer augmentation. Every list is a product axis; a [low, high] entry is drawn per motion."""

    sources: list[Source] = Field(min_length=1)
    heights: list[Scalar | None] = Field([1.75], min_length=1, description="body heights [m]; null keeps a file's")
    time_scales: list[Scalar] = Field([1.0], min_length=1, description="duration factors (2 = half speed)")
    mirror: list[bool | float] = Field([False], min_length=1, description="left/right mirror (or a probability)")
    headings_deg: list[Scalar] = Field([0.0], min_length=1, description="turn about the vertical [deg]")
    starts: list[Literal["auto"] | tuple[Scalar, Scalar]] = Field(
        ["auto"], min_length=1, description="first-frame hips (x, y) [m]; auto: walks centred on the origin")
    fps: float = Field(60.0, ge=10, le=2000, description="motion frame rate [Hz]")
    walk_legs: int | tuple[int, int] = Field(1, description="walks go back and forth: this many passes of each "
                                             "walk (or a [low, high] range of whole numbers, drawn per motion), "
                                             "joined by turns on the spot (rtchannel.motion.compose.back_and_forth)")
    walk_reverse: float = Field(0.0, ge=0, le=1, description="probability that a walk is turned 180 deg (starts "
                                "walking away from where it would walk toward), drawn per motion")
    unscaled: list[Activity] = Field(default_factory=list, description="activities time_scales do "
                                                  "not apply to (e.g. walks, whose pace is their generator's "
                                                  "speed, and falls, driven by gravity, not by the person's pace)")
    walk_turn_s: Scalar = Field(0.8, description="duration of one turn between walk legs [s] (or a range)")
    clip_s: dict[str, float] = Field(default_factory=dict, description="recording length [s] per activity ('*': "
                                     "any other): motions are padded with their first/last pose (split drawn "
                                     "per motion) or cut to it, as real fixed-length recordings")
    clip_start_s: Scalar | Literal["anywhere"] | dict[str, Scalar | Literal["anywhere"]] | None = Field(
        None, description="time of a motion's first frame in its recording [s] (or a range, drawn per motion; or "
        "these per activity, '*': any other); negative: the recording begins that far into the motion. "
        "'anywhere': drawn uniformly over every start that keeps all but clip_overhang of the motion inside the "
        "recording. None: the motion lies inside its recording, its padding split at random")
    clip_overhang: float = Field(0.3, ge=0, le=0.9, description="clip_start_s 'anywhere': share of the motion's "
                                 "duration that may lie outside the recording, at its start or its end")
    idle: IdleMotion | None = Field(None, description="small random upper-body movements added to every motion "
                                    "(rtchannel.motion.idle); null: none")
    idle_scale: Scalar = Field(1.0, description="factor on the idle amplitudes (or a range, drawn per motion: "
                               "people differ in how still they keep)")
    body: BodyShapeRanges | None = Field(None, description="body shapes drawn per motion (sex, age, BMI, muscle, "
                                         "proportions: rtchannel.body.shape.BodyShapeRanges; {} takes its "
                                         "documented defaults); null: the avatar as it is, scaled to the height")

    @field_validator("clip_s")
    @classmethod
    def _clips(cls, v):
        for k, x in _per_activity(v, "clip_s").items():
            if not 0.5 <= x <= 600:
                raise InputError(f"clip_s.{k}: {x} s outside 0.5-600 s")
        return v

    @field_validator("clip_start_s")
    @classmethod
    def _start(cls, v):
        if v is None:  # explicit null (a dumped plan read back): no clip start
            return v
        for k, x in (_per_activity(v, "clip_start_s") if isinstance(v, dict) else {"": v}).items():
            if x != "anywhere":
                _within(x, -30.0, 600.0, f"clip_start_s.{k}" if k else "clip_start_s", " s")
        return v

    @field_validator("idle_scale")
    @classmethod
    def _idle_scale(cls, v):
        return _within(v, 0.0, 10.0, "idle_scale")

    @model_validator(mode="after")
    def _idle_amplitudes(self):
        if self.idle is not None:  # the largest drawn factor must still give valid amplitudes
            hi = max(self.idle_scale) if isinstance(self.idle_scale, tuple) else self.idle_scale
            try:
                self.idle.scaled(hi)
            except ValidationError as e:
                raise InputError(f"idle_scale {hi} takes the idle amplitudes out of range: {one_line(e)}") from None
        return self

    @field_validator("walk_legs")
    @classmethod
    def _legs(cls, v):
        for x in (v if isinstance(v, tuple) else (v,)):
            if not 1 <= x <= 20:
                raise InputError(f"walk_legs {x} outside 1-20")
        if isinstance(v, tuple) and v[0] > v[1]:
            raise InputError(f"walk_legs range {list(v)} must be [low, high] with low <= high")
        return v

    @field_validator("walk_turn_s")
    @classmethod
    def _turn(cls, v):
        return _within(v, 0.1, 10.0, "walk_turn_s", " s")

    @field_validator("heights", "time_scales", "headings_deg")
    @classmethod
    def _ranges(cls, v):
        for x in v:
            if isinstance(x, tuple) and not x[0] <= x[1]:
                raise InputError(f"range {list(x)} must be [low, high] with low <= high")
        return v

    @field_validator("headings_deg")
    @classmethod
    def _headings(cls, v):
        for x in v:
            _within(x, -MAX_HEADING_DEG, MAX_HEADING_DEG, "heading", " deg")
        return v

    @field_validator("starts")
    @classmethod
    def _starts(cls, v):
        for st in v:
            for x in (() if st == "auto" else st):
                _within(x, -MAX_START_M, MAX_START_M, "start coordinate", " m")
        return v

    @field_validator("heights")
    @classmethod
    def _heights(cls, v):
        for x in v:
            for h in ((x,) if not isinstance(x, tuple) else x):
                if h is not None and not 1.2 <= h <= 2.2:
                    raise InputError(f"height {h} m outside 1.2-2.2 m")
        return v

    @field_validator("time_scales")
    @classmethod
    def _time_scales(cls, v):
        for x in v:
            if min(x if isinstance(x, tuple) else (x,)) <= 0:
                raise InputError("time scales must be positive")
        return v

    @field_validator("mirror")
    @classmethod
    def _mirror(cls, v):
        for x in v:
            if not isinstance(x, bool) and not 0 <= x <= 1:
                raise InputError("mirror entries are true/false or a probability in [0, 1]")
        return v


class GainSet(_Model):
    """A set of scatterer amplitude gains: the seed's area gains, scaled per scatterer, optionally perturbed.

    points backend: gain_l = seed_l * scale_l * 10^(N(0, perturb_db) / 20), the perturbation drawn per item.
    Mesh backends (facets, sionna): the set's overall amplitude factor sqrt(sum gain^2 / sum seed^2) scales
    the item's IQ (it only matters relative to noise and clutter; p(v,t) is normalised).
    """

    name: str = Field(pattern=_NAME)
    scale: dict[str, float] = Field(default_factory=dict, description="amplitude factor per scatterer name")
    perturb_db: float = Field(0.0, ge=0, le=20, description="std of a per-scatterer log-normal factor [dB]")

    @field_validator("scale")
    @classmethod
    def _names(cls, v):
        bad = sorted(set(v) - set(SCATTERER_NAMES))
        if bad:
            raise InputError(f"unknown scatterer {bad[0]!r}; names are {', '.join(SCATTERER_NAMES)}")
        if any(x < 0 for x in v.values()):
            raise InputError("gain scale factors must be >= 0")
        return v


class Clutter(_Model):
    """Static clutter: point returns at fixed ranges, total power `csr_db` above the item's signal power."""

    n_scatterers: int = Field(8, ge=1, le=1000)
    csr_db: float = Field(10.0, ge=-60, le=80, description="clutter-to-signal power ratio [dB]")
    range_m: tuple[float, float] = Field((0.5, 8.0), description="(low, high) range of the returns [m]")

    @field_validator("range_m")
    @classmethod
    def _range(cls, v):
        if not 0 < v[0] <= v[1]:
            raise InputError("range_m must be (low, high) with 0 < low <= high")
        return v


class SignalLayer(_Model):
    """Signal-layer augmentation (product axes): gain sets, receiver noise SNRs and clutter variants."""

    gain_sets: list[GainSet] = Field(default_factory=lambda: [GainSet(name="seed")], min_length=1)
    snr_db: list[float | None] = Field([None], min_length=1, description="SNR [dB] per link; null = noiseless")
    clutter: list[Clutter | None] = Field([None], min_length=1)

    @field_validator("gain_sets")
    @classmethod
    def _unique(cls, v):
        return unique_names(v, "gain set")


class Storage(_Model):
    items_per_shard: int = Field(16, ge=1, le=10000, description="work items per task and HDF5 shard")
    keep_iq: bool = Field(False, description="also store raw IQ (complex64; large)")
    image_layout: Literal["glasgow"] | None = Field(
        None, description="store each signature as the real images show it: drawn in this layout and read "
        "back (processing.realdata.spectrogram_image_writer.through_image); glasgow needs clip_s of 5 or 10 s")


class Plan(_Model):
    """A dataset: motion, physical and signal layers, backend and storage. See docs/dataset.md."""

    name: str = Field("dataset", pattern=_NAME)
    seed: int = Field(0, ge=0, le=2**63 - 1, description="plan seed: every random draw derives from it")
    backend: str = Field("points", min_length=1)
    backend_options: dict[str, Any] = Field(default_factory=dict)
    accuracy: str | float | None = Field(None, description="mesh backends: accuracy budget (fast, balanced, exact "
                                         "or an EMD in m/s) choosing backend settings per item (rtchannel.accuracy)")
    calibration: str | None = Field(None, description="with accuracy: calibration table JSON (default: the "
                                    "shipped table of the radar's carrier and range bin)")
    chair: Literal["auto", "none"] = Field("none", description="mesh backends: auto puts a chair under sit and "
                                           "stand motions (Scene.for_motion), as --chair auto")
    motion: MotionLayer
    physical: PhysicalLayer = Field(default_factory=PhysicalLayer)
    signal: SignalLayer = Field(default_factory=SignalLayer)
    storage: Storage = Field(default_factory=Storage)

    @model_validator(mode="after")
    def _budget(self) -> "Plan":
        if self.accuracy is not None:
            from rtchannel.accuracy import parse_budget

            self.accuracy = parse_budget(self.accuracy)
            if self.backend == "points":
                raise InputError("accuracy chooses a mesh backend's settings; the points backend has none")
        elif self.calibration is not None:
            raise InputError("calibration needs accuracy")
        return self

    @model_validator(mode="after")
    def _image_clips(self) -> "Plan":
        if self.storage.image_layout == "glasgow":
            clips = self.motion.clip_s
            acts = {a for a in (s.procedural or s.activity for s in self.motion.sources) if a is not None}
            missing = sorted(a for a in acts if clips.get(a, clips.get("*")) not in (5.0, 10.0))
            if missing:
                raise InputError(f"storage.image_layout glasgow: motion.clip_s must give {missing[0]} a length of "
                                 "5 or 10 s (the Glasgow images' lengths)")
        return self

    def digest(self) -> str:
        """Short sha256 of the normalised plan (identifies the dataset a folder holds)."""
        return hashlib.sha256(json.dumps(self.model_dump(mode="json"), sort_keys=True).encode()).hexdigest()[:16]
