"""Run one work item: build the motion (motion layer), the rotated radar (physical layer), the scatterer gains,
simulate with the plan's backend, the signal layer (clutter, receiver noise) applied to the raw IQ before DSP.

Warm state: motions and loaded motion files are cached per process (items are sorted so that all
directions and gain sets of one motion run back to back on one worker), and backends keep their own
scene/kernel caches at module level, so a Dask worker pays those costs once.
"""
from __future__ import annotations

import json
import time
import warnings
from collections import OrderedDict
from dataclasses import replace

import numpy as np

from processing.dataset_store import ACTIVITIES, signature_arrays
from processing.signal_augment import add_clutter, add_noise, signal_power
from rtchannel.dataset.plan import WorkItem
from rtchannel.radar import RadarConfig
from rtchannel.body.scatterers import SCATTERER_NAMES, seed_scatterers
from rtchannel.body.skeleton import Motion, avatar_rig

_CACHE_SIZE = 8
_MOTIONS: OrderedDict[str, Motion] = OrderedDict()
_FILES: OrderedDict[str, Motion] = OrderedDict()


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
        from rtchannel.motion.compose import back_and_forth, fit_clip

        motion = augment(_base_motion(m), time_scale=m["time_scale"], mirror=m["mirror"], trim=m.get("trim"),
                         heading_deg=m["heading_deg"], start=None if m["start"] == "auto" else m["start"])
        if m.get("walk_legs", 1) > 1:
            motion = back_and_forth(motion, m["walk_legs"], m["walk_turn_s"])
        if m["start"] == "auto" and m["activity"] == "walk":
            # a walk centred on the origin: it passes the room centre whatever its heading and length
            mid = 0.5 * (motion.positions[0, 0, :2] + motion.positions[-1, 0, :2])
            motion = motion.transformed(0.0, (-mid[0], -mid[1], 0.0))
        if m.get("clip_s") is not None:
            motion = fit_clip(motion, m["clip_s"], m["clip_lead"])
        return motion
    return _cached(_MOTIONS, m["key"], make)


def item_gains(gain_set: dict, rng: np.random.Generator) -> np.ndarray:
    """Amplitude gains [21] of the seed's scatterers for a gain set: seed gains x scale x log-normal factor."""
    g = seed_scatterers(avatar_rig()).gains.astype(float).copy()
    g *= np.array([gain_set.get("scale", {}).get(n, 1.0) for n in SCATTERER_NAMES])
    if gain_set.get("perturb_db", 0.0) > 0:
        g *= 10.0 ** (rng.normal(0.0, gain_set["perturb_db"], g.size) / 20.0)
    return g


def run_item(item: WorkItem) -> dict:
    """Simulate one item. Returns {"entry": index entry, "links": {link: arrays}} for `write_shard`."""
    t0, c0 = time.perf_counter(), time.process_time()
    ss = np.random.SeedSequence(item.seed)
    gain_ss, clutter_ss, noise_ss = ss.spawn(3)
    motion = build_motion(item.motion)
    radar = RadarConfig.model_validate(item.radar).rotated(item.angle_deg)
    gains = item_gains(item.gain_set, np.random.default_rng(gain_ss))
    seed_g = seed_scatterers(avatar_rig()).gains
    overall = float(np.sqrt(np.sum(gains ** 2) / np.sum(seed_g ** 2)))
    options = dict(item.backend_options)
    if item.backend == "points":
        options["gains"] = gains
    signal_layer = item.snr_db is not None or item.clutter is not None
    mesh_scale = item.backend != "points" and overall != 1.0  # mesh backends: the set's overall factor

    from rtchannel.pipeline import simulate

    links, clutter_info = {}, {}
    noise_streams = dict(zip((link.name for link in radar.links), noise_ss.spawn(len(radar.links))))

    def signal_layer_on_iq(name, iq):
        # raw IQ -> (mesh backends: the gain set's overall factor) -> clutter -> receiver noise, before DSP
        if mesh_scale:
            iq = (iq * np.float32(overall)).astype(np.complex64)
        p_s = signal_power(iq)
        if item.clutter is not None:
            crng = np.random.default_rng(clutter_ss.spawn(1)[0])
            iq, clutter_info[name] = add_clutter(iq, radar.waveform, crng, reference_power=p_s, **item.clutter)
        if item.snr_db is not None:
            iq = add_noise(iq, item.snr_db, np.random.default_rng(noise_streams[name]), reference_power=p_s)
        return iq

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if item.backend != "points" and item.chair != "none":  # the points backend is free space
            from rtchannel.scene.chair_fit import scene_for

            options["scene"] = scene_for(motion, options.get("scene"), item.chair)
        result = simulate(motion, radar, backend=item.backend, keep_iq=item.keep_iq, noise_seed=item.seed,
                          iq_transform=signal_layer_on_iq if signal_layer else None, **options)
    for name, lr in result.links.items():
        sig, iq = lr.signature, lr.iq
        if mesh_scale and not signal_layer:
            if iq is not None:
                iq = (iq * np.float32(overall)).astype(np.complex64)
            sig = replace(sig, power=sig.power * overall ** 2)  # normalised distributions are unchanged
        if item.image_layout == "glasgow":  # the display chain of the real images (40 dB span, 8-bit colour)
            from processing.spectrogram_image import glasgow_layout
            from processing.spectrogram_image_writer import through_image

            sig = through_image(sig, glasgow_layout(float(item.motion["clip_s"])))
        arrays = signature_arrays(sig)
        if item.keep_iq:
            arrays["iq"] = np.asarray(iq, dtype=np.complex64)
        links[name] = arrays
    params = item.to_dict()
    params.update(motion_params=motion.params, gains=[float(x) for x in gains], gain_overall=overall,
                  clutter_draws=clutter_info or None, duration_s=float(motion.duration),
                  warnings=sorted({str(w.message) for w in caught}))
    entry = {"item_id": item.item_id, "activity": item.activity, "label": ACTIVITIES.index(item.activity),
             "direction_deg": item.angle_deg, "direction": item.direction, "backend": item.backend,
             "group": item.group, "source": item.source, "link_set": item.link_set,
             "gain_set": item.gain_set["name"], "snr_db": item.snr_db, "seed": item.seed,
             "n_time": int(next(iter(links.values()))["p_vt"].shape[1]) if links else 0,
             "params": params, "seconds": round(time.perf_counter() - t0, 4),
             "cpu_seconds": round(time.process_time() - c0, 4)}
    return {"entry": entry, "links": links}
