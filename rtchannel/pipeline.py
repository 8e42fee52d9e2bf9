"""One simulation: motion -> backend paths (the channel) -> shared FMCW synthesiser -> DSP signatures, per link.

The chain in three steps, each a public function (exported by `rtchannel`): `trace` (motion and radar to
the channel, `PathSets`), `synthesise` (channel to raw IQ and signatures, `SimulationResult`; DSP settings
given here, default the radar's) and `process` (stored raw IQ to signatures: reprocessing). `simulate` is
`synthesise(trace(...))` and `simulate_radars` traces once for several radars and synthesises each; the CLI,
the dataset runner and the analysis tools all go through them. Settings flow one way: the radar's waveform
and the DSP settings go into synthesis (`processing.synthesis`), whose fast-time projection goes into the
DSP (`processing.dsp`); the fast-time model both use sits below them (`processing.fast_time`).
"""
from __future__ import annotations

import os
import time
import warnings
from dataclasses import replace

import numpy as np

from processing.dsp.config import DSPConfig, check_recording
from processing.dsp.signatures import Signature, signatures, signatures_from_projection
from processing.errors import InputError
from processing.pathset import PathSet
from rtchannel.backends import MESH_BACKENDS, backend_function, validate_options
from rtchannel.motion.pose import Motion
from rtchannel.radar import RadarConfig
from rtchannel.results import LinkResult, PathSets, SimulationResult
from rtchannel.scene.chair_fit import DEFAULT_CHAIR


def backend_paths(motion: Motion, radar: RadarConfig, backend: str = "points", **options) -> dict[str, PathSet]:
    """Path sets per link from the named backend. InputError first when a mesh backend's box room (the default
    "room" or ``room:...``) does not hold the person (`rtchannel.scene.rooms.check_inside_room`)."""
    if backend in MESH_BACKENDS:
        from rtchannel.scene.rooms import check_inside_room

        check_inside_room(motion, options.get("scene", "room"))
    return backend_function(backend)(motion, radar, **options)


def process_paths(paths: dict[str, PathSet], radar: RadarConfig, keep_iq: bool = False,
                  progress=None, timing: dict | None = None, synthesis: str = "auto",
                  oversample: int | None = None, iq_transform=None, noise_seed: int = 0) -> dict[str, LinkResult]:
    """Synthesise and compute signatures for every link's path set.

    With `radar.receiver` set, the IQ is what the ADC records (`processing.radar.receiver.receive`): scaled to
    sqrt(W) by the transmit power and chain gain, plus the receiver's thermal noise (and leakage, if
    configured), seeded by (`noise_seed`, link index) and keyed by chirp index, so chunking never
    changes it. Without a receiver the IQ stays in units of the transmit power (noiseless).
    Raw IQ is formed only when it is needed (`keep_iq`, `iq_transform`): otherwise the DSP's fast-time
    projection (range profiles of the used bins, coherent range sum) is synthesised straight from the paths
    with the same noise projected onto it (`processing.synthesis.projection`), which gives the same
    signatures up to float rounding (tests/test_synthesis_projection.py).
    `progress` is an optional callable receiving the number of chirps done after each chunk;
    `synthesis`/`oversample` choose the synthesiser (`processing.synthesis.exact.iter_synthesis`);
    `iq_transform(link name, iq [C, N]) -> iq` changes the raw IQ before DSP (signal-layer augmentation),
    and the kept IQ is the transformed one.
    """
    from threadpoolctl import threadpool_limits

    from processing.radar.receiver import noise_power_per_sample
    from processing.synthesis.exact import received_iq
    from processing.synthesis.projection import synthesise_projection

    timing = {} if timing is None else timing
    out = {}
    wf, dsp = radar.waveform, radar.dsp
    index = {link.name: i for i, link in enumerate(radar.links)}
    noise = None if radar.receiver is None else noise_power_per_sample(radar.receiver, wf.fs)
    # One BLAS thread: the synthesisers' and DSP's small matrix products (fast-time projections, N = 128)
    # gain nothing from threads, and OpenBLAS splits a product's sums by its thread count, so the same seed
    # would give other last bits on a machine with another core count (tests/test_dsp_determinism.py).
    with threadpool_limits(limits=1, user_api="blas"):
        for name, ps in paths.items():
            seed = (int(noise_seed), index.get(name, 0))
            t0 = time.perf_counter()
            if not keep_iq and iq_transform is None:
                chirp_t, proj = synthesise_projection(ps, wf, dsp, receiver=radar.receiver, seed=seed,
                                                      method=synthesis, oversample=oversample, progress=progress)
                t1 = time.perf_counter()
                sig = signatures_from_projection(proj, dsp, noise)
                iq = None
            else:
                chirp_t, iq = received_iq(ps, wf, radar.receiver, seed, method=synthesis,
                                          oversample=oversample, progress=progress)
                if iq_transform is not None:
                    iq = iq_transform(name, iq)
                t1 = time.perf_counter()
                sig = signatures(iq, wf, dsp, t0=float(chirp_t[0]) if chirp_t.size else 0.0, noise_power=noise)
            t2 = time.perf_counter()
            timing["synthesis"] = timing.get("synthesis", 0.0) + t1 - t0
            timing["dsp"] = timing.get("dsp", 0.0) + t2 - t1
            out[name] = LinkResult(signature=sig, chirp_times=chirp_t, iq=iq if keep_iq else None)
    return out


def _described(backend_options: dict) -> dict:
    """Backend options as stored in a result's config (objects by their `describe()`, no timing sinks)."""
    return {k: (v.describe() if hasattr(v, "describe") else v) for k, v in backend_options.items()
            if k not in ("timing", "stats")}


def _config(traced: dict, radar: RadarConfig, synthesis: str, noise_seed: int) -> dict:
    """Every parameter that made a result (JSON-serialisable; stored by `SimulationResult.save`): what the
    channel was traced from (`traced`: activity, motion, backend, backend_options) and how it was synthesised."""
    return {**{k: traced.get(k, d) for k, d in (("activity", ""), ("motion", {}))},
            "radar": radar.model_dump(mode="json"),
            **{k: traced.get(k, d) for k, d in (("backend", ""), ("backend_options", {}))},
            **{k: traced[k] for k in ("accuracy", "backend_stats") if k in traced},
            "synthesis": synthesis, "noise_seed": noise_seed,
            "iq_unit": "sqrt(W) at the ADC" if radar.receiver is not None else "sqrt(transmit power)"}


def _traced(motion: Motion, backend: str, options: dict, accuracy: dict | None = None,
            stats: dict | None = None) -> dict:
    out = {"activity": motion.activity, "motion": motion.params, "backend": backend,
           "backend_options": _described(options)}
    if accuracy is not None:
        out["accuracy"] = accuracy
    if stats:
        out["backend_stats"] = _json_safe(stats)
    return out


def _json_safe(value):
    """Backend statistics as JSON types (arrays to lists, unknown objects to their repr)."""
    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value if isinstance(value, (str, int, float, bool, type(None))) else repr(value)


def _budgeted(motion: Motion, radar: RadarConfig, backend: str, options: dict, accuracy, calibration):
    """(backend options, accuracy record or None, stats sink or None): the options an accuracy budget
    chooses (`rtchannel.accuracy.resolve`; explicit options win) and, for a backend that reports what its
    scene-dependent options chose (``stats``), a dict to receive it."""
    import inspect

    record = None
    if accuracy is not None:
        from rtchannel.accuracy import resolve

        options, record = resolve(accuracy, backend, radar, motion.activity, options, calibration)
    stats: dict | None = {} if "stats" in inspect.signature(backend_function(backend)).parameters else None
    return options, record, stats


def _motion_seed(motion_params: dict) -> int:
    return int(motion_params.get("seed", 0) or 0)


def _scene_for(motion: Motion, backend: str, scene, chair: str):
    """The scene the backend traces: for the mesh backends `scene` plus the chair `chair` asks for
    (`Scene.for_motion`); the points backend is free space (a warning when given another scene)."""
    from rtchannel.scene.chair_fit import CHAIR_MODES

    if chair not in CHAIR_MODES:
        raise InputError(f"chair must be one of {', '.join(CHAIR_MODES)}, got {chair!r}")
    if backend not in MESH_BACKENDS:
        if scene is not None and str(scene) != "free_space":
            warnings.warn(f"the {backend} backend is a free-space model: scene '{scene}' is not used", stacklevel=3)
        return None
    if scene is None or isinstance(scene, (str, os.PathLike)) or hasattr(scene, "with_chair_for"):
        from rtchannel.scene.spec import Scene

        try:
            return Scene.for_motion(motion, scene, chair)
        except ValueError as e:
            raise InputError(f"chair {chair}: {e}; use chair none (--chair none)") from None
    return scene  # an RTScene or a path: as given


def trace(motion: Motion, radar: RadarConfig | None = None, backend: str = "points", *, scene=None,
          chair: str = DEFAULT_CHAIR, accuracy=None, calibration=None, **backend_options) -> PathSets:
    """The channel of `motion` seen by every link of `radar`: the backend's path sets, nothing synthesised.

    Args:
        motion: the pose sequence (`rtchannel.Motion`).
        radar: antennas and links (`rtchannel.Radar`); default the seed's 2x2 system.
        backend: "points", "facets" or "sionna" (`rtchannel.BACKENDS`).
        scene: mesh backends only: a `rtchannel.Scene`, "room" (default), "free_space" or a Mitsuba XML path.
            The points backend has no scene (a warning is issued if one other than free space is given).
        chair: mesh backends: "auto" puts a chair under a sit/stand motion's seated pelvis
            (`Scene.for_motion`), "none" (the default, `rtchannel.scene.chair_fit.DEFAULT_CHAIR`, as the
            CLI's ``--chair``) adds none.
        accuracy: mesh backends: "fast", "balanced", "exact" or an EMD budget [m/s]; the cheapest calibrated
            settings within it are used (`rtchannel.accuracy`) and recorded in ``config["accuracy"]``.
        calibration: the calibration table for `accuracy` (path or `CalibrationTable`; default: the shipped
            table of the radar's carrier and range bin).
        **backend_options: the backend's options (e.g. ``lod="5k"``), checked against its typed model
            (`rtchannel.backends.options`: names, types, ranges; docs/backend_options.md); with `accuracy`,
            they override the chosen settings.

    Returns:
        `PathSets` (one `PathSet` per link name).
    """
    radar = RadarConfig() if radar is None else radar
    backend_options = validate_options(backend, backend_options)  # the backend's options model
    backend_options, record, stats = _budgeted(motion, radar, backend, backend_options, accuracy, calibration)
    if record is not None:  # the table's options are checked like the user's
        backend_options = validate_options(backend, backend_options)
    scene = _scene_for(motion, backend, scene, chair)
    if scene is not None:
        backend_options["scene"] = scene
    t0 = time.perf_counter()
    paths = backend_paths(motion, radar, backend, **backend_options, **({} if stats is None else {"stats": stats}))
    timing = {"backend": time.perf_counter() - t0}
    return PathSets(paths=paths, radar=radar, config=_traced(motion, backend, backend_options, record, stats),
                    timing=timing)


def _with_dsp(radar: RadarConfig, dsp) -> RadarConfig:
    """`radar` with the DSP settings `dsp` (a `DSPConfig` or a dict of its fields; None: the radar's own)."""
    if dsp is None:
        return radar
    return radar.model_copy(update={"dsp": dsp if isinstance(dsp, DSPConfig) else DSPConfig.model_validate(dsp)})


def synthesise(channel: PathSets, radar: RadarConfig | None = None, *, dsp: DSPConfig | dict | None = None,
               keep_iq: bool = False, progress=None, synthesis: str = "auto", iq_transform=None,
               noise_seed: int | None = None) -> SimulationResult:
    """Raw IQ (optional) and signatures of a traced channel: the shared FMCW synthesiser, receiver noise and
    DSP per link.

    Args:
        channel: `trace`'s result (or `PathSets.load`'s).
        radar: the radar to synthesise for (default the traced one). It may change the waveform's chirp
            timing, the DSP and the receiver, but not the antennas: its links must be the traced ones.
        dsp: the DSP settings (`rtchannel.DSPConfig` or a dict of its fields); default the radar's
            (``radar.dsp``). The result's ``config["radar"]["dsp"]`` records the settings used.
        keep_iq: keep the raw IQ [chirps, samples] complex64 of every link (memory: 8 bytes per sample), so
            that `process` can reprocess it.
        progress: optional callable receiving the number of chirps done after each chunk.
        synthesis: "auto", "exact" or "grid" (see `processing.synthesis.exact.iter_synthesis`).
        iq_transform: optional `f(link name, iq) -> iq` applied before the DSP (e.g. signal augmentation).
        noise_seed: seed of the receiver noise (default: the motion's seed, else 0).

    Returns:
        `SimulationResult`; its ``timing`` includes the channel's backend time [s].
    """
    radar = _with_dsp(channel.radar if radar is None else radar, dsp)
    traced = {lk.name: (tuple(lk.tx_pos), tuple(lk.rx_pos)) for lk in channel.radar.links}
    wanted = {lk.name: (tuple(lk.tx_pos), tuple(lk.rx_pos)) for lk in radar.links}
    if wanted != traced or radar.waveform.carrier_hz != channel.radar.waveform.carrier_hz:
        raise InputError("synthesise: the radar's links (names, antenna positions) and carrier must be the "
                         "traced ones; trace again for other antennas or another carrier")
    if noise_seed is None:
        noise_seed = _motion_seed(channel.config.get("motion", {}))
    timing = dict(channel.timing)
    links = process_paths(channel.paths, radar, keep_iq=keep_iq, progress=progress, timing=timing,
                          synthesis=synthesis, iq_transform=iq_transform, noise_seed=noise_seed)
    return SimulationResult(links=links, timing=timing, config=_config(channel.config, radar, synthesis, noise_seed))


def simulate(motion: Motion, radar: RadarConfig | None = None, backend: str = "points", *, scene=None,
             chair: str = DEFAULT_CHAIR, dsp: DSPConfig | dict | None = None, keep_iq: bool = False, progress=None,
             synthesis: str = "auto", iq_transform=None, noise_seed: int | None = None, accuracy=None,
             calibration=None, **backend_options) -> SimulationResult:
    """Run `motion` through a scattering backend and the shared synthesiser/DSP for every link of `radar`:
    `synthesise(trace(...))`.

    Args:
        motion: the pose sequence (`rtchannel.Motion`, e.g. `Motion.procedural("walk")`).
        radar: waveform, DSP settings and links (`rtchannel.Radar`); default the seed's 2x2 system.
        backend: "points" (the seed's 21 scatterers, free space), "facets" (every triangle of the skinned
            mesh, ray-traced visibility, wall multipath) or "sionna" (Sionna RT, the reference).
        scene: mesh backends only: a `rtchannel.Scene`, "room" (default), "free_space" or a Mitsuba XML
            path. The points backend has no scene (a warning is issued if one other than free space is given).
        chair: mesh backends: "auto" (a chair under sit/stand) or "none" (default; see `trace`).
        dsp: DSP settings (default the radar's; see `synthesise`).
        keep_iq: keep the raw IQ [chirps, samples] complex64 of every link (memory: 8 bytes per sample).
        progress: optional callable receiving the number of chirps done after each chunk.
        synthesis: "auto", "exact" or "grid" (see `processing.synthesis.exact.iter_synthesis`).
        iq_transform: optional `f(link name, iq) -> iq` applied before the DSP (e.g. signal augmentation).
        noise_seed: seed of the receiver noise (default: the motion's seed, else 0).
        accuracy: an accuracy budget ("fast", "balanced", "exact" or an EMD [m/s]; see `trace`).
        calibration: the calibration table for `accuracy` (see `trace`).
        **backend_options: the backend's options (e.g. `lod="5k"`, `walls=False` for facets).

    Returns:
        `SimulationResult` with `.signatures`, `.iq`, `.timing`, `.config`, `.save(path)`, `.plot(ax=...)`.
    """
    radar = _with_dsp(RadarConfig() if radar is None else radar, dsp)
    check_recording(motion.duration, radar.waveform, radar.dsp, len(radar.links), keep_iq)
    channel = trace(motion, radar, backend, scene=scene, chair=chair, accuracy=accuracy, calibration=calibration,
                    **backend_options)
    return synthesise(channel, keep_iq=keep_iq, progress=progress, synthesis=synthesis,
                      iq_transform=iq_transform, noise_seed=noise_seed)


def process(iq, radar: RadarConfig | None = None, dsp: DSPConfig | dict | None = None, *, t0: float = 0.0):
    """Signatures of raw IQ: the DSP alone, e.g. to reprocess stored IQ with other settings.

    With the radar and DSP settings a result was synthesised with, ``process(result.iq, radar)`` gives its
    signatures bit for bit (the receiver's noise level sets the `valid` windows, as in `synthesise`).

    Args:
        iq: raw IQ [n_chirps, n_samples] complex of one link, or {link name: IQ} (e.g. `SimulationResult.iq`
            of a result made with ``keep_iq=True``, or `SimulationResult.load(path).iq`).
        radar: the radar that recorded it (waveform, receiver); default the seed's.
        dsp: the DSP settings (`rtchannel.DSPConfig` or a dict of its fields); default the radar's.
        t0: start time [s] of the first chirp (the time axis of the signatures starts there).

    Returns:
        A `Signature` for one IQ array, or {link name: Signature} for a dict.
    """
    from processing.radar.receiver import noise_power_per_sample

    radar = _with_dsp(RadarConfig() if radar is None else radar, dsp)
    noise = None if radar.receiver is None else noise_power_per_sample(radar.receiver, radar.waveform.fs)

    def one(x) -> Signature:
        return signatures(np.asarray(x), radar.waveform, radar.dsp, t0=float(t0), noise_power=noise)

    return {name: one(x) for name, x in iq.items()} if isinstance(iq, dict) else one(iq)


def union_radar(radars) -> RadarConfig:
    """One radar holding every link of `radars` (names prefixed ``r<i>__``, each with its antennas made
    explicit), so that a backend can trace all antenna positions against one skinned body per frame."""
    first = radars[0]
    for r in radars[1:]:
        if r.waveform != first.waveform:
            raise InputError("radars traced together must share one waveform (carrier and wavelength)")
    links = []
    for i, r in enumerate(radars):
        for lk in r.links:
            tx_ant, rx_ant = r.antennas(lk)
            links.append(lk.model_copy(update={"name": f"r{i}__{lk.name}", "tx_antenna": tx_ant,
                                               "rx_antenna": rx_ant}))
    return first.model_copy(update={"links": links})


def simulate_radars(motion: Motion, radars, backend: str = "points", *, scene=None, chair: str = DEFAULT_CHAIR,
                    keep_iq: bool = False, progress=None, synthesis: str = "auto", iq_transforms=None,
                    noise_seeds=None, accuracy=None, calibration=None, **backend_options) -> list[SimulationResult]:
    """`simulate` for several radars (e.g. one motion seen from the seed's 18 directions) with the backend
    run once: `trace` of all their links together (the body is skinned and, for the mesh backends, its BVH
    built once per frame; walls stay fixed, the radars move), then `synthesise` per radar, so each result
    equals `simulate(motion, radars[i], ..., noise_seed=noise_seeds[i], iq_transform=iq_transforms[i])`.

    Args:
        motion: the pose sequence.
        radars: RadarConfigs sharing one waveform (their DSP, receivers and antennas may differ).
        backend: "points", "facets" or "sionna".
        scene: mesh backends only: as `simulate`.
        chair: mesh backends: as `simulate`.
        keep_iq: keep every link's raw IQ [chirps, samples].
        progress: optional callable receiving the number of chirps done after each chunk (all radars).
        synthesis: "auto", "exact" or "grid".
        iq_transforms: one `f(link name, iq) -> iq` (or None) per radar.
        noise_seeds: one receiver-noise seed (or None: the motion's) per radar.
        accuracy: an accuracy budget (see `trace`); chosen for the first radar's carrier and range bin (the
            radars share one waveform).
        calibration: its calibration table (see `trace`).
        **backend_options: the backend's options, as `simulate`.

    Returns:
        One `SimulationResult` per radar; the shared backend time [s] is split evenly over their ``timing``.
    """
    radars = list(radars)
    if not radars:
        return []
    n = len(radars)
    iq_transforms = [None] * n if iq_transforms is None else list(iq_transforms)
    noise_seeds = [None] * n if noise_seeds is None else list(noise_seeds)
    if len(iq_transforms) != n or len(noise_seeds) != n:
        raise InputError("iq_transforms and noise_seeds need one entry per radar")
    for r in radars:
        check_recording(motion.duration, r.waveform, r.dsp, len(r.links), keep_iq)
    channel = trace(motion, union_radar(radars), backend, scene=scene, chair=chair, accuracy=accuracy,
                    calibration=calibration, **backend_options)
    shared = {"backend": channel.timing["backend"] / n}
    results = []
    for i, r in enumerate(radars):
        mine = {lk.name: replace(channel.paths[f"r{i}__{lk.name}"], link=lk.name) for lk in r.links}
        res = synthesise(PathSets(paths=mine, radar=r, config=channel.config, timing=shared), keep_iq=keep_iq,
                         progress=progress, synthesis=synthesis, iq_transform=iq_transforms[i],
                         noise_seed=noise_seeds[i])
        res.config["traced_with_radars"] = n
        results.append(res)
    return results


__all__ = ["LinkResult", "PathSets", "SimulationResult", "backend_paths", "process", "process_paths", "simulate",
           "simulate_radars", "synthesise", "trace", "union_radar"]
