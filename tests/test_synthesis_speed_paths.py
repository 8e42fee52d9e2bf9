"""The fast paths of issue 26 (exact tone sum, receiver noise, fast-time projection, moving-average MTI) keep the
physics and the reproducibility contract.

- Tones: the table-plus-Taylor phasors and the [paths, chirps] recurrence are float64-accurate (~1e-13 of the
  summed amplitudes after 128 steps, against complex64's 6e-8 in the stored IQ).
- Determinism: a chirp's bytes depend on that chirp only, so any chunking and any number of threads give the
  same IQ and the same projection, bit for bit (a one-chirp chunk included: numpy would sum its paths in
  another order).
- Noise: one 64-bit word per sample, Box-Muller in polar form. |z|^2 = -P ln u is exponential with mean P for u
  uniform on (0, 1] (the law of a circular complex Gaussian's power) and the phase is uniform and independent of
  it, so I and Q are independent N(0, P/2). The checks below use 2^21 samples of a fixed stream: each moment's
  spread is ~1/sqrt(2^21) = 7e-4 relative, and the tolerances are ~6 of those spreads.
- DSP: the moving-average MTI gives the bytes of the former gather formula; the chunked projection gives the
  bytes of the whole one.
"""
import numpy as np
import pytest
from scipy import stats

from processing.fast_time import project, projector, range_weights
from processing.dsp.mti import _subtract_moving_average
from processing.dsp.signatures import DSPConfig
from processing.pathset import PathSet
from processing.radar.receiver import ANCORTEK_2400T2R4, LeakageConfig, gaussian_from_words, receive, receive_inplace
from processing.radar.waveform import C0, Waveform
from processing.synthesis import exact
from processing.synthesis.projection import synthesise_projection

WF = Waveform()  # seed radar: 128 samples, PRI 0.5 ms
RX = ANCORTEK_2400T2R4.receiver


def _walkers(n_paths=21, seconds=0.6, fps=60.0, seed=3):
    """Persistent paths (the points backend's count) moving at up to 3 m/s with delay rates; 0.6 s at the
    seed PRI is 1201 chirps."""
    rng = np.random.default_rng(seed)
    times = np.arange(0, seconds + 1e-9, 1 / fps)
    r0, v = rng.uniform(1.0, 6.0, n_paths), rng.uniform(-3.0, 3.0, n_paths)
    r = r0 + v * times[:, None] + 0.02 * np.sin(7 * times[:, None] + r0)
    rate = 2 * (v + 0.14 * np.cos(7 * times[:, None] + r0)) / C0
    gains = 1e-4 * (rng.normal(size=n_paths) + 1j * rng.normal(size=n_paths)) * (1 + 0.1 * times[:, None])
    gains[:8, 3] = 0  # one path appears late
    return PathSet(times, 2 * r / C0, gains, ids=np.arange(n_paths), delay_rates=rate, link="r")


def test_cis_is_float64_accurate():
    x = np.random.default_rng(0).uniform(-1.0, 2.0, 200_000)
    assert np.abs(exact._cis(x) - np.exp(2j * np.pi * x)).max() < 3e-15


def test_tone_sum_matches_direct_exponentials():
    paths = _walkers()
    evaluate = exact._PersistentPaths(paths)
    t = exact.chirp_times(paths.times[0], paths.times[-1], WF.pri_s)[::37]
    delays, gains, rates = evaluate(t)
    got = exact.tone_sum(delays, gains, WF, rates)
    m = np.arange(WF.samples_per_chirp)
    # reference phases in cycles, the carrier's reduced first (2 pi f_s tau ~ 4e3 rad would cost 1e-12 rad)
    x0 = WF.start_hz * delays
    cycles = (x0 - np.floor(x0))[:, :, None] + (WF.slope / WF.fs) * (
        delays + exact.coupling_s(WF) * rates)[:, :, None] * m
    ref = (gains[:, :, None] * np.exp(2j * np.pi * cycles)).sum(axis=1)
    assert np.abs(got - ref).max() <= 1e-13 * np.abs(gains).sum(axis=1).max()


@pytest.mark.parametrize("threads", [1, 2])
def test_exact_route_same_bytes_for_any_chunking_and_threads(monkeypatch, threads):
    paths = _walkers()
    cfg = DSPConfig()
    monkeypatch.setattr(exact, "_threads", lambda: 1)
    t_ref, iq_ref = exact.received_iq(paths, WF, RX, (4, 1), chunk_chirps=1024)
    proj_ref = synthesise_projection(paths, WF, cfg, receiver=RX, seed=(4, 1), chunk_chirps=1024)[1]
    assert t_ref.size == 1201
    monkeypatch.setattr(exact, "_threads", lambda: threads)
    for chunk in (300, 7, 4096):  # 300: the last chunk is a single chirp
        t, iq = exact.received_iq(paths, WF, RX, (4, 1), chunk_chirps=chunk)
        assert np.array_equal(t, t_ref) and iq.tobytes() == iq_ref.tobytes()
        proj = synthesise_projection(paths, WF, cfg, receiver=RX, seed=(4, 1), chunk_chirps=chunk)[1]
        assert proj.profiles.tobytes() == proj_ref.profiles.tobytes()
        assert proj.coherent.tobytes() == proj_ref.coherent.tobytes()
    # the consumed-only projection is the DSP's projection of the kept IQ, bitwise
    whole = project(iq_ref, WF, cfg)
    assert whole.profiles.tobytes() == proj_ref.profiles.tobytes()
    assert whole.coherent.tobytes() == proj_ref.coherent.tobytes()


def test_receive_inplace_gives_the_bytes_of_receive():
    iq = (np.random.default_rng(1).standard_normal((700, 128)) * 1e-5).astype(np.complex64)
    rx = RX.model_copy(update={"leakage": LeakageConfig(coupling_db=-45.0)})
    a = receive(iq, rx, WF, seed=(2, 0), first_chirp=100)
    b = receive_inplace(iq.copy(), rx, WF, seed=(2, 0), first_chirp=100)
    assert a.tobytes() == b.tobytes()


def test_noise_words_give_circular_gaussian_samples():
    p = 3e-14
    words = np.random.Generator(np.random.PCG64(12345)).bit_generator.random_raw(1 << 21)
    z = gaussian_from_words(words, p).astype(np.complex128)
    assert z.dtype == np.complex128 and z.shape == words.shape
    power = np.abs(z) ** 2 / p
    assert power.mean() == pytest.approx(1.0, abs=5e-3)
    assert np.mean(z.real ** 2) / p == pytest.approx(0.5, abs=3e-3)
    assert np.mean(z.imag ** 2) / p == pytest.approx(0.5, abs=3e-3)
    assert abs(np.mean(z.real * z.imag)) / p < 3e-3 and abs(z.mean()) / np.sqrt(p) < 5e-3
    assert np.mean(power ** 2) == pytest.approx(2.0, abs=0.02)  # E|z|^4 = 2 P^2 (Var of power^2: 20)
    for x in (1.0, 4.0, 9.0):  # exponential tail P(|z|^2 > x P) = e^-x
        q = np.exp(-x)
        assert np.mean(power > x) == pytest.approx(q, abs=6 * np.sqrt(q * (1 - q) / z.size))
    assert stats.kstest(z.real / np.sqrt(p / 2), "norm").pvalue > 1e-3
    assert stats.kstest(np.angle(z), "uniform", args=(-np.pi, 2 * np.pi)).pvalue > 1e-3


@pytest.mark.parametrize("cfg", [DSPConfig(), DSPConfig(range_window="hann", range_sum="incoherent"),
                                 DSPConfig(range_bins="positive_half", coherent_offset_samples=0)])
def test_chunked_projection_equals_whole_and_the_weights(cfg):
    iq = (np.random.default_rng(2).standard_normal((1500, 128))
          + 1j * np.random.default_rng(3).standard_normal((1500, 128))).astype(np.complex64)
    whole = project(iq, WF, cfg)
    apply = projector(WF, cfg)
    parts = [apply(iq[a:a + 256]) for a in range(0, 1500, 256)]
    assert np.concatenate([q.profiles for q in parts]).tobytes() == whole.profiles.tobytes()
    if cfg.range_sum == "coherent":
        assert np.concatenate([q.coherent for q in parts]).tobytes() == whole.coherent.tobytes()
    w, rng = range_weights(WF, cfg)
    assert np.array_equal(rng, whole.range)
    # complex64 FFT: a few 1e-7 of the largest bin
    ref = iq.astype(np.complex128) @ w
    assert np.abs(whole.profiles - ref).max() <= 1e-6 * np.abs(ref).max()


def _gathered_moving_average(x, half):
    """The former formulation: both window ends gathered for every row."""
    c = np.concatenate([np.zeros((1,) + x.shape[1:], x.dtype), np.cumsum(x, axis=0)])
    n = np.arange(x.shape[0])
    lo, hi = np.maximum(n - half, 0), np.minimum(n + half + 1, x.shape[0])
    return x - (c[hi] - c[lo]) / (hi - lo).reshape((-1,) + (1,) * (x.ndim - 1))


@pytest.mark.parametrize("dtype", [np.complex128, np.complex64])
@pytest.mark.parametrize("shape", [(2000, 18), (2000,), (5, 3), (1,), (0, 4), (502, 2)])
@pytest.mark.parametrize("half", [0, 1, 250, 251, 600])
def test_moving_average_same_bytes_as_before(shape, half, dtype):
    rng = np.random.default_rng(4)
    x = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)).astype(dtype)
    ref = _gathered_moving_average(x.astype(np.complex128), half)  # the former mti_filter converted first
    assert _subtract_moving_average(x, half).tobytes() == ref.tobytes()
