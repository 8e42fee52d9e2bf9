"""Consumed-only synthesis: the DSP's fast-time projection of one link straight from its paths, no raw IQ.

The DSP reads a chirp only through linear maps of its N samples (`processing.fast_time`): the range profile of
the used bins, iq @ W [N, R], and for the coherent range sum (seed eq. 6) one slow-time value, iq @ h [N]. The
gridded synthesiser (`processing.synthesis.grid`) makes a chirp's IQ as a fixed linear map of its spread grid
b [M + w + 1] (fold, M-point inverse FFT, division by the kernel's transform), so

    iq @ [W h] = b @ P,   P = `synthesis_grid.projection_matrix([W h])`   [M + w + 1, R + 1],

applied by the spreading kernel itself over the few tens of cells the paths touch (at most (M + w)(R + 1)
complex multiply-adds per chirp, 521 x 19 at the seed's settings), instead of an N-sample IQ row, its inverse
FFT, complex64 copy, receiver scaling and range FFT. A path of unit gain at delay tau contributes exactly
`fast_time.path_response([W h], tau)` up to the grid's error: with |e| <= `error_bound` per path and
sample (1.8e-6 at the defaults), a range bin is off by at most error_bound x sum_m |W_mk| x sum_p |a_p|
= error_bound x sum_p |a_p| (W's taper is normalised by its sum) and the coherent value by
error_bound x sum_m |h_m| x sum_p |a_p|. With few paths (the exact route of `synthesis.iter_synthesis`, e.g.
the points backend) the IQ is cheap: it is synthesised, received and projected exactly as in the full route,
so the result is bitwise the full route's.

Receiver (`processing.radar.receiver.receive`): the ADC records s x (synthesiser IQ) + leakage + thermal noise,
s = sqrt(P_t G_chain). All three terms go through the same linear maps, so the projection of what the ADC
records is s (b @ P) + project(leakage + noise): the noise and leakage of the same chirps are drawn exactly
as `receive` draws them (same seed, keyed by chirp index, so chunking never changes them) and projected by
the DSP's own `fast_time.project` (complex64 range FFT, float64 coherent sum; 25x cheaper than the weights
as a matrix). That equals the full route's projection up to float rounding: the full route rounds s x iq
to complex64 before adding the noise and range-FFTs the sum in complex64 (relative ~4e-7 of the largest
bin of a chirp); here the paths' part stays in float64 and the noise's FFT rounds only the noise.
"""
from __future__ import annotations

import math

import numpy as np

from processing.fast_time import Projection, coherent_weights, doppler_band, project, projector, range_weights
from processing.pathset import PathSet
from processing.synthesis.exact import chirp_times, iter_received, iter_weighted, uses_grid
from processing.radar.waveform import Waveform


def projection_weights(wf: Waveform, cfg) -> tuple[np.ndarray, np.ndarray, float]:
    """(weights [N, R (+1)] complex128, range [R] m, coherent carrier [Hz]) of a `DSPConfig`: the range FFT of
    the used bins (`fast_time.range_weights`) and, for range_sum "coherent", the coherent-sum weights h as the
    last column (`fast_time.coherent_weights`); the carrier is the waveform's otherwise."""
    w, rng = range_weights(wf, cfg)
    doppler_band(rng, wf, cfg)  # the DSP's own check that the Doppler band is not empty
    if cfg.range_sum != "coherent":
        return w, rng, wf.carrier_hz
    h, f_eff = coherent_weights(wf, cfg)
    return np.concatenate([w, h[:, None]], axis=1), rng, f_eff


def synthesise_projection(paths: PathSet, wf: Waveform, cfg, receiver=None, seed=0, method: str = "auto",
                          chunk_chirps: int = 1024, oversample: int | None = None,
                          progress=None) -> tuple[np.ndarray, Projection]:
    """(chirp start times [C] s, `Projection`) of one link, as `fast_time.project` would make it from the IQ
    of `synthesis.iter_synthesis` passed through `receiver.receive(iq, receiver, wf, seed, first_chirp)`.

    Args:
        paths: the link's paths. wf: waveform. cfg: `DSPConfig` (used bins, taper, range sum).
        receiver: `ReceiverConfig` (IQ in sqrt(W) at the ADC with its noise and leakage) or None (noiseless,
            units of the transmit power).
        seed: the receiver noise seed, as for `receive` (e.g. (simulation seed, link index)).
        method, chunk_chirps, oversample: as `synthesis.iter_synthesis`.
        progress: optional callable receiving the number of chirps done after each chunk.
    """
    from processing.radar.receiver import leakage_iq, receiver_noise, transmit_power_w

    if not uses_grid(paths, method):
        return _exact_projection(paths, wf, cfg, receiver, seed, chunk_chirps, progress)
    weights, rng, f_eff = projection_weights(wf, cfg)
    project_extra = projector(wf, cfg)
    n_range = rng.size
    coherent = cfg.range_sum == "coherent"
    # receiver.scale_to_receiver's factor sqrt(P_t G_chain), kept in float64
    scale = 1.0 if receiver is None else math.sqrt(transmit_power_w(receiver) * 10.0 ** (receiver.chain_gain_db / 10))
    t_parts, prof_parts = [], []
    coh_parts: list[np.ndarray] = []
    done = 0
    for t, val in iter_weighted(paths, wf, weights, chunk_chirps=chunk_chirps, method=method,
                                oversample=oversample):
        prof = val[:, :n_range] * scale
        coh = val[:, n_range] * scale if coherent else None
        if receiver is not None:
            extra = receiver_noise(receiver, wf.fs, wf.samples_per_chirp, seed, done, t.size)
            if receiver.leakage is not None:
                extra += leakage_iq(receiver, wf, seed, done, t.size)
            p_extra = project_extra(extra)
            prof += p_extra.profiles
            if coherent:
                coh += p_extra.coherent
        done += t.size
        t_parts.append(t)
        prof_parts.append(prof.astype(np.complex64))
        if coh is not None:
            coh_parts.append(coh)
        if progress is not None:
            progress(t.size)
    if not t_parts:
        t_all = chirp_times(paths.times[0], paths.times[-1], wf.pri_s)[:0]
        return t_all, Projection(np.zeros((0, n_range), np.complex64), rng, wf,
                                 np.zeros(0, np.complex128) if coherent else None, f_eff, 0.0)
    t_all = np.concatenate(t_parts)
    proj = Projection(profiles=np.concatenate(prof_parts), range=rng, waveform=wf,
                      coherent=np.concatenate(coh_parts) if coherent else None, coherent_carrier_hz=f_eff,
                      t0=float(t_all[0]))
    return t_all, proj


def _exact_projection(paths: PathSet, wf: Waveform, cfg, receiver, seed, chunk_chirps: int,
                      progress) -> tuple[np.ndarray, Projection]:
    """The exact route: every chunk's received IQ projected as soon as it is made (`iter_received`'s threads),
    row by row as `project` does the whole IQ, so the result is bitwise the full route's."""
    t_parts, parts = [], []
    for t, proj in iter_received(paths, wf, receiver, seed, chunk_chirps, method="exact",
                                 finish=projector(wf, cfg)):
        t_parts.append(t)
        parts.append(proj)
        if progress is not None:
            progress(t.size)
    if not parts:
        t_all = chirp_times(paths.times[0], paths.times[-1], wf.pri_s)[:0]
        return t_all, project(np.zeros((0, wf.samples_per_chirp), np.complex64), wf, cfg)
    t_all = np.concatenate(t_parts)
    coherent = None if parts[0].coherent is None else np.concatenate([p.coherent for p in parts])
    return t_all, Projection(profiles=np.concatenate([p.profiles for p in parts]), range=parts[0].range, waveform=wf,
                             coherent=coherent, coherent_carrier_hz=parts[0].coherent_carrier_hz,
                             t0=float(t_all[0]))
