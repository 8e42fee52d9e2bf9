"""The public API documents its arguments in a structured way: every parameter of every exported function,
and of every public method the project defines on an exported class, has an entry in a Google-style
``Args:`` section of its docstring (what pdoc renders as a parameter list), and an argument annotated as an
array states its shape (``[...]``) there. Units are the entries' own words (``[m]``, ``[s]``, ``[Hz]``)."""
import inspect
import re

import pytest

import rtchannel


def _project_callables():
    for name in rtchannel.__all__:
        obj = getattr(rtchannel, name)
        if inspect.isfunction(obj):
            yield name, obj
        elif inspect.isclass(obj):
            for attr, member in vars(obj).items():
                fn = member.__func__ if isinstance(member, (classmethod, staticmethod)) else member
                if attr.startswith("_") or not inspect.isfunction(fn):
                    continue
                if (fn.__module__ or "").split(".")[0] in ("rtchannel", "processing"):
                    yield f"{name}.{attr}", fn


CALLABLES = sorted(_project_callables())


def args_entries(doc: str) -> dict[str, str] | None:
    """{parameter name: its entry's text} of the ``Args:`` section of a Google-style docstring (an entry may
    name several parameters, ``a, b: ...``), or None without one."""
    m = re.search(r"^(?:Args|Arguments):\n((?:[ \t]+.*\n?|\n)*)", doc, flags=re.M)
    if not m:
        return None
    entries, current = {}, []
    for line in m.group(1).splitlines():
        head = re.match(r"^ {4}(\*{0,2}[\w, *]+?)(?: \([^)]*\))?:(.*)", line)
        if head:
            current = [n.strip().lstrip("*") for n in head.group(1).split(",")]
            for n in current:
                entries[n] = head.group(2)
        else:
            for n in current:
                entries[n] += " " + line.strip()
    return entries


@pytest.mark.parametrize("name,fn", CALLABLES, ids=[n for n, _ in CALLABLES])
def test_every_argument_has_a_structured_entry(name, fn):
    doc = inspect.getdoc(fn) or ""
    assert doc, f"{name} has no docstring"
    params = {p: v for p, v in inspect.signature(fn).parameters.items() if p not in ("self", "cls")}
    if not params:
        return
    entries = args_entries(doc)
    assert entries is not None, f"{name}: no Args: section"
    missing = [p for p in params if p not in entries]
    assert not missing, f"{name}: arguments without an Args: entry: {missing}"
    arrays = [p for p, v in params.items() if "ndarray" in str(v.annotation) and "[" not in entries[p]]
    assert not arrays, f"{name}: array arguments whose entry states no shape [...]: {arrays}"


def test_the_check_covers_the_api_and_can_fail():
    names = {n for n, _ in CALLABLES}
    assert {"simulate", "trace", "synthesise", "process", "Motion.procedural", "Radar.seed", "Scene.room",
            "SimulationResult.load", "PathSets.save", "train_classifier"} <= names
    assert args_entries("Summary.\n\nArgs:\n    a, b: one [m].\n    c (int): two\n        more.\n") == {
        "a": " one [m].", "b": " one [m].", "c": " two more."}
    assert args_entries("Summary naming `a` and `b` in prose.") is None
