"""Reading plan files safely and sizing a plan before it is expanded.

A plan is user input that drives hours of work, so it is refused (one `ConfigError` line naming the file
and the line or field) before anything is expanded:

* the text (`rtchannel.safe_yaml`): at most `MAX_PLAN_BYTES`, UTF-8, valid YAML (errors give the line), at
  most `MAX_DEPTH` levels of nesting, and at most `MAX_YAML_NODES` values *after* alias expansion. The size is
  counted on the composed node graph (each anchored node's expanded size is computed once), so a "billion laughs"
  alias bomb is refused in microseconds without ever being expanded; a recursive alias is refused too.
  Aliases themselves stay allowed (a plan may reuse a link set);
* `backend_options`: every value a finite scalar (str, int, float, bool or null): backends take single
  values, and anything nested would be copied into every work item;
* the item count: the product of the layers' list lengths, counted (Python integers, no overflow) and
  never expanded; an empty axis (e.g. ``directions: []``) and more than `MAX_PLAN_ITEMS` items are
  refused. `MAX_PLAN_ITEMS` keeps `expand` within ~1 GB (measured ~1 kB and ~25 us per work item).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rtchannel.errors import ConfigError
from rtchannel.safe_yaml import MAX_DEPTH, MAX_YAML_NODES, read_yaml_mapping  # noqa: F401 - re-exported

MAX_PLAN_BYTES = 1 << 20  # 1 MiB: the seed preset is 2 kB
MAX_PLAN_ITEMS = 1_000_000  # work items per plan (split larger datasets into several plans)
SCALAR_TYPES = (str, bool, int, float)


def read_plan_yaml(path: Path) -> dict:
    """The mapping in a YAML/JSON plan file (`rtchannel.safe_yaml.read_yaml_mapping` with the plan limits)."""
    return read_yaml_mapping(path, "plan", MAX_PLAN_BYTES)


def check_backend_options(options, where: str) -> None:
    """`ConfigError` naming the first backend option whose value is not a finite scalar."""
    if not isinstance(options, dict):
        return  # the model reports a wrong type with its field name
    for name, value in options.items():
        if value is not None and not isinstance(value, SCALAR_TYPES):
            raise ConfigError(f"{where}: backend_options.{name}: expected a single value (text, number or "
                              f"true/false), got a {type(value).__name__}")
        if isinstance(value, float) and not math.isfinite(value):
            raise ConfigError(f"{where}: backend_options.{name}: must be finite, got {value}")


def axis_lengths(plan, files_per_source: Callable[[object], int]) -> dict[str, int]:
    """Length of every product axis of `plan` (a `Plan`), named by its field; the item count is their
    product. `files_per_source(source)` counts the motion files of a `files` source."""
    ml, ph, sg = plan.motion, plan.physical, plan.signal
    motions = sum(s.variants if s.procedural is not None else files_per_source(s) for s in ml.sources)
    if ph.angles_deg is not None:
        directions, dir_field = len(ph.angles_deg), "physical.angles_deg"
    else:
        directions, dir_field = 18 if ph.directions in (None, "seed") else len(ph.directions), "physical.directions"
    return {"motion.sources": motions, "motion.heights": len(ml.heights), "motion.time_scales": len(ml.time_scales),
            "motion.mirror": len(ml.mirror), "motion.headings_deg": len(ml.headings_deg),
            "motion.starts": len(ml.starts), dir_field: directions, "physical.waveforms": len(ph.waveforms),
            "physical.link_sets": len(ph.link_sets), "signal.gain_sets": len(sg.gain_sets),
            "signal.snr_db": len(sg.snr_db), "signal.clutter": len(sg.clutter)}


def count_items(plan, files_per_source: Callable[[Any], int], where: str) -> int:
    """Number of work items of `plan`, counted from the axis lengths (nothing is expanded).

    Raises `ConfigError` (prefixed with `where`) when an axis is empty (the plan would give no items) or
    the count exceeds `MAX_PLAN_ITEMS`."""
    lengths = axis_lengths(plan, files_per_source)
    for name, n in lengths.items():
        if n == 0:
            raise ConfigError(f"{where}: {name}: empty list, the plan would have no items")
    total = math.prod(lengths.values())
    if total > MAX_PLAN_ITEMS:
        big = sorted(lengths.items(), key=lambda kv: -kv[1])[:3]
        raise ConfigError(f"{where}: {total:.3g} work items, more than the limit of {MAX_PLAN_ITEMS} (largest axes: "
                          f"{', '.join(f'{k} {v}' for k, v in big)}); split the plan")
    return total


__all__ = ["MAX_DEPTH", "MAX_PLAN_BYTES", "MAX_PLAN_ITEMS", "MAX_YAML_NODES", "axis_lengths",
           "check_backend_options", "count_items", "read_plan_yaml"]
