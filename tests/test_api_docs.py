"""The public API documents its arguments: every parameter of every exported function, and of every public
method the project defines on an exported class, is named in its docstring (an ``Args:`` section with
shapes and units, or the summary for a single obvious argument)."""
import inspect

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


@pytest.mark.parametrize("name,fn", CALLABLES, ids=[n for n, _ in CALLABLES])
def test_every_argument_is_documented(name, fn):
    doc = inspect.getdoc(fn) or ""
    assert doc, f"{name} has no docstring"
    params = [p for p in inspect.signature(fn).parameters if p not in ("self", "cls")]
    missing = [p for p in params if p not in doc]
    assert not missing, f"{name}: arguments not documented: {missing}"


def test_the_check_covers_the_api():
    names = {n for n, _ in CALLABLES}
    assert {"simulate", "trace", "synthesise", "Motion.procedural", "Radar.seed", "Scene.room"} <= names
