"""Consumed-only synthesis (`processing.synthesis.projection`) against full-IQ synthesis + DSP.

Both routes share the synthesis (the same spread grid for many paths, the same exact tone sum for few) and the
same keyed receiver noise, and the DSP is linear up to the clutter filter: they differ only by float rounding.
The full route stores the IQ as complex64 (relative rounding 2^-24 = 6e-8 of each sample) and range-FFTs it in
complex64 (~log2(N) x 6e-8 = 4e-7 of a chirp's largest bin); the consumed route stays in float64 until its
profiles are stored as complex64. A p(v,t) or range-distribution column is a normalised power spectrum, so a
relative amplitude error e of its dominant content moves it by about 2e in total variation (TV): ~1e-6 here,
and the brief's 1e-4 leaves two orders of magnitude for the clutter filter's amplification of residues (it
removes the slow part of the signal, leaving a smaller moving part; the test scenes keep everything moving,
so that amplification stays below ~10). Mean velocity: |sum_v v (p - q)| <= max|v| x 2 TV of the column, so
TV <= 1e-4 bounds it by 2e-4 x the largest velocity of the axis.
"""

import numpy as np
import pytest

from processing.dsp.signatures import DSPConfig
from processing.fast_time import project, range_weights
from processing.metrics.distances import pvt_tv_distance
from processing.pathset import PathSet
from processing.radar.receiver import ANCORTEK_2400T2R4, LeakageConfig, receive
from processing.synthesis.exact import iter_synthesis, iter_weighted
from processing.synthesis.grid import spread_kernel
from processing.synthesis.projection import projection_weights, synthesise_projection
from processing.radar.waveform import C0, Waveform
from rtchannel.pipeline import process_paths
from rtchannel.radar import Link, RadarConfig

WF = Waveform()  # seed radar: 24.125 GHz, 250 MHz, 0.5 ms, 128 samples
GWF = Waveform(carrier_hz=5.8e9, bandwidth_hz=400e6, pri_s=1e-3, samples_per_chirp=128)  # Glasgow-like
# 100 samples (not a power of two) at 300 kHz in a 0.4 ms chirp every 0.5 ms: fs and slope not tied to N / PRI
SWF = Waveform(samples_per_chirp=100, chirp_duration_s=0.4e-3, adc_rate_hz=300e3)
# The Glasgow script's band (3.75-11.25 m) with the scene inside it
GLASGOW = DSPConfig.glasgow()
MODES = {
    "seed-coherent": (WF, DSPConfig(), (1.0, 6.0)),
    "seed-incoherent": (WF, DSPConfig(range_sum="incoherent"), (1.0, 6.0)),
    "seed-magnitude-hann": (WF, DSPConfig(range_sum="magnitude", range_window="hann"), (1.0, 6.0)),
    "glasgow": (GWF, GLASGOW, (4.5, 10.0)),
    "short-adc-hann": (SWF, DSPConfig(range_window="hann", coherent_offset_samples=0), (1.0, 6.0)),
}
TV_MAX = 1e-4


def _random_paths(wf: Waveform, kind: str, n_paths=96, seconds=0.8, fps=60.0, seed=1, r_range=(1.0, 6.0)):
    """Moving paths (up to 0.97 v_max, a few at +-0.97 v_max exactly), some vanishing for a few frames,
    some appearing late or disappearing early. kind: "hermite" (persistent with delay rates), "spline"
    (persistent, no rates), "local" (frame-local with rates)."""
    rng = np.random.default_rng(seed)
    times = np.arange(0, seconds + 1e-9, 1 / fps)
    amp, w = rng.uniform(0, 0.03, n_paths), rng.uniform(2, 12, n_paths)
    v = rng.uniform(-1, 1, n_paths) * (0.97 * wf.v_max - amp * w)  # |radial velocity| <= 0.97 v_max
    v[:4], amp[:4] = np.array([1, -1, 1, -1]) * 0.97 * wf.v_max, 0.0
    r0 = rng.uniform(*r_range, n_paths) + np.maximum(v, 0) * seconds  # approaching paths start farther out
    r = r0 - v * times[:, None] + amp * np.sin(w * times[:, None])
    rate = 2 * (-v + amp * w * np.cos(w * times[:, None])) / C0
    gains = 1e-5 * (rng.normal(size=n_paths) + 1j * rng.normal(size=n_paths)) * (1 + 0.2 * np.cos(times[:, None]))
    gains[5:9, 10:20] = 0  # vanish for a few frames
    gains[:10, 20:30] = 0  # appear late
    gains[-8:, 30:40] = 0  # disappear early
    delays = np.where(gains != 0, 2 * r / C0, np.nan)
    rates = np.where(gains != 0, rate, np.nan)
    if kind == "local":
        return PathSet(times, delays, gains, ids=None, delay_rates=rates, link="r")
    return PathSet(times, delays, gains, ids=np.arange(n_paths), delay_rates=rates if kind == "hermite" else None,
                   link="r")


def _radar(wf, cfg, noise: bool) -> RadarConfig:
    return RadarConfig(waveform=wf, dsp=cfg, links=[Link(name="r", tx=(3.0, 0.0, 1.1))],
                       receiver=ANCORTEK_2400T2R4.receiver if noise else None)


def _assert_same_signatures(a, b, tv_max=TV_MAX):
    assert np.array_equal(a.valid, b.valid) and a.valid.any()
    assert np.array_equal(a.velocity, b.velocity) and a.carrier_hz == b.carrier_hz
    col_tv = 0.5 * np.abs(a.p_vt - b.p_vt).sum(axis=0)
    assert pvt_tv_distance(a.p_vt, b.p_vt) <= tv_max and col_tv.max() <= tv_max, col_tv.max()
    v_abs = np.abs(a.velocity).max()
    assert np.abs(a.mean_velocity - b.mean_velocity).max() <= 2 * v_abs * tv_max
    r_tv = 0.5 * np.abs(a.range_distribution - b.range_distribution).sum(axis=0)
    assert r_tv.max() <= tv_max, r_tv.max()


# paths at 0.97 v_max: the not-a-knot spline through gap-filled delays ("spline") may overshoot v_max by ~1 %
# and warn; both routes synthesise the same paths
@pytest.mark.filterwarnings("ignore::processing.synthesis.exact.NyquistWarning")
@pytest.mark.parametrize("noise", [True, False], ids=["noise", "noiseless"])
@pytest.mark.parametrize("kind", ["hermite", "spline", "local"])
@pytest.mark.parametrize("mode", list(MODES))
def test_consumed_only_equals_full_iq_route(mode, kind, noise):
    wf, cfg, r_range = MODES[mode]
    paths = {"r": _random_paths(wf, kind, r_range=r_range)}
    radar = _radar(wf, cfg, noise)
    full = process_paths(paths, radar, keep_iq=True, noise_seed=7)["r"]
    consumed = process_paths(paths, radar, noise_seed=7)["r"]
    assert consumed.iq is None and full.iq is not None
    np.testing.assert_array_equal(full.chirp_times, consumed.chirp_times)
    _assert_same_signatures(full.signature, consumed.signature)


def test_few_paths_take_the_full_route_bitwise():
    # 21 paths (the points backend's count) stay below GRID_MIN_PATHS: the exact IQ is cheap, and the
    # consumed-only route makes, receives and projects it exactly as the full route does (bitwise equal)
    paths = {"r": _random_paths(WF, "spline", n_paths=21)}
    radar = _radar(WF, DSPConfig(), True)
    a, b = process_paths(paths, radar, keep_iq=True)["r"].signature, process_paths(paths, radar)["r"].signature
    for field in ("p_vt", "mean_velocity", "range_distribution", "valid", "power", "range_doppler"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


@pytest.mark.parametrize("kind", ["hermite", "local"])
@pytest.mark.parametrize("mode", ["seed-coherent", "glasgow"])
@pytest.mark.filterwarnings("ignore::processing.synthesis.exact.NyquistWarning")  # fading paths: see below
def test_projection_within_the_grid_bound_of_the_exact_synthesis(mode, kind):
    # Per path and sample the grid's relative error is at most kernel.error_bound (synthesis_grid), so a
    # projected value through weights w is off by at most error_bound x sum_m |w_m| x sum_p |a_p(t)|; the
    # exact route is float64 throughout (its own error ~1e-13 relative). The exact route checks Nyquist at
    # every chirp, including paths fading out across a gap, whose filled delays (rate 0 at the absent frame)
    # may briefly exceed v_max: the warning is expected there.
    wf, cfg, r_range = MODES[mode]
    paths = _random_paths(wf, kind, r_range=r_range)
    weights, _, _ = projection_weights(wf, cfg)
    t, grid = map(np.concatenate, zip(*iter_weighted(paths, wf, weights, method="grid")))
    _, exact = map(np.concatenate, zip(*iter_weighted(paths, wf, weights, method="exact")))
    frame = np.clip(np.searchsorted(paths.times, t, side="right") - 1, 0, paths.n_frames - 2)
    # gains are linear between frames, so |a_p(t)| <= max(|a_p(t_k)|, |a_p(t_k+1)|); frame-local: frame k's
    # paths fading out plus frame k+1's fading in, at most the sum of both frames
    g0, g1 = np.abs(paths.gains[frame]), np.abs(paths.gains[frame + 1])
    sum_a = (g0 + g1).sum(axis=1) if kind == "local" else np.maximum(g0, g1).sum(axis=1)
    bound = spread_kernel().error_bound * np.abs(weights).sum(axis=0)[None, :] * sum_a[:, None]
    assert np.all(np.abs(grid - exact) <= bound + 1e-12 * np.abs(exact).max())
    # and the signatures agree with the exact synthesis as well (noiseless)
    a = synthesise_projection(paths, wf, cfg, method="exact")[1]
    b = synthesise_projection(paths, wf, cfg, method="grid")[1]
    from processing.dsp.signatures import signatures_from_projection
    _assert_same_signatures(signatures_from_projection(a, cfg), signatures_from_projection(b, cfg))


def test_receiver_noise_and_leakage_are_projected_exactly():
    # receive() adds s x iq + leakage + noise; the consumed route projects the same keyed draws.
    rx = ANCORTEK_2400T2R4.receiver.model_copy(update={"leakage": LeakageConfig(coupling_db=-45.0)})
    paths = _random_paths(WF, "hermite")
    cfg = DSPConfig()
    parts = []
    done = 0
    for t, iq in iter_synthesis(paths, WF):
        parts.append(receive(iq, rx, WF, seed=(3, 0), first_chirp=done))
        done += t.size
    full = project(np.concatenate(parts), WF, cfg)
    _, proj = synthesise_projection(paths, WF, cfg, receiver=rx, seed=(3, 0), chunk_chirps=300)
    scale = np.abs(full.profiles).max(axis=1, keepdims=True)
    # complex64 IQ and FFT: a few 1e-7 of the chirp's largest bin
    assert np.all(np.abs(proj.profiles - full.profiles) <= 2e-6 * scale)
    assert np.all(np.abs(proj.coherent - full.coherent) <= 2e-6 * np.abs(full.coherent).max())
    assert proj.coherent_carrier_hz == full.coherent_carrier_hz and np.array_equal(proj.range, full.range)


def test_chunking_changes_nothing():
    paths = _random_paths(WF, "hermite", seconds=0.3)
    rx = ANCORTEK_2400T2R4.receiver
    _, a = synthesise_projection(paths, WF, DSPConfig(), receiver=rx, seed=5, chunk_chirps=37)
    _, b = synthesise_projection(paths, WF, DSPConfig(), receiver=rx, seed=5, chunk_chirps=4096)
    np.testing.assert_allclose(a.profiles, b.profiles, rtol=0, atol=1e-6 * np.abs(b.profiles).max())
    # complex64 profiles; float64 coherent sum: the phasor recurrences restart at chunk edges (rounding only)
    np.testing.assert_allclose(a.coherent, b.coherent, rtol=0, atol=1e-11 * np.abs(b.coherent).max())


def test_silent_paths_give_noise_only():
    paths = _random_paths(WF, "hermite", seconds=0.3)
    paths.gains[:] = 0
    paths.delays[:] = np.nan
    rx = ANCORTEK_2400T2R4.receiver
    t, proj = synthesise_projection(paths, WF, DSPConfig(), receiver=rx, seed=2)
    n = np.concatenate([iq for _, iq in iter_synthesis(paths, WF)])
    assert not n.any()
    noise_only = project(receive(n, rx, WF, seed=2), WF, DSPConfig())
    np.testing.assert_allclose(proj.profiles, noise_only.profiles, rtol=0,
                               atol=1e-6 * np.abs(noise_only.profiles).max())
    _, quiet = synthesise_projection(paths, WF, DSPConfig())
    assert quiet.profiles.shape == (t.size, range_weights(WF, DSPConfig())[1].size) and not quiet.profiles.any()


@pytest.fixture(scope="module")
def facets_walk():
    pytest.importorskip("mitsuba")
    from rtchannel.analysis.chain_bench import exact_duration_walk
    from rtchannel.pipeline import backend_paths

    motion = exact_duration_walk(1.0)
    radar = RadarConfig()
    return backend_paths(motion, radar, "facets", lod="2k"), radar


@pytest.mark.parametrize("noise", [True, False], ids=["noise", "noiseless"])
def test_facets_walk_consumed_only_equals_full_iq(facets_walk, noise):
    paths, radar = facets_walk
    assert min(ps.n_paths for ps in paths.values()) >= 64  # the grid route
    if not noise:
        radar = radar.model_copy(update={"receiver": None})
    full = process_paths(paths, radar, keep_iq=True, noise_seed=11)
    consumed = process_paths(paths, radar, noise_seed=11)
    for name in paths:
        _assert_same_signatures(full[name].signature, consumed[name].signature)
        # the walk is real: the mean velocity is a walking speed, not noise
        assert np.abs(consumed[name].signature.mean_velocity).max() > 0.3
