"""One typed options model per backend (pydantic): names, types, ranges, units and defaults of every option.

Everything that takes backend options reads these models: the API (`trace`, `simulate(**options)`), the CLI's
``--option NAME=VALUE``, dataset plans (``backend_options``), the accuracy calibration (`rtchannel.accuracy`
rows and `rtchannel.analysis.calibrate` candidates) and the documentation's table (`options_table`,
docs/backend_options.md, checked by tests/test_backend_options.py). A bad option is one `InputError` line
naming it and the valid names, its range or its type.

The models hold what a user may set; the pipeline sets the rest itself (`RESERVED_OPTIONS`: motion, radar,
progress, timing, stats; the scene is `trace(scene=...)`). Options that hold Python objects (arrays, a skin
material) are set from Python only. The backend functions keep the same defaults (a test pins them).
"""
from __future__ import annotations

import math
from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from processing.errors import InputError

# keywords the pipeline or the dataset runner sets itself; users never pass them as options
RESERVED_OPTIONS = ("motion", "radar", "progress", "timing", "stats")
# the avatar's levels of detail (`rtchannel.body.avatar.LODS`, pinned by a test; named here so that checking an
# option does not load the avatar module)
LOD_NAMES = ("full", "10k", "5k", "2k")
Lod = Literal["full", "10k", "5k", "2k", "auto"]
MAX_TRACE_FPS_HZ = 1000.0  # the ray tracers evaluate at most 1 kHz: a body moves < 1 cm per frame even at 10 m/s


def _opt(default, unit: str, description: str, **constraints):
    """A model field with its unit (shown in the docs table) and description."""
    return Field(default, description=description, json_schema_extra={"unit": unit}, **constraints)


class BackendOptions(BaseModel):
    """Options shared by the backend models' machinery (not a backend itself)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, arbitrary_types_allowed=True)
    backend: ClassVar[str] = ""
    python_only: ClassVar[tuple[str, ...]] = ()  # options holding Python objects (set from Python only)

    @field_validator("*", mode="before")
    @classmethod
    def _scalar(cls, value, info):
        if info.field_name in cls.python_only:
            return value
        if isinstance(value, (dict, list, tuple, set)):
            raise ValueError(f"expected a single value, got a {type(value).__name__}")
        if isinstance(value, float) and not math.isfinite(value):
            raise ValueError("must be finite")
        return value


def _array_or_none(value, what: str):
    if value is not None and not hasattr(value, "__array__"):
        raise ValueError(f"expects an array ({what}; set it from Python)")
    return value


class PointsOptions(BackendOptions):
    """The `points` backend (`rtchannel.backends.points.point_paths`): the seed's 21 point scatterers."""

    backend: ClassVar[str] = "points"
    python_only: ClassVar[tuple[str, ...]] = ("gains", "trajectories")

    gains: Any = _opt(None, "1", "amplitude gain per scatterer [21] (complex array, Python only); default the "
                      "Lund-Browder area gains")
    trajectories: Any = _opt(None, "m", "scatterer positions [frames, scatterers, 3] (array, Python only); default "
                             "the skeleton-attached seed scatterers")
    scale: Literal["radar", "seed"] = _opt("radar", "-", "radar: gains^2 x body_rcs_m2 through the radar equation; "
                                           "seed: the gains as they are")
    body_rcs_m2: float = _opt(0.49, "m^2", "whole-body RCS on the radar scale", gt=0.0, le=100.0)

    @field_validator("gains")
    @classmethod
    def _gains(cls, v):
        return _array_or_none(v, "one gain per scatterer")

    @field_validator("trajectories")
    @classmethod
    def _trajectories(cls, v):
        return _array_or_none(v, "[frames, scatterers, 3] m")


def _skin(value):
    if value is not None and not hasattr(value, "relative_permittivity"):
        raise ValueError("expects a rtchannel.scene.skin.SkinMaterial (set it from Python)")
    return value


class FacetsOptions(BackendOptions):
    """The `facets` backend (`rtchannel.backends.facets.facet_paths`): every triangle of the skinned avatar."""

    backend: ClassVar[str] = "facets"
    python_only: ClassVar[tuple[str, ...]] = ("skin",)

    lod: Lod = _opt("10k", "-", "avatar level of detail, or auto: the coarsest whose facets scatter like the smooth "
                    "body at the carrier")
    trace_fps: float | None = _opt(10.0, "Hz", "rate of visibility and gain evaluation (null: every motion frame)",
                                   gt=0.0, le=MAX_TRACE_FPS_HZ)
    walls: bool | str = _opt(True, "-", "first-order body-wall image paths: true, false, auto (the walls in view) "
                             "or comma-separated wall names")
    po: bool = _opt(True, "-", "add the physical-optics term to the diffuse gain")
    skin: Any = _opt(None, "-", "body material (SkinMaterial, Python only); default dry skin at the carrier")
    min_relative_gain_db: float | None = _opt(-50.0, "dB", "drop paths this far below the link's strongest (null: "
                                              "keep all)", ge=-400.0, le=0.0)
    velocity_method: Literal["spline", "central"] = _opt("spline", "-", "vertex velocities from splines or "
                                                         "central differences")
    batch_frames: int = _opt(16, "frames", "traced frames sharing one BVH build (speed only)", ge=1, le=4096)
    image_lod: Literal["full", "10k", "5k", "2k"] | None = _opt("2k", "-", "LOD the wall-image paths are traced "
                                                                 "on (null: lod)")
    seed: int | None = _opt(0, "-", "seed of each facet's diffuse phase (null: no random phase)", ge=0,
                            le=2 ** 63 - 1)
    double_bounce: bool | str = _opt("floor", "-", "double-bounce wall paths: floor, true (each wall), pairs, "
                                     "false, or a wall's name")
    clutter: bool = _opt(True, "-", "static clutter of walls, floor and furniture, shadowed by the body")
    trace_step_m: float | None = _opt(None, "m", "instead of trace_fps: trace where the fastest vertex moved this "
                                      "far", gt=0.0, le=10.0)
    trace_step_deg: float | None = _opt(None, "deg", "instead of trace_fps: trace where the facets' aspect turned "
                                        "this far", gt=0.0, le=180.0)
    trace_max_gap_s: float = _opt(1.0, "s", "with trace_step_m/deg: longest time between traced frames", gt=0.0,
                                  le=60.0)
    wall_cut_db: float | None = _opt(-30.0, "dB", "with walls=auto: cull a wall every antenna sees this far below "
                                     "its peak", ge=-200.0, le=0.0)

    @field_validator("skin")
    @classmethod
    def _skin_material(cls, v):
        return _skin(v)


class SionnaOptions(BackendOptions):
    """The `sionna` backend (`rtchannel.backends.sionna_rt.sionna_paths`): Sionna RT's path solver."""

    backend: ClassVar[str] = "sionna"
    python_only: ClassVar[tuple[str, ...]] = ("skin",)

    lod: Lod = _opt("10k", "-", "avatar level of detail, or auto (as facets)")
    trace_fps: float | None = _opt(None, "Hz", "trace at this frame rate (null: every motion frame)", gt=0.0,
                                   le=MAX_TRACE_FPS_HZ)
    samples_per_src: int = _opt(1_000_000, "rays", "rays shot per transmitter and frame", ge=1, le=10 ** 9)
    max_depth: int = _opt(1, "-", "maximum interactions per path", ge=1, le=10)
    specular: bool = _opt(True, "-", "specular reflection")
    diffuse: bool = _opt(True, "-", "diffuse reflection")
    refraction: bool = _opt(False, "-", "refraction")
    diffraction: bool = _opt(False, "-", "diffraction")
    skin: Any = _opt(None, "-", "body material (SkinMaterial, Python only); default dry skin at the carrier")
    seed: int = _opt(0, "-", "ray-sampling seed (the same every frame)", ge=0, le=2 ** 31 - 1)
    deterministic: bool = _opt(False, "-", "Sionna's deterministic candidate generator")
    pad_bucket: int = _opt(512, "paths", "candidate counts padded to a multiple of this (0: no padding)", ge=0,
                           le=10 ** 7)
    joint_links: bool = _opt(True, "-", "trace all links in one solver call per antenna-shape group")
    max_num_paths_per_src: int = _opt(1_000_000, "paths", "Sionna's candidate buffer per source", ge=1, le=10 ** 9)

    @field_validator("skin")
    @classmethod
    def _skin_material(cls, v):
        return _skin(v)


OPTIONS: dict[str, type[BackendOptions]] = {m.backend: m for m in (PointsOptions, FacetsOptions, SionnaOptions)}


def options_model(backend: str) -> type[BackendOptions]:
    """The options model of `backend` (InputError naming the backends for an unknown one)."""
    if backend not in OPTIONS:
        raise InputError(f"unknown backend '{backend}'; choose one of {', '.join(OPTIONS)}")
    return OPTIONS[backend]


def option_names(backend: str, reserved: tuple[str, ...] = RESERVED_OPTIONS) -> list[str]:
    """The options a user may set for `backend` (its model's fields less `reserved`)."""
    return [n for n in options_model(backend).model_fields if n not in reserved]


def validate_options(backend: str, options: dict, reserved: tuple[str, ...] = RESERVED_OPTIONS) -> dict:
    """The one check of backend options, shared by every command, dataset plans, the accuracy tables and the
    API: the backend exists, every name is one of its options (and not `reserved`), every value fits the
    option's type and range.

    Args:
        backend: "points", "facets" or "sionna".
        options: {name: value} as given (values from the CLI and plans are YAML scalars).
        reserved: names refused although the model has them (set by the caller itself).

    Returns:
        {name: value} of the given names, converted to the option's type (e.g. 30 -> 30.0 Hz).

    Raises:
        processing.errors.InputError: one line naming the option and the valid names, range or type.
    """
    model = options_model(backend)
    names = option_names(backend, reserved)
    bad = [n for n in options if n not in names]
    if bad:
        raise InputError(f"backend '{backend}' has no option '{bad[0]}' (its options: {', '.join(names)})")
    try:
        checked = model.model_validate(options)
    except ValidationError as e:
        err = e.errors()[0]
        name = str(err["loc"][0]) if err.get("loc") else "?"
        msg = err["msg"].removeprefix("Value error, ")
        raise InputError(f"backend option '{name}' = {options.get(name)!r}: {msg}") from None
    return {n: getattr(checked, n) for n in options}


def options_table(backend: str) -> str:
    """The markdown table of `backend`'s options (name, type, default, range, unit, meaning), as in
    docs/backend_options.md."""
    model = options_model(backend)
    rows = ["| option | type | default | range | unit | meaning |", "|---|---|---|---|---|---|"]
    for name, info in model.model_fields.items():
        kind = "Python object" if name in model.python_only else _type_name(info.annotation)
        default = "null" if info.default is None else _yaml(info.default)
        bounds = [f"{sym} {_yaml(getattr(m, attr))}" for m in info.metadata for attr, sym in
                  (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")) if getattr(m, attr, None) is not None]
        extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
        unit = extra.get("unit", "-")
        rows.append(f"| `{name}` | {kind} | `{default}` | {', '.join(bounds) or '-'} | {unit} | {info.description} |")
    return "\n".join(rows)


def options_doc() -> str:
    """docs/backend_options.md: every backend's options table (regenerate with scripts/backend_options_doc.py)."""
    parts = ["# Backend options", "",
             "Generated from the typed options models (`rtchannel/backends/options.py`) by",
             "`scripts/backend_options_doc.py`; tests/test_backend_options.py checks that this page agrees with them.",
             "Set them as keywords (`simulate(motion, radar, backend=\"facets\", lod=\"5k\")`), on the command line",
             "(`--option lod=5k`, values as YAML scalars: `null`, `true`, numbers) or in a dataset plan",
             "(`backend_options: {lod: 5k}`). A bad name, type or value is one error line naming the option.", ""]
    for backend, model in OPTIONS.items():
        parts += [f"## `{backend}`", "", (model.__doc__ or "").strip(), "", options_table(backend), ""]
    return "\n".join(parts)


def _yaml(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)) and value >= 10 ** 6:
        exact = {f"1e{k}": 10 ** k for k in range(6, 19)} | {f"2^{k} - 1": 2 ** k - 1 for k in (31, 63)}
        return next((text for text, v in exact.items() if v == value), str(value))
    return f"{value:g}" if isinstance(value, float) else str(value)


def _type_name(annotation) -> str:
    """A readable type: float, int | null, one of full, 10k, ... (escaped for a markdown table)."""
    import typing

    args = typing.get_args(annotation)
    if typing.get_origin(annotation) is Literal:
        return ", ".join(map(str, args))
    if args:  # a union
        return " \\| ".join(_type_name(a) for a in args)
    return "null" if annotation is type(None) else getattr(annotation, "__name__", str(annotation))


__all__ = ["BackendOptions", "FacetsOptions", "LOD_NAMES", "OPTIONS", "PointsOptions", "RESERVED_OPTIONS",
           "SionnaOptions", "option_names", "options_doc", "options_model", "options_table", "validate_options"]
