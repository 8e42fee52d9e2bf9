"""Reading plan files safely and sizing a plan before it is expanded.

A plan is user input that drives hours of work, so it is refused (one `ConfigError` line naming the file
and the line or field) before anything is expanded:

* the text: at most `MAX_PLAN_BYTES`, UTF-8, valid YAML (errors give the line), at most `MAX_DEPTH`
  levels of nesting, and at most `MAX_YAML_NODES` values *after* alias expansion. The size is counted on
  the composed node graph (each anchored node's expanded size is computed once), so a "billion laughs"
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

import yaml

from rtchannel.errors import ConfigError

MAX_PLAN_BYTES = 1 << 20  # 1 MiB: the seed preset is 2 kB
MAX_YAML_NODES = 100_000  # values after alias expansion; a large hand-written plan has a few hundred
MAX_DEPTH = 64  # nesting levels (PyYAML's composer recurses per level); a plan uses about 6
MAX_PLAN_ITEMS = 1_000_000  # work items per plan (split larger datasets into several plans)
SCALAR_TYPES = (str, bool, int, float)


class _PlanLoader(yaml.SafeLoader):
    """SafeLoader whose composer refuses more than `MAX_DEPTH` nesting levels (it recurses per level, so
    a long run of '[' would otherwise end in a RecursionError after seconds)."""

    _depth = 0

    def compose_node(self, parent, index):  # noqa: D102 - PyYAML hook
        if self._depth >= MAX_DEPTH:
            raise yaml.MarkedYAMLError(problem=f"nested deeper than {MAX_DEPTH} levels",
                                       problem_mark=self.peek_event().start_mark)
        self._depth += 1
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


def _expanded_size(root: yaml.Node, where: str) -> int:
    """Number of nodes `root` stands for once every alias is expanded (memoised over the shared graph;
    iterative, so an alias cycle cannot recurse without bound)."""
    size: dict[int, int] = {}
    on_path: set[int] = set()
    stack: list[yaml.Node] = [root]
    while stack:
        node = stack.pop()
        key = id(node)
        if key in size:
            continue
        if isinstance(node, yaml.ScalarNode):
            size[key] = 1
            continue
        children = [c for pair in node.value for c in pair] if isinstance(node, yaml.MappingNode) else node.value
        if key not in on_path:  # first visit: children first, then this node again
            on_path.add(key)  # (the nodes on the stack's pending path: this node's ancestors)
            stack.append(node)
            for child in children:
                if id(child) in on_path:
                    raise ConfigError(f"{where}: line {child.start_mark.line + 1}: recursive YAML alias")
                stack.append(child)
            continue
        on_path.discard(key)
        size[key] = 1 + sum(size[id(c)] for c in children)
        if size[key] > MAX_YAML_NODES:
            raise ConfigError(f"{where}: line {node.start_mark.line + 1}: more than {MAX_YAML_NODES} values once "
                              f"YAML aliases are expanded (an alias bomb?)")
    return size[id(root)]


def _yaml_error(e: yaml.YAMLError) -> str:
    mark = getattr(e, "problem_mark", None)
    problem = getattr(e, "problem", None) or getattr(e, "reason", None) or str(e).splitlines()[0]
    at = f"line {mark.line + 1}: " if mark is not None else ""
    return f"{at}not valid YAML ({' '.join(str(problem).split())[:120]})"


def read_plan_yaml(path: Path) -> dict:
    """The mapping in a YAML/JSON plan file; `ConfigError` naming the file (and line) for anything that
    is not a small, well-formed YAML mapping (see the module docstring for the limits)."""
    where = f"plan {path}"
    try:
        n_bytes = path.stat().st_size
    except OSError as e:
        raise ConfigError(f"{where}: cannot read ({e.strerror or e})") from None
    if n_bytes > MAX_PLAN_BYTES:
        raise ConfigError(f"{where}: {n_bytes} bytes, more than the {MAX_PLAN_BYTES} a plan may have")
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(f"{where}: not UTF-8 text (byte {e.start})") from None
    try:
        loader = _PlanLoader(text)  # its reader already refuses non-printable characters
    except yaml.YAMLError as e:
        raise ConfigError(f"{where}: {_yaml_error(e)}") from None
    try:
        node = loader.get_single_node()
        if node is None:
            return {}
        _expanded_size(node, where)
        data = loader.construct_document(node)
    except yaml.YAMLError as e:
        raise ConfigError(f"{where}: {_yaml_error(e)}") from None
    except ConfigError:
        raise
    except (ValueError, TypeError, OverflowError) as e:  # a tagged scalar that cannot be built (e.g. a bad date)
        raise ConfigError(f"{where}: not valid YAML ({' '.join(str(e).split())[:120]})") from None
    finally:
        loader.dispose()
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a mapping at the top level, got a {type(data).__name__}")
    return data


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


def count_items(plan, files_per_source: Callable[[object], int], where: str) -> int:
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
