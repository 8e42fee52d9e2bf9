"""What `rtchannel dataset --dry-run` tries beyond the plan's fields, without simulating: every distinct motion
file of the plan's `files` sources loads (once, with the source's options, as the work items will load it), and
each source's options fit its files (a skeleton for an AMC motion and only for it, checked by `plan.expand`; a
`trim` that starts inside the take and keeps at least two frames of it).

Registered third-party files (``data:``) are loaded only when they are already local (mirror or cache): a dry
run never downloads; the ones it could not try are counted.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from processing.errors import InputError, one_line
from rtchannel.data_registry import DATA_PREFIX
from rtchannel.dataset.plan import _labelled_files, skeleton_for
from rtchannel.dataset.plan_schema import Plan
from rtchannel.errors import ConfigError


@dataclass
class SourceCheck:
    """What `check_sources` did: files loaded, and registered files it could not try (not local)."""

    loaded: int = 0
    not_local: int = 0


def _local(path: Path, registered: bool) -> Path | None:
    """The local file of a plan's motion or skeleton path (a registry path when `registered`), or None."""
    if not registered:
        return path
    from rtchannel import data_registry

    return data_registry.local_path(path.as_posix())


def check_sources(plan: Plan, where: str) -> SourceCheck:
    """Load every distinct motion file of `plan`'s `files` sources once and check each source's `trim` against
    it; `ConfigError` naming `where` (the plan), the source and the file for the first that fails.

    The file is loaded as the work items load it (`rtchannel.motion.load.load_motion` with the source's options,
    the motion layer's frame rate and, if the plan keeps a file's own height anywhere, that height, else the
    first height), so what fails here would fail every item made from it.
    """
    from rtchannel.motion.augment import trim as trim_motion
    from rtchannel.motion.load import load_motion
    from rtchannel.motion.pose import Motion

    ml = plan.motion
    check_starts_in_room(plan, where)
    heights = [h if not isinstance(h, tuple) else h[0] for h in ml.heights]
    height = None if None in heights else heights[0]
    loaded: dict[str, Motion] = {}
    out = SourceCheck()
    for si, src in enumerate(ml.sources):
        if src.files is None:
            continue
        registered = src.files.startswith(DATA_PREFIX)
        for f, _rel in _labelled_files(src, fetch=False):
            name = f"{where}: motion.sources.{si}: {f.name}"
            options = dict(src.options)
            local = _local(f, registered)
            if "skeleton" in options:
                skel = skeleton_for(f, options["skeleton"], fetch=False)
                options["skeleton"] = _local(skel, options["skeleton"].startswith(DATA_PREFIX))
                if options["skeleton"] is None:
                    local = None
            if local is None:
                out.not_local += 1
                continue
            assert src.activity is not None  # a files source has one (Source._one_kind)
            activity = f.parent.name if src.activity == "from_folder" else src.activity
            key = json.dumps([str(local), sorted((k, str(v)) for k, v in options.items())])
            try:
                if key not in loaded:
                    loaded[key] = load_motion(local, fps=ml.fps, height=height, activity=activity, **options)
                    out.loaded += 1
                motion = loaded[key]
                if src.trim is not None:
                    t0, t1 = src.trim
                    if t0 >= motion.duration:
                        raise InputError(f"trim starts at {t0:g} s, after the take's end ({motion.duration:.2f} s)")
                    trim_motion(motion, t0, t1)
            except InputError as e:  # MotionImportError, ConfigError, a trim keeping too little
                raise ConfigError(f"{name}: {one_line(e, 300)}") from None
    return out


def check_starts_in_room(plan: Plan, where: str) -> None:
    """`ConfigError` when a mesh backend traces the default room (the plan draws no `physical.room`) and a
    `starts` entry (value or range) puts the hips on or beyond its walls: every item of it would fail
    (`rtchannel.scene.rooms.check_inside_room`). Automatic starts are centred on the origin."""
    from rtchannel.backends import MESH_BACKENDS
    from rtchannel.scene.rooms import DEFAULT_ROOM

    if plan.backend not in MESH_BACKENDS or plan.physical.room is not None:
        return
    x0, x1, y0, y1, _ = DEFAULT_ROOM
    for st in plan.motion.starts:
        if st == "auto":
            continue
        xs, ys = ((v if isinstance(v, tuple) else (v, v)) for v in st)
        if not (x0 < min(xs) and max(xs) < x1 and y0 < min(ys) and max(ys) < y1):
            raise ConfigError(f"{where}: motion.starts {[list(v) if isinstance(v, tuple) else v for v in st]} puts the "
                              f"person outside the {plan.backend} backend's room (walls at x {x0:g}..{x1:g} m, y "
                              f"{y0:g}..{y1:g} m); draw rooms around the person (physical.room) or move the starts")


__all__ = ["SourceCheck", "check_sources", "check_starts_in_room"]
