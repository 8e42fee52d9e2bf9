"""One simulation: motion -> backend paths -> shared FMCW synthesiser -> DSP signatures, per link."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from processing.dsp import Signature, signatures
from processing.pathset import PathSet
from processing.synthesis import iter_synthesis
from rtchannel.radar import RadarConfig
from rtchannel.skeleton import Motion

BACKENDS = ("points", "facets", "sionna")


@dataclass
class LinkResult:
    """Raw IQ (if kept) and signatures of one link."""

    signature: Signature
    chirp_times: np.ndarray
    iq: np.ndarray | None = None


@dataclass
class SimulationResult:
    """Per-link results plus wall-clock split [s] between backend, synthesis and DSP."""

    links: dict[str, LinkResult]
    timing: dict[str, float] = field(default_factory=dict)


def backend_function(backend: str):
    """The path-set function of the named backend (imported on demand: the mesh backends load Mitsuba)."""
    if backend == "points":
        from rtchannel.backends.points import point_paths

        return point_paths
    if backend == "facets":
        from rtchannel.backends.facets import facet_paths

        return facet_paths
    if backend == "sionna":
        from rtchannel.backends.sionna_rt import sionna_paths

        return sionna_paths
    raise ValueError(f"unknown backend '{backend}'; choose one of {', '.join(BACKENDS)}")


def backend_paths(motion: Motion, radar: RadarConfig, backend: str = "points", **options) -> dict[str, PathSet]:
    """Path sets per link from the named backend."""
    return backend_function(backend)(motion, radar, **options)


def process_paths(paths: dict[str, PathSet], radar: RadarConfig, keep_iq: bool = False,
                  progress=None, timing: dict | None = None, synthesis: str = "auto",
                  oversample: int = 8, iq_transform=None) -> dict[str, LinkResult]:
    """Synthesise raw IQ and compute signatures for every link's path set.

    `progress` is an optional callable receiving the number of chirps done after each chunk;
    `synthesis`/`oversample` choose the synthesiser (`processing.synthesis.iter_synthesis`);
    `iq_transform(link name, iq [C, N]) -> iq` changes the raw IQ before DSP (receiver noise, clutter),
    and the kept IQ is the transformed one.
    """
    timing = {} if timing is None else timing
    out = {}
    wf, dsp = radar.waveform, radar.dsp
    for name, ps in paths.items():
        t0 = time.perf_counter()
        t_parts, iq_parts = [], []
        for t, iq in iter_synthesis(ps, wf, method=synthesis, oversample=oversample):
            t_parts.append(t)
            iq_parts.append(iq)
            if progress is not None:
                progress(t.size)
        chirp_t = np.concatenate(t_parts) if t_parts else np.zeros(0)
        iq = np.concatenate(iq_parts) if iq_parts else np.zeros((0, wf.samples_per_chirp), np.complex64)
        if iq_transform is not None:
            iq = iq_transform(name, iq)
        t1 = time.perf_counter()
        sig = signatures(iq, wf, dsp, t0=float(chirp_t[0]) if chirp_t.size else 0.0)
        t2 = time.perf_counter()
        timing["synthesis"] = timing.get("synthesis", 0.0) + t1 - t0
        timing["dsp"] = timing.get("dsp", 0.0) + t2 - t1
        out[name] = LinkResult(signature=sig, chirp_times=chirp_t, iq=iq if keep_iq else None)
    return out


def simulate(motion: Motion, radar: RadarConfig, backend: str = "points", keep_iq: bool = False,
             progress=None, synthesis: str = "auto", iq_transform=None, **backend_options) -> SimulationResult:
    """Run `motion` through `backend` and the shared synthesiser/DSP for every link of `radar`.

    `backend_options` go to the backend (e.g. `lod`, `scene`, `walls` for the mesh backends);
    `iq_transform` see `process_paths`.
    """
    timing: dict[str, float] = {}
    t0 = time.perf_counter()
    paths = backend_paths(motion, radar, backend, **backend_options)
    timing["backend"] = time.perf_counter() - t0
    links = process_paths(paths, radar, keep_iq=keep_iq, progress=progress, timing=timing, synthesis=synthesis,
                          iq_transform=iq_transform)
    return SimulationResult(links=links, timing=timing)
