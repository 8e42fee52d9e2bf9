"""Reading YAML configuration files (dataset plans, radar descriptions) safely.

User input that drives hours of work is refused with one `ConfigError` line naming the file and line
before anything is built: at most `max_bytes`, UTF-8, valid YAML (errors give the line), at most
`MAX_DEPTH` levels of nesting, and at most `MAX_YAML_NODES` values *after* alias expansion. The size is
counted on the composed node graph (each anchored node's expanded size is computed once), so a "billion
laughs" alias bomb is refused in microseconds without ever being expanded; a recursive alias is refused
too. Aliases themselves stay allowed (a plan may reuse a link set). JSON is YAML, so the same reader
takes both.
"""
from __future__ import annotations

from pathlib import Path

import yaml

from rtchannel.errors import ConfigError

MAX_YAML_NODES = 100_000  # values after alias expansion; a large hand-written plan has a few hundred
MAX_DEPTH = 64  # nesting levels (PyYAML's composer recurses per level); a plan uses about 6


class _BoundedLoader(yaml.SafeLoader):
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


def read_yaml_mapping(path: Path, what: str = "plan", max_bytes: int = 1 << 20) -> dict:
    """The mapping in a YAML (or JSON) file; `ConfigError` naming `what`, the file (and line) for anything
    that is not a small, well-formed YAML mapping (see the module docstring for the limits)."""
    where = f"{what} {path}"
    try:
        n_bytes = path.stat().st_size
    except OSError as e:
        raise ConfigError(f"{where}: cannot read ({e.strerror or e})") from None
    if n_bytes > max_bytes:
        raise ConfigError(f"{where}: {n_bytes} bytes, more than the {max_bytes} a {what} file may have")
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(f"{where}: not UTF-8 text (byte {e.start})") from None
    try:
        loader = _BoundedLoader(text)  # its reader already refuses non-printable characters
    except yaml.YAMLError as e:
        raise ConfigError(f"{where}: {_yaml_error(e)}") from None
    try:
        node = loader.get_single_node()
        if node is None:  # an empty file (or only comments) would silently mean "all defaults"
            raise ConfigError(f"{where}: the file is empty (no {what} settings); give the settings, or leave "
                              f"the file out for the defaults")
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
    if data is None or data == {}:
        raise ConfigError(f"{where}: the file is empty (no {what} settings); give the settings, or leave the "
                          f"file out for the defaults")
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a mapping at the top level, got a {type(data).__name__}")
    return data
