"""Where one `rtchannel` command's time goes, measured inside its own process (used by bench_startup.py --split).

Run: python benchmarks/startup_stages.py simulate --backend facets --out DIR   (any `rtchannel` arguments)

The command runs as `rtchannel.cli.main(argv)`. Its stages are found by wrapping, as soon as their module is
imported, the functions below (module attributes looked up at call time, so the wrapper is what runs); the
time between them is "other" (argument parsing, radar file, output checks). Imports are timed apart: a
top-level `import` statement (not nested in another import) that runs while a stage is active is charged to
"import" of that stage, so lazy imports inside a stage show up as such. Time exclusive of nested stages:
"backend" excludes "scene load", which excludes "avatar load". Interpreter start-up (before this script runs) and
exit are not included: the caller compares its own clock with the epoch times printed here.

Prints, as the last line of stdout, JSON {"stages": {stage: [work s, import s]}, "total_s": s, "rc": exit status,
"start_epoch": time.time() at start, "end_epoch": at the end}.
"""
from __future__ import annotations

import builtins
import json
import os
import sys
import time

T0 = time.perf_counter()
T0_EPOCH = time.time()  # the caller's clock: start-up (before this line) and exit (after main) apart

# (module, attribute path) -> stage name; missing ones (an older checkout) are skipped.
TARGETS = {
    ("rtchannel.cli.simulate", "build_motion"): "motion",
    ("rtchannel.cli.simulate", "scene_with_chair"): "chair fit",
    ("rtchannel.scene.rt_scene", "get_scene"): "scene load",
    ("rtchannel.pipeline", "backend_paths"): "backend",
    ("rtchannel.body.avatar", "load_avatar"): "avatar load",
    ("rtchannel.backends.facets", "mesh_paths"): "facets trace",
    ("rtchannel.pipeline", "process_paths"): "synthesis+dsp",
    ("rtchannel.pipeline", "SimulationResult.save"): "save h5",
    ("rtchannel.pipeline", "SimulationResult.plot"): "plots",
}

_stack = ["other"]
_acc: dict[str, list[float]] = {}
_last = [T0]
_depth = [0]
_pending = dict(TARGETS)


def _charge(kind: int) -> None:
    """Charge the time since the last event to the active stage (kind 0: work, 1: import)."""
    now = time.perf_counter()
    _acc.setdefault(_stack[-1], [0.0, 0.0])[kind] += now - _last[0]
    _last[0] = now


def _wrap(fn, stage):
    def timed(*args, **kwargs):
        _charge(0)
        _stack.append(stage)
        try:
            return fn(*args, **kwargs)
        finally:
            _charge(0)
            _stack.pop()

    timed.__wrapped__ = fn
    return timed


def _patch_loaded() -> None:
    for (mod, path), stage in list(_pending.items()):
        m = sys.modules.get(mod)
        if m is None:
            continue
        del _pending[(mod, path)]
        *owner_path, name = path.split(".")
        owner = m
        for part in owner_path:
            owner = getattr(owner, part, None)
        if owner is not None and hasattr(owner, name):
            setattr(owner, name, _wrap(getattr(owner, name), stage))


_real_import = builtins.__import__


def _import(name, globals=None, locals=None, fromlist=(), level=0):
    if _depth[0]:
        return _real_import(name, globals, locals, fromlist, level)
    _charge(0)
    _depth[0] += 1
    try:
        return _real_import(name, globals, locals, fromlist, level)
    finally:
        _depth[0] -= 1
        _charge(1)
        _patch_loaded()  # before a `from m import f` reads f


def main(argv: list[str]) -> int:
    builtins.__import__ = _import
    import rtchannel.cli
    from rtchannel.cli import main as cli_main

    try:
        rc = cli_main(argv)
    finally:
        builtins.__import__ = _real_import
        _charge(0)
    print(json.dumps({"stages": _acc, "total_s": time.perf_counter() - T0, "rc": rc, "start_epoch": T0_EPOCH,
                      "end_epoch": time.time()}), flush=True)
    if argv and argv[0] in getattr(rtchannel.cli, "FAST_EXIT_COMMANDS", ()):
        sys.stderr.flush()
        os._exit(rc)  # as the console script ends (`rtchannel.cli.run`)
    return rc


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
