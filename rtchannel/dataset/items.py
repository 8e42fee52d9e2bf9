"""Run one work item: build the motion (motion layer), the rotated radar (physical layer), the scatterer gains,
simulate with the plan's backend, the signal layer (clutter, receiver noise) applied to the raw IQ before DSP.

Warm state: motions and loaded motion files are cached per process (items are sorted so that all
directions and gain sets of one motion run back to back on one worker), and backends keep their own
scene/kernel caches at module level, so a Dask worker pays those costs once. For the mesh backends the
items of one motion run as one task and share one backend run (`run_shared`): the body is skinned and its
BVH built once per frame for all of their antennas.
"""
from __future__ import annotations

import json
import time
import warnings
from collections import OrderedDict
from dataclasses import replace

import numpy as np

from processing.io.dataset_store import ACTIVITIES, SIGNATURE_ARRAYS, signature_arrays
from processing.synthesis.augment import add_clutter, add_noise, signal_power
from rtchannel.dataset.plan import WorkItem
from rtchannel.radar import RadarConfig
from rtchannel.body.scatterers import SCATTERER_NAMES, seed_scatterers
from rtchannel.motion.pose import Motion, avatar_rig
from processing.errors import InputError

_CACHE_SIZE = 8
_MOTIONS: OrderedDict[str, Motion] = OrderedDict()
_FILES: OrderedDict[str, Motion] = OrderedDict()
_SCENES: OrderedDict[str, object] = OrderedDict()


def _cached(cache: OrderedDict, key: str, make):
    if key in cache:
        cache.move_to_end(key)
        return cache[key]
    value = make()
    cache[key] = value
    while len(cache) > _CACHE_SIZE:
        cache.popitem(last=False)
    return value


def _base_motion(m: dict) -> Motion:
    if m["kind"] == "procedural":
        from rtchannel.motion.procedural import ProceduralParams, generate

        p = ProceduralParams(height=1.75 if m["height"] is None else m["height"], fps=m["fps"], **m["params"])
        return generate(m["activity"], p)
    from rtchannel.motion.load import load_motion

    key = json.dumps([m["path"], m["height"], m["fps"], m["options"]], sort_keys=True)
    return _cached(_FILES, key, lambda: load_motion(m["path"], fps=m["fps"], height=m["height"],
                                                   activity=m["activity"], **m["options"]))


def build_motion(m: dict) -> Motion:
    """The augmented motion of an item's motion dict (cached per process by its key)."""
    def make():
        from rtchannel.motion.augment import augment
        from rtchannel.motion.compose import back_and_forth, centre_walk, clip_start_anywhere, fit_clip

        motion = augment(_base_motion(m), time_scale=m["time_scale"], mirror=m["mirror"], trim=m.get("trim"),
                         heading_deg=m["heading_deg"], start=None if m["start"] == "auto" else m["start"])
        if m.get("walk_legs", 1) > 1:
            motion = back_and_forth(motion, m["walk_legs"], m["walk_turn_s"])
        if m["start"] == "auto" and m["activity"] == "walk":
            motion = centre_walk(motion, m.get("walk_legs", 1))
        if m.get("clip_s") is not None:
            start = m.get("clip_start_s")
            if start == "anywhere":
                start = clip_start_anywhere(motion.duration, m["clip_s"], m["clip_start_u"], m["clip_overhang"])
            motion = fit_clip(motion, m["clip_s"], m["clip_lead"], start)
        if m.get("idle") is not None:  # after the clip fit: the held poses before and after move too
            from rtchannel.motion.idle import IdleMotion, add_idle

            motion = add_idle(motion, IdleMotion(**m["idle"]), m["idle_seed"])
        if m.get("body") is not None:  # last: the shaped rig follows every pose the steps above made
            from rtchannel.body.shape import reshape_motion

            motion = reshape_motion(motion, m["body"])
        return motion
    # keyed by the whole motion dict, not m["key"]: motion ids repeat across plans ("fall-00-0000-m00" of
    # any plan), and a process that ran another plan first reused that plan's motion (different bytes)
    return _cached(_MOTIONS, json.dumps(m, sort_keys=True, default=str), make)


def _without_range_doppler(radar: RadarConfig) -> RadarConfig:
    """`radar` with its DSP's range-Doppler maps off: a dataset stores the signatures of
    `processing.io.dataset_store.SIGNATURE_ARRAYS`, which do not include them (computing them took ~15 % of the
    Glasgow DSP); the signatures it stores are the same with or without."""
    if "range_doppler" in SIGNATURE_ARRAYS or not radar.dsp.range_doppler:
        return radar
    return radar.model_copy(update={"dsp": radar.dsp.model_copy(update={"range_doppler": False})})


def item_scene(item: WorkItem, motion: Motion):
    """The mesh backends' scene of an item: its drawn room (None: the default room) plus the chair its plan
    asks for under `motion` (`Scene.for_motion`). Cached per process by motion, room and chair: the items of
    one motion (its placements) share them, and the chair's fit skins the whole motion."""
    def make():
        from rtchannel.scene.spec import Scene

        scene = Scene(item.room) if item.room is not None else None
        return Scene.for_motion(motion, scene, item.chair) if item.chair != "none" else scene
    return _cached(_SCENES, json.dumps([item.motion, item.room, item.chair], sort_keys=True, default=str), make)


def item_gains(gain_set: dict, rng: np.random.Generator) -> np.ndarray:
    """Amplitude gains [21] of the seed's scatterers for a gain set: seed gains x scale x log-normal factor."""
    g = seed_scatterers(avatar_rig()).gains.astype(float).copy()
    g *= np.array([gain_set.get("scale", {}).get(n, 1.0) for n in SCATTERER_NAMES])
    if gain_set.get("perturb_db", 0.0) > 0:
        g *= 10.0 ** (rng.normal(0.0, gain_set["perturb_db"], g.size) / 20.0)
    return g


class _Job:
    """One item made ready to simulate: motion, rotated radar, backend options, signal-layer transform, and
    `finish` turning the simulation result into the stored record."""

    def __init__(self, item: WorkItem):
        self.item = item
        self.t0, self.c0 = time.perf_counter(), time.process_time()
        ss = np.random.SeedSequence(item.seed)
        gain_ss, self.clutter_ss, noise_ss = ss.spawn(3)
        self.motion = build_motion(item.motion)
        self.radar = _without_range_doppler(RadarConfig.model_validate(item.radar).rotated(item.angle_deg))
        self.gains = item_gains(item.gain_set, np.random.default_rng(gain_ss))
        seed_g = seed_scatterers(avatar_rig()).gains
        self.overall = float(np.sqrt(np.sum(self.gains ** 2) / np.sum(seed_g ** 2)))
        self.options = dict(item.backend_options)
        if item.accuracy is not None:  # simulate's own keywords: the budget chooses the backend options per item
            self.options.update(accuracy=item.accuracy, calibration=item.calibration)
        if item.backend == "points":
            self.options["gains"] = self.gains
        elif item.room is not None or item.chair != "none":  # mesh backends: the drawn room and furniture
            self.options["scene"] = item_scene(item, self.motion)  # (the points backend is free space)
        self.signal_layer = item.snr_db is not None or item.clutter is not None
        self.mesh_scale = item.backend != "points" and self.overall != 1.0  # mesh backends: the set's overall factor
        self.clutter_info: dict[str, dict] = {}
        self.noise_streams = dict(zip((link.name for link in self.radar.links), noise_ss.spawn(len(self.radar.links))))
        self.setup_s = time.perf_counter() - self.t0  # motion (cached per motion), radar, gains, scene

    def transform(self, name, iq):
        """Signal layer on the raw IQ before DSP: (mesh backends: the gain set's overall factor) -> clutter ->
        relative receiver noise."""
        item = self.item
        if self.mesh_scale:
            iq = (iq * np.float32(self.overall)).astype(np.complex64)
        p_s = signal_power(iq)
        if item.clutter is not None:
            crng = np.random.default_rng(self.clutter_ss.spawn(1)[0])
            iq, self.clutter_info[name] = add_clutter(iq, self.radar.waveform, crng, reference_power=p_s,
                                                      **item.clutter)
        if item.snr_db is not None:
            iq = add_noise(iq, item.snr_db, np.random.default_rng(self.noise_streams[name]), reference_power=p_s)
        return iq

    @property
    def iq_transform(self):
        return self.transform if self.signal_layer else None

    def finish(self, result, caught, shared_with: int = 1, setup_s: float | None = None) -> dict:
        """{"entry": index entry, "links": {link: arrays}} of the simulation `result` (`setup_s`: this item's
        share of its group's set-up time [s], default its own)."""
        item, overall = self.item, self.overall
        links = {}
        image_s = 0.0
        for name, lr in result.links.items():
            sig, iq = lr.signature, lr.iq
            if self.mesh_scale and not self.signal_layer:
                if iq is not None:
                    iq = (iq * np.float32(overall)).astype(np.complex64)
                sig = replace(sig, power=sig.power * overall ** 2)  # normalised distributions are unchanged
            if item.image_layout == "glasgow":  # the display chain of the real images (40 dB span, 8-bit colour)
                from processing.realdata.spectrogram_image import glasgow_layout
                from processing.realdata.spectrogram_image_writer import through_image

                t = time.perf_counter()
                sig = through_image(sig, glasgow_layout(float(item.motion["clip_s"])))
                image_s += time.perf_counter() - t
            arrays = signature_arrays(sig)
            if item.keep_iq:
                arrays["iq"] = np.asarray(iq, dtype=np.complex64)
            links[name] = arrays
        params = item.to_dict()
        params.update(motion_params=self.motion.params, gains=[float(x) for x in self.gains], gain_overall=overall,
                      clutter_draws=self.clutter_info or None, duration_s=float(self.motion.duration),
                      warnings=sorted({str(w.message) for w in caught}), traced_with_items=shared_with,
                      accuracy_choice=result.config.get("accuracy"), backend_stats=result.config.get("backend_stats"))
        entry = {"item_id": item.item_id, "activity": item.activity, "label": ACTIVITIES.index(item.activity),
                 "direction_deg": item.angle_deg, "direction": item.direction, "backend": item.backend,
                 "group": item.group, "source": item.source, "link_set": item.link_set,
                 "gain_set": item.gain_set["name"], "snr_db": item.snr_db, "seed": item.seed,
                 "n_time": int(next(iter(links.values()))["p_vt"].shape[1]) if links else 0,
                 "params": params, "seconds": round((time.perf_counter() - self.t0) / shared_with, 4),
                 "cpu_seconds": round((time.process_time() - self.c0) / shared_with, 4),
                 "stage_seconds": self.stages(result.timing, image_s, setup_s)}
        return {"entry": entry, "links": links}

    def stages(self, timing: dict, image_s: float, setup_s: float | None = None) -> dict[str, float]:
        """Wall time [s] of this item by stage: "setup" (motion, radar, gains, scene), "backend" (its share of a
        shared run), "synthesis" (with the signal layer), "dsp" and "image" (the Glasgow display chain); the
        shard's HDF5 write comes after the entry is made and is not included."""
        stages = {"setup": self.setup_s if setup_s is None else setup_s, "backend": timing.get("backend", 0.0),
                  "synthesis": timing.get("synthesis", 0.0), "dsp": timing.get("dsp", 0.0), "image": image_s}
        return {k: round(float(v), 4) for k, v in stages.items()}


def run_item(item: WorkItem) -> dict:
    """Simulate one item. Returns {"entry": index entry, "links": {link: arrays}} for `write_shard`."""
    from rtchannel.pipeline import simulate

    job = _Job(item)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = simulate(job.motion, job.radar, backend=item.backend, keep_iq=item.keep_iq, noise_seed=item.seed,
                          iq_transform=job.iq_transform, **job.options)
    return job.finish(result, caught)


def shared_key(item: WorkItem) -> str:
    """Items with equal keys can share one backend run (`run_shared`): same augmented motion, mesh backend,
    options and waveform; they differ in direction, link set, gain set and signal layer."""
    if item.backend == "points":  # per-item scatterer gains; the backend is ~1 % of the chain anyway
        return item.item_id
    return json.dumps([item.motion["key"], item.backend, item.backend_options, item.radar["waveform"],
                       item.keep_iq, item.room, item.accuracy, item.calibration], sort_keys=True, default=str)


def run_shared(items: list[WorkItem]) -> list[dict]:
    """Simulate items of one `shared_key` with the backend run once for all their radars
    (`rtchannel.pipeline.simulate_radars`: one skinning and BVH per frame for every direction); each record
    equals `run_item`'s. Raises if the shared run fails (the caller then runs the items one by one)."""
    from rtchannel.pipeline import simulate_radars

    if len({shared_key(it) for it in items}) != 1:
        raise InputError("run_shared needs items of one shared_key")
    jobs = [_Job(it) for it in items]
    first = items[0]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        results = simulate_radars(jobs[0].motion, [j.radar for j in jobs], first.backend, keep_iq=first.keep_iq,
                                  iq_transforms=[j.iq_transform for j in jobs],
                                  noise_seeds=[it.seed for it in items], **jobs[0].options)
    setup_s = sum(j.setup_s for j in jobs) / len(jobs)  # the first job builds the shared motion and scene
    return [j.finish(r, caught, len(jobs), setup_s) for j, r in zip(jobs, results)]
