"""Scattering backends: each turns a pose sequence into a PathSet per radar link.

The registry below imports a backend only when it is asked for: the mesh backends load Mitsuba, numba
kernels and the avatar, which a points-only run never needs.
"""
from __future__ import annotations

import inspect
import math

from processing.errors import InputError

BACKENDS = ("points", "facets", "sionna")
MESH_BACKENDS = ("facets", "sionna")
# keywords the pipeline or the dataset runner sets itself; users never pass them as options
RESERVED_OPTIONS = ("motion", "radar", "progress", "timing", "stats")


def backend_function(backend: str):
    """The path-set function `f(motion, radar, **options) -> {link: PathSet}` of the named backend."""
    if backend == "points":
        from rtchannel.backends.points import point_paths

        return point_paths
    if backend == "facets":
        from rtchannel.backends.facets import facet_paths

        return facet_paths
    if backend == "sionna":
        from rtchannel.backends.sionna_rt import sionna_paths

        return sionna_paths
    raise InputError(f"unknown backend '{backend}'; choose one of {', '.join(BACKENDS)}")


def unknown_options(backend: str, options: dict, reserved: tuple[str, ...] = RESERVED_OPTIONS) -> list[str]:
    """The option names the backend does not accept (or that are reserved), in the order given."""
    accepted = inspect.signature(backend_function(backend)).parameters
    return [name for name in options if name not in accepted or name in reserved]


def option_names(backend: str, reserved: tuple[str, ...] = RESERVED_OPTIONS) -> list[str]:
    """The options a user may set for `backend` (its keyword arguments less motion, radar and `reserved`)."""
    accepted = inspect.signature(backend_function(backend)).parameters
    return [n for n in accepted if n not in ("motion", "radar") and n not in reserved]


def check_options(backend: str, options: dict, reserved: tuple[str, ...] = RESERVED_OPTIONS) -> None:
    """Raise InputError naming the first option the backend does not accept (or that is reserved), with the
    names it does accept."""
    bad = unknown_options(backend, options, reserved)
    if bad:
        raise InputError(f"backend '{backend}' has no option '{bad[0]}' (its options: "
                         f"{', '.join(option_names(backend, reserved))})")


def validate_options(backend: str, options: dict, reserved: tuple[str, ...] = RESERVED_OPTIONS) -> None:
    """The one check of backend options, shared by every command, dataset plans and the API: the backend
    exists, every name is one of its options and every value fits the option's type (InputError, one line
    naming the option and the valid names or the expected type)."""
    check_options(backend, options, reserved)
    check_option_values(backend, options)


def check_option_values(backend: str, options: dict) -> None:
    """Raise InputError naming the first option whose value does not fit the backend's type annotation
    (e.g. ``body_rcs_m2=abc``) or is not a scalar (options come from command lines and YAML plans)."""
    import typing

    from pydantic import TypeAdapter, ValidationError

    hints = typing.get_type_hints(backend_function(backend))
    for name, value in options.items():
        if isinstance(value, (dict, list, tuple, set)):
            raise InputError(f"backend option '{name}': expected a single value, got a {type(value).__name__}")
        hint = hints.get(name)
        if hint is None or name == "scene":
            continue
        if "ndarray" in str(hint) and not hasattr(value, "__array__") and value is not None:
            raise InputError(f"backend option '{name}' = {value!r}: expects an array (set it from Python)")
        try:
            TypeAdapter(hint).validate_python(value, strict=False)
        except ValidationError as e:
            raise InputError(f"backend option '{name}' = {value!r}: {e.errors()[0]['msg']}") from None
        except Exception:  # noqa: BLE001 - an annotation pydantic cannot check (a library object): skip
            continue
        if isinstance(value, float) and not math.isfinite(value):
            raise InputError(f"backend option '{name}' = {value!r}: must be finite")
