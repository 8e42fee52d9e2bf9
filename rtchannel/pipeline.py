"""One simulation: motion -> backend paths -> shared FMCW synthesiser -> DSP signatures, per link.

`simulate` is the library's single entry point (also exported as `rtchannel.simulate`); the CLI, the
dataset runner and the analysis tools all go through it.
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from processing.dsp.signatures import Signature, signatures, signatures_from_projection
from processing.dsp.config import check_recording
from processing.pathset import PathSet
from rtchannel.backends import MESH_BACKENDS, RESERVED_OPTIONS, backend_function, validate_options
from rtchannel.motion.pose import Motion
from rtchannel.radar import RadarConfig
from processing.errors import InputError


@dataclass
class LinkResult:
    """Raw IQ (if kept) and signatures of one link; chirp start times [s]."""

    signature: Signature
    chirp_times: np.ndarray
    iq: np.ndarray | None = None


@dataclass
class SimulationResult:
    """Per-link results, the wall-clock split [s] between backend, synthesis and DSP, and every
    parameter that produced them (`config`, JSON-serialisable; stored by `save`)."""

    links: dict[str, LinkResult]
    timing: dict[str, float] = field(default_factory=dict)
    config: dict = field(default_factory=dict)

    @property
    def signatures(self) -> dict[str, Signature]:
        """{link name: Signature} (p(v,t), mean velocity, range distribution, ...)."""
        return {name: r.signature for name, r in self.links.items()}

    @property
    def iq(self) -> dict[str, np.ndarray]:
        """{link name: raw IQ [chirps, samples] complex64} of the links whose IQ was kept (`keep_iq`)."""
        return {name: r.iq for name, r in self.links.items() if r.iq is not None}

    def save(self, path: str | Path, seed: int | None = None) -> Path:
        """Write `signature.h5` (DESIGN.md layout, atomically) with the parameters that made it; the raw IQ
        is stored for links that kept it.

        Args:
            path: the file to write.
            seed: the root attribute ``seed`` (default: the motion's seed).

        Returns:
            `path`.
        """
        from processing.io.signature_file import write_signature_file

        cfg = self.config
        radar = cfg.get("radar", {})
        links = {lk["name"]: lk for lk in radar.get("links", [])}
        link_attrs = {n: {"tx": np.asarray(lk["tx"], float),
                          "rx": np.asarray(lk["tx"] if lk.get("rx") is None else lk["rx"], float)}
                      for n, lk in links.items()}
        motion = cfg.get("motion", {})
        return write_signature_file(
            path, self.signatures, activity=cfg.get("activity", ""), backend=cfg.get("backend", ""),
            seed=int(motion.get("seed", 0) if seed is None else seed),
            direction_deg=float(radar.get("orientation_deg", 0.0)), config=cfg, link_attrs=link_attrs,
            iq=self.iq or None)

    def plot(self, out_dir: str | Path, title: str | None = None) -> list[Path]:
        """PNG figures (p(v,t), mean velocity, range-time) into `out_dir`; returns their paths.

        Args:
            out_dir: folder to write into.
            title: figure title (default: activity, backend and radar orientation).
        """
        from processing.plots.signatures import plot_all

        if title is None:
            c = self.config
            title = f"{c.get('activity', '')} ({c.get('backend', '')}, {c.get('radar', {}).get('orientation_deg', 0):g} deg)"
        return plot_all(self.signatures, Path(out_dir), title=title)


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
    return {**{k: traced.get(k, d) for k, d in (("activity", ""), ("motion", {}))}, "radar": radar.model_dump(mode="json"),
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
    stats = {} if "stats" in inspect.signature(backend_function(backend)).parameters else None
    return options, record, stats


def _motion_seed(motion_params: dict) -> int:
    return int(motion_params.get("seed", 0) or 0)


@dataclass
class PathSets:
    """The channel between motion and radar: one `PathSet` per link (delays [s], complex gains with
    |a|^2 = P_r/P_t, path ids, delay rates [s/s] at frame times [s]), the radar whose links they belong to,
    and what made them (`config`: motion, backend, options; `timing` [s]). `trace` makes it, `synthesise`
    turns it into raw IQ and signatures, so a channel can be stored, inspected or synthesised for several
    waveforms and DSP settings of the same antennas."""

    paths: dict[str, PathSet]
    radar: RadarConfig
    config: dict = field(default_factory=dict)
    timing: dict[str, float] = field(default_factory=dict)

    def __getitem__(self, link: str) -> PathSet:
        return self.paths[link]

    def __iter__(self):
        return iter(self.paths)

    def __len__(self) -> int:
        return len(self.paths)


def trace(motion: Motion, radar: RadarConfig | None = None, backend: str = "points", *, scene=None,
          accuracy=None, calibration=None, **backend_options) -> PathSets:
    """The channel of `motion` seen by every link of `radar`: the backend's path sets, nothing synthesised.

    Args:
        motion: the pose sequence (`rtchannel.Motion`).
        radar: antennas and links (`rtchannel.Radar`); default the seed's 2x2 system.
        backend: "points", "facets" or "sionna" (`rtchannel.BACKENDS`).
        scene: mesh backends only: a `rtchannel.Scene`, "room" (default), "free_space" or a Mitsuba XML path.
        accuracy: mesh backends: "fast", "balanced", "exact" or an EMD budget [m/s]; the cheapest calibrated
            settings within it are used (`rtchannel.accuracy`) and recorded in ``config["accuracy"]``.
        calibration: the calibration table for `accuracy` (path or `CalibrationTable`; default: the shipped
            table of the radar's carrier and range bin).
        **backend_options: the backend's options, checked by name and type (e.g. ``lod="5k"``); with
            `accuracy`, they override the chosen settings.

    Returns:
        `PathSets` (one `PathSet` per link name).
    """
    radar = RadarConfig() if radar is None else radar
    validate_options(backend, backend_options, reserved=RESERVED_OPTIONS + ("scene",))
    backend_options, record, stats = _budgeted(motion, radar, backend, backend_options, accuracy, calibration)
    if record is not None:  # the table's options are checked like the user's
        validate_options(backend, backend_options, reserved=RESERVED_OPTIONS + ("scene",))
    if scene is not None:
        if backend in MESH_BACKENDS:
            backend_options["scene"] = scene
        elif str(scene) != "free_space":
            warnings.warn(f"the {backend} backend is a free-space model: scene '{scene}' is not used",
                          stacklevel=2)
    t0 = time.perf_counter()
    paths = backend_paths(motion, radar, backend, **backend_options, **({} if stats is None else {"stats": stats}))
    timing = {"backend": time.perf_counter() - t0}
    return PathSets(paths=paths, radar=radar, config=_traced(motion, backend, backend_options, record, stats),
                    timing=timing)


def synthesise(channel: PathSets, radar: RadarConfig | None = None, *, keep_iq: bool = False, progress=None,
               synthesis: str = "auto", iq_transform=None, noise_seed: int | None = None) -> SimulationResult:
    """Raw IQ (optional) and signatures of a traced channel: the shared FMCW synthesiser, receiver noise and
    DSP per link.

    Args:
        channel: `trace`'s result.
        radar: the radar to synthesise for (default the traced one). It may change the waveform's chirp
            timing, the DSP and the receiver, but not the antennas: its links must be the traced ones.
        keep_iq, progress, synthesis, iq_transform: as `simulate`.
        noise_seed: seed of the receiver noise (default: the motion's seed, else 0).

    Returns:
        `SimulationResult`; its ``timing`` includes the channel's backend time.
    """
    from processing.errors import InputError

    radar = channel.radar if radar is None else radar
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
             keep_iq: bool = False, progress=None, synthesis: str = "auto", iq_transform=None,
             noise_seed: int | None = None, accuracy=None, calibration=None, **backend_options) -> SimulationResult:
    """Run `motion` through a scattering backend and the shared synthesiser/DSP for every link of `radar`:
    `synthesise(trace(...))`.

    Args:
        motion: the pose sequence (`rtchannel.Motion`, e.g. `Motion.procedural("walk")`).
        radar: waveform, DSP settings and links (`rtchannel.Radar`); default the seed's 2x2 system.
        backend: "points" (the seed's 21 scatterers, free space), "facets" (every triangle of the skinned
            mesh, ray-traced visibility, wall multipath) or "sionna" (Sionna RT, the reference).
        scene: mesh backends only: a `rtchannel.Scene`, "room" (default), "free_space" or a Mitsuba XML
            path. The points backend has no scene (a warning is issued if one other than free space is given).
        keep_iq: keep the raw IQ [chirps, samples] of every link (memory: 8 bytes per sample).
        progress: optional callable receiving the number of chirps done after each chunk.
        synthesis: "auto", "exact" or "grid" (see `processing.synthesis.exact.iter_synthesis`).
        iq_transform: optional `f(link name, iq) -> iq` applied before the DSP (e.g. signal augmentation).
        noise_seed: seed of the receiver noise (default: the motion's seed, else 0).
        accuracy, calibration: an accuracy budget and its calibration table (see `trace`).
        **backend_options: the backend's options (e.g. `lod="5k"`, `walls=False` for facets).

    Returns:
        `SimulationResult` with `.signatures`, `.iq`, `.timing`, `.config`, `.save(path)`, `.plot(dir)`.
    """
    radar = RadarConfig() if radar is None else radar
    check_recording(motion.duration, radar.waveform, radar.dsp, len(radar.links), keep_iq)
    channel = trace(motion, radar, backend, scene=scene, accuracy=accuracy, calibration=calibration,
                    **backend_options)
    return synthesise(channel, keep_iq=keep_iq, progress=progress, synthesis=synthesis,
                      iq_transform=iq_transform, noise_seed=noise_seed)


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


def simulate_radars(motion: Motion, radars, backend: str = "points", *, scene=None, keep_iq: bool = False,
                    synthesis: str = "auto", iq_transforms=None, noise_seeds=None, accuracy=None, calibration=None,
                    **backend_options) -> list[SimulationResult]:
    """`simulate` for several radars (e.g. one motion seen from the seed's 18 directions) with the backend
    run once: the body is skinned (and, for the mesh backends, its BVH built) once per frame and every
    antenna of every radar is traced against it; walls stay fixed, the radars move. Synthesis, receiver
    noise and DSP then run per radar exactly as `simulate` does, so each result equals
    `simulate(motion, radars[i], ..., noise_seed=noise_seeds[i], iq_transform=iq_transforms[i])`.

    Args:
        motion: the pose sequence.
        radars: RadarConfigs sharing one waveform (their DSP, receivers and antennas may differ).
        backend: "points", "facets" or "sionna".
        scene: mesh backends only: as `simulate`.
        keep_iq: keep every link's raw IQ [chirps, samples].
        synthesis: "auto", "exact" or "grid".
        iq_transforms, noise_seeds: one per radar (default None / the motion's seed).
        accuracy, calibration: an accuracy budget and its calibration table (see `trace`); chosen for the
            first radar's carrier and range bin (the radars share one waveform).
        **backend_options: the backend's options, as `simulate`.

    Returns:
        One `SimulationResult` per radar; the shared backend time is split evenly over their ``timing``.
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
    validate_options(backend, backend_options, reserved=RESERVED_OPTIONS + ("scene",))
    union = union_radar(radars)
    backend_options, record, stats = _budgeted(motion, union, backend, backend_options, accuracy, calibration)
    if record is not None:  # the table's options are checked like the user's
        validate_options(backend, backend_options, reserved=RESERVED_OPTIONS + ("scene",))
    if scene is not None and backend in MESH_BACKENDS:
        backend_options["scene"] = scene
    t0 = time.perf_counter()
    paths = backend_paths(motion, union, backend, **backend_options, **({} if stats is None else {"stats": stats}))
    shared = (time.perf_counter() - t0) / n
    traced = _traced(motion, backend, backend_options, record, stats)
    results = []
    for i, r in enumerate(radars):
        mine = {lk.name: replace(paths[f"r{i}__{lk.name}"], link=lk.name) for lk in r.links}
        seed = _motion_seed(motion.params) if noise_seeds[i] is None else noise_seeds[i]
        timing = {"backend": shared}
        links = process_paths(mine, r, keep_iq=keep_iq, timing=timing, synthesis=synthesis,
                              iq_transform=iq_transforms[i], noise_seed=seed)
        config = {**_config(traced, r, synthesis, seed), "traced_with_radars": n}
        results.append(SimulationResult(links=links, timing=timing, config=config))
    return results
