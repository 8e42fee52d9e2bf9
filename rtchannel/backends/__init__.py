"""Scattering backends: each turns a pose sequence into a PathSet per radar link.

The registry below imports a backend only when it is asked for: the mesh backends load Mitsuba, numba
kernels and the avatar, which a points-only run never needs. Their options are typed models
(`rtchannel.backends.options`); the checks below are that module's, under the names callers already use.
"""
from __future__ import annotations

from processing.errors import InputError
from rtchannel.backends.options import RESERVED_OPTIONS, option_names, options_model, validate_options

BACKENDS = ("points", "facets", "sionna")
MESH_BACKENDS = ("facets", "sionna")


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
    names = option_names(backend, reserved)
    return [name for name in options if name not in names]


def check_options(backend: str, options: dict, reserved: tuple[str, ...] = RESERVED_OPTIONS) -> None:
    """Raise InputError naming the first option the backend does not accept (or that is reserved), with the
    names it does accept."""
    bad = unknown_options(backend, options, reserved)
    if bad:
        raise InputError(f"backend '{backend}' has no option '{bad[0]}' (its options: "
                         f"{', '.join(option_names(backend, reserved))})")


def check_option_values(backend: str, options: dict) -> None:
    """Raise InputError naming the first option whose value does not fit its type or range."""
    validate_options(backend, options, reserved=())


__all__ = ["BACKENDS", "MESH_BACKENDS", "RESERVED_OPTIONS", "backend_function", "check_option_values",
           "check_options", "option_names", "options_model", "unknown_options", "validate_options"]
