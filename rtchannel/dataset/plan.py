"""Augmentation plan: loading a validated config (motion, physical and signal layers; the schema is in
`plan_schema`) and its deterministic expansion into work items, one per (motion variant, direction,
link set/waveform, gain set, noise, clutter).

Randomness: every draw comes from ``numpy.random.SeedSequence(plan.seed, spawn_key=sha256(key))`` with
a key naming what is drawn, so the same config gives the same items (and the same dataset), and changing
the plan seed changes every draw. Motion-layer draws depend only on the motion key, so all directions
and gain sets of one motion see the same body; signal-layer draws (gain perturbation, noise, clutter)
use the item seed.
"""
from __future__ import annotations

import fnmatch
import hashlib
import itertools
import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from rtchannel.motion.procedural import ACTIVITIES, ProceduralParams
from rtchannel.backends import RESERVED_OPTIONS, validate_options
from rtchannel.data_registry import DATA_PREFIX
from rtchannel.errors import ConfigError
from rtchannel.dataset.plan_schema import (  # noqa: F401 - the schema, re-exported with its loader
    Clutter, GainSet, LinkSet, MotionLayer, PhysicalLayer, Plan, SignalLayer, Source, Storage, for_activity)
from rtchannel.dataset.plan_yaml import check_backend_options, count_items, read_plan_yaml
from processing.errors import InputError

MOTION_SUFFIXES = (".bvh", ".c3d", ".amc", ".json", ".npz", ".csv")
PRESETS_DIR = Path(__file__).with_name("presets")


def resolve_config(spec: str | Path) -> Path:
    """Path of a plan file, or of a preset named `spec` (e.g. ``seed``) in rtchannel/dataset/presets/."""
    p = Path(spec)
    if p.is_file():
        return p
    preset = PRESETS_DIR / f"{spec}.yaml"
    if p.suffix == "" and preset.is_file():
        return preset
    raise FileNotFoundError(f"plan file not found: {spec} (presets: "
                            f"{', '.join(sorted(q.stem for q in PRESETS_DIR.glob('*.yaml')))})")


def load_plan(spec: str | Path, **overrides) -> Plan:
    """Validate a YAML/JSON plan (file or preset name); `files` paths become absolute (relative to the plan).

    Raises pydantic.ValidationError naming the bad field, FileNotFoundError, or ConfigError naming the file
    (bad or oversized YAML, non-scalar backend options, an empty axis or too many items: `plan_yaml`).
    """
    path = resolve_config(spec)
    data = read_plan_yaml(path)
    data.update({k: v for k, v in overrides.items() if v is not None})
    check_backend_options(data.get("backend_options"), f"plan {path}")
    plan = Plan.model_validate(data)
    sources = []
    for s in plan.motion.sources:
        if s.files is not None and not s.files.startswith(DATA_PREFIX):
            f = Path(s.files).expanduser()
            s = s.model_copy(update={"files": str((f if f.is_absolute() else path.parent / f).resolve())})
        skel = s.options.get("skeleton")
        if isinstance(skel, str) and not skel.startswith(DATA_PREFIX):  # relative to the plan, like files
            k = Path(skel).expanduser()
            s = s.model_copy(update={"options": {**s.options, "skeleton": str((k if k.is_absolute() else
                                                                              path.parent / k).resolve())}})
        sources.append(s)
    plan = plan.model_copy(update={"motion": plan.motion.model_copy(update={"sources": sources})})
    if plan.calibration is not None:  # relative to the plan file, like motion files
        cal = Path(plan.calibration).expanduser()
        plan = plan.model_copy(update={"calibration": str(cal if cal.is_absolute() else (path.parent / cal).resolve())})
    check_plan_options(plan, f"plan {path}")
    count_items(plan, lambda s: len(_motion_files(s, fetch=False)), f"plan {path}")  # counted, not expanded
    return plan


# what the dataset runner sets itself: a plan never names these
RUNNER_OPTIONS = RESERVED_OPTIONS + ("gains",)


def check_plan_options(plan: Plan, where: str) -> None:
    """ConfigError (one line naming the plan) when the plan's backend is unknown or a backend option is not
    one of the backend's, or of the wrong type: the same check every command and the API make."""
    try:
        validate_options(plan.backend, plan.backend_options, reserved=RUNNER_OPTIONS)
    except ValueError as e:
        raise ConfigError(f"{where}: backend_options: {e}") from None


@dataclass(frozen=True)
class WorkItem:
    """Everything needed to simulate one item (JSON-able; drawn values already resolved)."""

    item_id: str
    seed: int
    activity: str
    group: str
    source: str
    motion: dict  # kind, activity, generator params / file path, height, time_scale, mirror, heading, start
    radar: dict  # RadarConfig (waveform, dsp, links) before rotation
    angle_deg: float
    direction: int | None
    link_set: str
    backend: str
    backend_options: dict
    gain_set: dict
    snr_db: float | None
    clutter: dict | None
    keep_iq: bool
    image_layout: str | None = None
    chair: str = "none"
    room: str | None = None  # mesh backends: a generated box room (rtchannel.scene.rooms), drawn per motion
    accuracy: str | float | None = None  # mesh backends: the plan's accuracy budget (rtchannel.accuracy)
    calibration: str | None = None

    def to_dict(self) -> dict:
        return asdict(self)


def derive_seed(plan_seed: int, key: str) -> int:
    """A 63-bit seed from the plan seed and a key string (SeedSequence, so keys give independent streams)."""
    words = np.frombuffer(hashlib.sha256(key.encode()).digest()[:16], dtype="<u4")
    state = np.random.SeedSequence(plan_seed, spawn_key=tuple(int(w) for w in words)).generate_state(2, np.uint64)
    return int(state[0] >> np.uint64(1))


def _draw(value, rng: np.random.Generator):
    if isinstance(value, tuple):
        return float(rng.uniform(*value))
    return value


def _motion_files(src: Source, fetch: bool = True) -> list[Path]:
    """The motion files of a `files` source, sorted. ``data:PREFIX`` names registered third-party files
    (fetched through `rtchannel.data_registry`; with `fetch` False only counted, nothing downloaded)."""
    assert src.files is not None  # a files source (Source._one_kind)
    if src.files.startswith(DATA_PREFIX):
        return _registry_files(src, fetch)
    root = Path(src.files)
    if root.is_file():
        return [root]
    if not root.is_dir():
        raise FileNotFoundError(f"motion source not found: {root}")
    files = sorted(p for p in root.glob(src.pattern) if p.is_file() and p.suffix.lower() in MOTION_SUFFIXES)
    if not files:
        raise FileNotFoundError(f"no .bvh/.c3d files match {src.pattern!r} in {root}")
    return files


def _registry_files(src: Source, fetch: bool) -> list[Path]:
    from rtchannel import data_registry

    assert src.files is not None  # a files source (Source._one_kind)
    prefix = src.files[len(DATA_PREFIX):].rstrip("/")
    pattern = src.pattern[3:] if src.pattern.startswith("**/") else src.pattern  # '**/*' = anything below
    chosen = []
    for e in data_registry.entries(prefix):
        rel = e.path[len(prefix) + 1:] if e.path != prefix else Path(e.path).name
        if Path(e.path).suffix.lower() in MOTION_SUFFIXES and (e.path == prefix or fnmatch.fnmatch(rel, pattern)):
            chosen.append(e.path)
    if not chosen:
        raise ConfigError(f"motion source {src.files}: no registered .bvh/.c3d file matches {src.pattern!r} "
                          "(rtchannel data list shows them)")
    if not fetch:
        return [Path(p) for p in chosen]
    return [data_registry.fetch(p) for p in chosen]


def skeleton_for(motion_file: Path, spec: str, fetch: bool = True) -> Path:
    """The ASF skeleton of an AMC `motion_file`: `spec` names the file, or a folder (``data:`` prefix or local)
    whose ASF with the longest name that starts the AMC's name is taken (HDM05: HDM_bd.asf for
    HDM_bd_depositFloorR_001_120.amc), so one source can hold several actors' takes."""
    cands: dict[str, str | Path]
    get: Callable[[Any], Path]
    if spec.startswith(DATA_PREFIX):
        from rtchannel import data_registry

        rels = [e.path for e in data_registry.entries(spec[len(DATA_PREFIX):]) if e.path.lower().endswith(".asf")]
        cands = {Path(r).stem: r for r in rels}
        get = (lambda r: data_registry.fetch(str(r))) if fetch else Path
    else:
        p = Path(spec)
        if p.is_file():
            return p
        cands = {q.stem: q for q in p.glob("*.asf")} if p.is_dir() else {}
        get = Path
    best = max((k for k in cands if motion_file.stem.lower().startswith(k.lower())), key=len, default=None)
    if best is None:
        raise ConfigError(f"motion file {motion_file.name}: no ASF skeleton in {spec} whose name starts its name")
    return get(cands[best])


def _labelled_files(src: Source, fetch: bool = True) -> list[tuple[Path, str]]:
    """(local path, label) of each file of a `files` source; the label is the path below the folder or
    registry prefix the source names (the file name for a single file). Without `fetch`, registered files
    keep their registry paths (nothing is downloaded)."""
    files = _motion_files(src, fetch)
    assert src.files is not None  # a files source (Source._one_kind)
    if src.files.startswith(DATA_PREFIX):
        prefix = src.files[len(DATA_PREFIX):].rstrip("/")
        regs = _registry_files(src, fetch=False)
        return [(f, r.name if r.as_posix() == prefix else r.as_posix()[len(prefix) + 1:]) for f, r in zip(files, regs)]
    root = Path(src.files)
    return [(f, f.name if root.is_file() else str(f.relative_to(root))) for f in files]


def _motion_variants(plan: Plan, fetch: bool = True) -> list[tuple[str, str, str, str, dict]]:
    """(motion id, activity, group, source label, base motion dict) per source variant."""
    out: list[tuple[str, str, str, str, dict]] = []
    base: dict[str, Any]
    for si, src in enumerate(plan.motion.sources):
        act: str | None
        if src.procedural is not None:
            act = src.procedural
            for v in range(src.variants):
                rng = np.random.default_rng(derive_seed(plan.seed, f"variant:{si}:{v}"))
                params = {k: _draw(val, rng) for k, val in sorted(src.params.items())}
                try:
                    ProceduralParams(**params)
                except ValidationError as e:
                    err = e.errors()[0]
                    raise InputError(f"motion.sources.{si}.params.{'.'.join(map(str, err['loc'])) or '(root)'}: "
                                     f"{err['msg']} (drawn value {err.get('input')!r})") from None
                # generator seed (mod 3) = fall direction 0 forward, 1 left, 2 right, cycled over the variants;
                # a backward fall is named in the parameters (the seed's residue stays 0)
                direction = src.fall_directions[v % len(src.fall_directions)]
                fall = ("forward", "left", "right").index(direction) if direction != "backward" else 0
                gen_seed = 3 * int(rng.integers(0, 2 ** 20)) + fall
                if act == "fall" and direction == "backward":
                    params["fall_direction"] = "backward"
                base = {"kind": "procedural", "activity": act, "params": {**params, "seed": gen_seed}}
                out.append((f"{act}-{si:02d}-{v:04d}", act, f"procedural:{act}#{si}.{v}", f"procedural:{act}", base))
        else:
            for v, (f, rel) in enumerate(_labelled_files(src, fetch)):
                act = f.parent.name if src.activity == "from_folder" else src.activity
                if act not in ACTIVITIES:
                    raise InputError(f"motion file {f}: folder name {act!r} is not an activity "
                                     f"({', '.join(ACTIVITIES)})")
                options = dict(src.options)
                if (f.suffix.lower() == ".amc") != ("skeleton" in options):
                    raise ConfigError(f"motion.sources.{si}: {f.name}: an .amc motion needs its ASF skeleton "
                                      "(options: {skeleton: FILE or FOLDER}) and only an .amc motion takes one")
                if "skeleton" in options:
                    options["skeleton"] = str(skeleton_for(f, options["skeleton"], fetch))
                base = {"kind": "file", "activity": act, "path": str(f), "options": options}
                if src.trim is not None:
                    base["trim"] = list(src.trim)
                out.append((f"{act}-{si:02d}-{v:04d}", act, f"file:{rel}", rel, base))
    return out


def _antennas(items: list[WorkItem]) -> np.ndarray:
    """World positions [N, 3] (m) of every transmitter and receiver of `items`, after their rotation."""
    pts = []
    for it in items:
        a = np.radians(it.angle_deg)
        rot = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
        for link in it.radar["links"]:
            pts += [rot @ np.asarray(link["tx"], float)] + ([rot @ np.asarray(link["rx"], float)] if link.get("rx")
                                                            else [])
    return np.array(pts)


def expand(plan: Plan, fetch: bool = True) -> list[WorkItem]:
    """All work items of `plan`, sorted by item_id (deterministic). ConfigError first if the plan would
    have no items or more than `plan_yaml.MAX_PLAN_ITEMS`, or a backend option is not a single value.
    `fetch` False: registered motion files are not downloaded and items name them by registry path (for
    counting, e.g. ``dataset --dry-run``; such items cannot be run)."""
    check_backend_options(plan.backend_options, f"plan {plan.name!r}")  # a Plan built in code skips load_plan
    check_plan_options(plan, f"plan {plan.name!r}")
    count_items(plan, lambda s: len(_motion_files(s, fetch=False)), f"plan {plan.name!r}")
    ml, ph, sg = plan.motion, plan.physical, plan.signal
    motion_axes = list(itertools.product(ml.heights, ml.time_scales, ml.mirror, ml.headings_deg, ml.starts))
    phys_axes = list(itertools.product(ph.rotations(), ph.waveforms, ph.link_sets))
    sig_axes = list(itertools.product(sg.gain_sets, sg.snr_db, sg.clutter))
    wm, wp, ws = (max(2, len(str(len(a) - 1))) for a in (motion_axes, phys_axes, sig_axes))
    items = []
    for mid, act, group, source, base in _motion_variants(plan, fetch):
        for mi, (h, ts, mir, hd, st) in enumerate(motion_axes):
            motion_id = f"{mid}-m{mi:0{wm}d}"
            rng = np.random.default_rng(derive_seed(plan.seed, "motion:" + motion_id))
            mirror = bool(mir) if isinstance(mir, bool) else bool(rng.random() < mir)
            start = st if st == "auto" else [float(_draw(x, rng)) for x in st]
            motion = {**base, "fps": ml.fps, "height": _draw(h, rng), "time_scale": float(_draw(ts, rng)),
                      "mirror": mirror, "heading_deg": float(_draw(hd, rng)), "start": start, "key": motion_id}
            clip = for_activity(ml.clip_s, act)
            if act == "walk" and ml.walk_legs != 1:
                legs = ml.walk_legs
                if isinstance(legs, tuple):
                    legs = int(rng.integers(legs[0], legs[1] + 1))
                motion.update(walk_legs=legs, walk_turn_s=float(_draw(ml.walk_turn_s, rng)))
            if clip is not None:  # drawn after the seed's draws: plans without clip_s keep their motions
                motion.update(clip_s=float(clip), clip_lead=float(rng.uniform(0.0, 1.0)))
                start = for_activity(ml.clip_start_s, act)
                if start == "anywhere":  # the motion's duration is known when it is built
                    motion.update(clip_start_s="anywhere", clip_start_u=float(rng.uniform(0.0, 1.0)),
                                  clip_overhang=ml.clip_overhang)
                elif start is not None:  # drawn after the lead: plans without clip_start_s keep their motions
                    motion.update(clip_start_s=float(_draw(start, rng)))
            if ml.idle is not None:
                idle = ml.idle.scaled(float(_draw(ml.idle_scale, rng)))
                motion.update(idle=idle.model_dump(mode="json"), idle_seed=int(rng.integers(2 ** 31)))
            # after every other draw: plans without these fields keep their motions
            if act == "walk" and ml.walk_reverse > 0 and rng.random() < ml.walk_reverse:
                motion.update(heading_deg=motion["heading_deg"] + 180.0)
            if act in ml.unscaled:
                motion.update(time_scale=1.0)
            if ml.body is not None:  # own stream: plans without bodies keep every other draw
                from rtchannel.body.shape import draw_body_shape

                body_rng = np.random.default_rng(derive_seed(plan.seed, "body:" + motion_id))
                motion.update(body=draw_body_shape(body_rng, ml.body).model_dump(mode="json"))
            draws_physical = any(x is not None for x in (ph.downtilt_deg, ph.hpbw_el_deg, ph.distance_m, ph.height_m))
            motion_items = []
            for pi, ((angle, direction), wf, ls) in enumerate(phys_axes):
                links = ls.links
                ant: dict[str, float | str] = {}
                if draws_physical:  # own stream: other draws unchanged
                    arng = np.random.default_rng(derive_seed(plan.seed, f"antenna:{motion_id}-p{pi}"))
                    ant = {key: float(_draw(getattr(ph, key), arng))
                           for key in ("downtilt_deg", "hpbw_el_deg") if getattr(ph, key) is not None}
                    links = ph.placed(links, act, arng)
                if ph.aim is not None or ph.beam is not None or ph.polarization is not None:
                    brng = np.random.default_rng(derive_seed(plan.seed, f"beam:{motion_id}-p{pi}"))  # own stream
                    pol = "V"
                    if ph.polarization is not None:
                        pol = ph.polarization[int(brng.integers(len(ph.polarization)))]
                        ant["polarization"] = pol
                    if ph.aim is not None:
                        stature = 1.75 if motion["height"] is None else float(motion["height"])
                        ant["downtilt_deg"] = ph.aim.downtilt_deg(links[0].tx, stature, brng)
                    if ph.beam is not None:
                        ant.update(ph.beam.draw(brng, pol))
                radar = {"waveform": wf.model_dump(mode="json"), "dsp": ph.dsp.model_dump(mode="json"),
                         "links": [link.model_dump(mode="json") for link in links], **ph.kit(links)}
                if ant:
                    radar["antenna"] = {**radar["antenna"], **ant}
                for gi, (gs, snr, cl) in enumerate(sig_axes):
                    item_id = f"{motion_id}-p{pi:0{wp}d}-s{gi:0{ws}d}"
                    motion_items.append(WorkItem(
                        item_id=item_id, seed=derive_seed(plan.seed, "item:" + item_id), activity=act,
                        group=group, source=source, motion=motion, radar=radar, angle_deg=float(angle),
                        direction=direction, link_set=ls.name, backend=plan.backend,
                        backend_options=dict(plan.backend_options), gain_set=gs.model_dump(mode="json"),
                        snr_db=snr, clutter=None if cl is None else cl.model_dump(mode="json"),
                        keep_iq=plan.storage.keep_iq, image_layout=plan.storage.image_layout,
                        chair=plan.chair, accuracy=plan.accuracy, calibration=plan.calibration))
            if ph.room is not None:  # one room for all items of a motion: they share one mesh-backend run
                rng_room = np.random.default_rng(derive_seed(plan.seed, "room:" + motion_id))
                room = ph.room.draw(_antennas(motion_items), rng_room)
                motion_items = [replace(it, room=room) for it in motion_items]
            items += motion_items
    items.sort(key=lambda it: it.item_id)
    if plan.accuracy is not None:  # every waveform needs a calibration table: fail at --dry-run, not per item
        from rtchannel.accuracy import table_for
        from rtchannel.radar import RadarConfig

        for item in {json.dumps(it.radar["waveform"], sort_keys=True): it for it in items}.values():
            try:
                table_for(RadarConfig.model_validate(item.radar), plan.calibration)
            except ValueError as e:
                raise ConfigError(f"plan {plan.name!r}: accuracy: {e}") from None
    return items
