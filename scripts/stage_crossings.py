"""Count how often the call path of one simulation crosses between the synthesis and the DSP packages.

    python scripts/stage_crossings.py [--backend points] [--synthesis exact|grid|auto] [--show]

Every Python function call made while `rtchannel.simulate` runs one walk for one monostatic link (in every
thread) is recorded with the package of the called function's module; calls into `processing.synthesis.*`
count as "synthesis", calls into `processing.dsp.*` as "dsp", all others (the pipeline, the radar front end,
the neutral fast-time model, numpy, ...) are transparent, and so is the DSP's settings model
(`processing.dsp.config`: `DSPConfig` and the pre-flight `check_recording`), which is what is followed,
not a stage it passes through. The path is the sequence of those labels with
repeats merged; a crossing is one change of label. Data flowing one way, radar -> synthesis -> dsp, gives
exactly one crossing (synthesis, then dsp); every further one is the call path turning back. Before the
fast-time model moved to `processing.fast_time` (commit a23fed9) this counted 15 (exact) and 17 (grid).
"""
from __future__ import annotations

import argparse
import sys
import threading

STAGES = {"processing.synthesis": "synthesis", "processing.dsp": "dsp"}


SETTINGS = ("processing.dsp.config",)


def _stage(module: str) -> str | None:
    if module in SETTINGS:
        return None
    for prefix, label in STAGES.items():
        if module == prefix or module.startswith(prefix + "."):
            return label
    return None


def stage_path(backend: str = "points", synthesis: str = "auto") -> list[tuple[str, str]]:
    """[(stage, first function called in it)] of one simulation, repeats merged (see the module docstring)."""
    from rtchannel import Motion, Radar, simulate

    motion = Motion.procedural("walk", duration=1.0, seed=0)
    radar = Radar.monostatic((3.0, 0.0, 1.1))
    events: list[tuple[str, str]] = []
    lock = threading.Lock()

    def profile(frame, event, arg):
        if event == "call":
            label = _stage(frame.f_globals.get("__name__", ""))
            if label is not None:
                with lock:
                    if not events or events[-1][0] != label:
                        events.append((label, f"{frame.f_globals['__name__']}.{frame.f_code.co_name}"))

    threading.setprofile(profile)
    sys.setprofile(profile)
    try:
        simulate(motion, radar, backend=backend, synthesis=synthesis)
    finally:
        sys.setprofile(None)
        threading.setprofile(None)
    return events


def crossings(backend: str = "points", synthesis: str = "auto") -> int:
    """Changes between synthesis and DSP along one simulation's call path (1: one way, no turning back)."""
    return max(0, len(stage_path(backend, synthesis)) - 1)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--backend", default="points")
    ap.add_argument("--synthesis", default="auto", choices=("auto", "exact", "grid"))
    ap.add_argument("--show", action="store_true", help="print the path")
    args = ap.parse_args(argv)
    path = stage_path(args.backend, args.synthesis)
    if args.show:
        for label, fn in path:
            print(f"{label:9s} {fn}")
    print(f"{args.backend}, synthesis {args.synthesis}: {max(0, len(path) - 1)} crossings between synthesis and dsp")
    return 0


if __name__ == "__main__":
    sys.exit(main())
