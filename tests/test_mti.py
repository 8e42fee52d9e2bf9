"""Slow-time clutter (MTI) filters: responses from filter theory, static targets vanish, movers keep their power."""
import numpy as np
import pytest
from pydantic import ValidationError

from processing.dsp.signatures import DSPConfig, project, signatures
from processing.dsp.mti import MA_CUTOFF_PRODUCT, cutoff_hz, moving_average_length, mti_filter, settling_time_s
from processing.pathset import PathSet
from processing.synthesis.exact import synthesise
from processing.radar.waveform import C0, Waveform

PRF = 2000.0
F0 = 24.125e9
FC = 8.0  # Hz
BW = dict(static_removal="butterworth", mti_cutoff_hz=FC)
WF = Waveform()


def _tone(f, n=20000):
    return np.exp(2j * np.pi * f * np.arange(n) / PRF)


def _butter_power(f, order):
    # digital Butterworth high-pass (bilinear transform with pre-warping): the analog |H|^2 on tan-warped axes
    return 1.0 / (1.0 + (np.tan(np.pi * FC / PRF) / np.tan(np.pi * f / PRF)) ** (2 * order))


@pytest.mark.parametrize("order", [2, 4])
@pytest.mark.parametrize("ratio", [0.25, 1.0, 4.0])
def test_causal_butterworth_steady_state_power_follows_theory(order, ratio):
    f = ratio * FC
    y = mti_filter(_tone(f), PRF, F0, DSPConfig(**BW, mti_order=order))
    # after 10 s every transient (slowest pole decays at 2 pi fc sin(pi / 2n) >= 19 /s) is gone
    gain = np.mean(np.abs(y[-5000:]) ** 2)
    assert gain == pytest.approx(_butter_power(f, order), rel=1e-4)
    if ratio == 1.0:
        assert gain == pytest.approx(0.5, rel=1e-9)  # -3 dB exactly at the cut-off


def test_zero_phase_butterworth_squares_the_response():
    y = mti_filter(_tone(FC), PRF, F0, DSPConfig(**BW, mti_zero_phase=True))
    mid = slice(5000, 15000)
    assert np.mean(np.abs(y[mid]) ** 2) == pytest.approx(0.25, rel=1e-4)  # |H|^4 = 1/4 (-6 dB) at fc
    # zero phase: the output is in phase with the input
    assert np.max(np.abs(np.angle(y[mid] / _tone(FC)[mid]))) < 1e-6


def test_moving_average_length_and_response():
    n = moving_average_length(FC, PRF)
    assert n % 2 == 1 and abs(n - MA_CUTOFF_PRODUCT * PRF / FC) <= 1
    for f in (FC, 5 * FC):
        y = mti_filter(_tone(f), PRF, F0, DSPConfig(mti_cutoff_hz=FC))
        d = np.sin(np.pi * f * n / PRF) / (n * np.sin(np.pi * f / PRF))  # centred average of a tone (Dirichlet)
        mid = slice(n, -n)  # away from the ends, where the average is one-sided
        np.testing.assert_allclose(y[mid], (1 - d) * _tone(f)[mid], atol=1e-9)
    # at fc the rounding of L to an odd integer moves f L / PRF by at most fc / PRF = 0.004 from 0.7554;
    # the slope of (1 - sinc x)^2 there is 1.9, so |H(fc)|^2 is 0.5 within 0.008
    d = np.sin(np.pi * FC * n / PRF) / (n * np.sin(np.pi * FC / PRF))
    assert (1 - d) ** 2 == pytest.approx(0.5, abs=0.008)


@pytest.mark.parametrize("cfg", [DSPConfig(mti_cutoff_hz=FC), DSPConfig(**BW), DSPConfig(**BW, mti_zero_phase=True)],
                         ids=["moving_average", "butterworth", "zero_phase"])
def test_static_return_vanishes_from_the_first_chirp(cfg):
    # H(0) = 0; the centred average and the steady-state start remove a constant exactly
    x = (0.3 - 0.7j) * np.ones((4000, 3))
    assert np.max(np.abs(mti_filter(x, PRF, F0, cfg))) < 1e-9


@pytest.mark.parametrize("order", [2, 4])
def test_causal_filter_from_rest_rings_then_settles(order):
    cfg = DSPConfig(**BW, mti_order=order, mti_initial="zero")
    y = np.abs(mti_filter(np.ones(4000, complex), PRF, F0, cfg))
    t = np.arange(4000) / PRF
    sigma = 2 * np.pi * FC * np.sin(np.pi / (2 * order))  # slowest pole pair's decay rate [1/s]
    t40 = np.log(100) / sigma  # e^(-sigma t) at -40 dB
    assert y[0] > 0.9  # a high-pass passes the step's edge: the static scene shows at the start
    # after twice t40 the envelope is at -80 dB, leaving 40 dB for the residue of the slowest poles
    assert y[t >= 2 * t40].max() < 1e-2
    ts = settling_time_s(cfg, PRF, F0)
    assert 0.5 * t40 <= ts <= 2 * t40
    assert y[t >= ts].max() <= 1e-2 + 1e-12


def test_cutoff_in_mps_and_hz_agree():
    v = 0.05
    hz = 2 * v * WF.carrier_hz / C0
    assert cutoff_hz(DSPConfig(mti_cutoff_mps=v), WF.carrier_hz) == pytest.approx(hz, rel=1e-15)
    times = np.arange(0, 0.6, 1 / 60)
    tau = np.stack([2 * (4.0 - 0.8 * times) / C0, np.full_like(times, 2 * 2.5 / C0)], axis=1)
    t, iq = synthesise(PathSet(times, tau, np.ones_like(tau, complex), ids=np.arange(2)), WF)
    for kind in ("moving_average", "butterworth"):
        a = signatures(iq, WF, DSPConfig(static_removal=kind, mti_cutoff_mps=v))
        b = signatures(iq, WF, DSPConfig(static_removal=kind, mti_cutoff_hz=hz))
        np.testing.assert_allclose(a.p_vt, b.p_vt, rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(a.range_distribution, b.range_distribution, rtol=1e-9, atol=1e-15)


def test_invalid_cutoffs_are_clear_errors():
    with pytest.raises(ValidationError, match="either in Hz"):
        DSPConfig(mti_cutoff_hz=3.0, mti_cutoff_mps=0.1)
    with pytest.raises(ValidationError, match="greater than 0"):
        DSPConfig(mti_cutoff_mps=0.0)
    with pytest.raises(ValueError, match="Nyquist"):
        mti_filter(np.ones(100, complex), PRF, F0, DSPConfig(mti_cutoff_hz=1500.0))


def _static_and_mover(v=0.5, static_gain=10.0, duration=1.5):
    """A mover at 4 m approaching at v [m/s] (gain 1) and a static reflector at 2.5 m (gain `static_gain`)."""
    times = np.arange(0, duration, 1 / 60)
    tau = np.stack([2 * (4.0 - v * times) / C0, np.full_like(times, 2 * 2.5 / C0)], axis=1)
    gains = np.tile([1.0 + 0j, static_gain], (times.size, 1))
    return PathSet(times, tau, gains, ids=np.arange(2))


@pytest.mark.parametrize("kind", ["moving_average", "butterworth"])
def test_slow_mover_keeps_its_power_and_static_reflector_vanishes(kind):
    v = 0.5  # 80 Hz Doppler, 25 x the default 0.02 m/s (3.2 Hz) cut-off
    t, iq = synthesise(_static_and_mover(v, duration=2.5), WF)
    _, iq_mover = synthesise(_static_and_mover(v, static_gain=0.0, duration=2.5), WF)
    cfg = DSPConfig(static_removal=kind)
    sig = signatures(iq, WF, cfg, t0=t[0])
    ref = signatures(iq_mover, WF, DSPConfig(static_removal="none"), t0=t[0])
    # away from the ends: the Butterworth's settling at the start (the mover was not there "before"),
    # the average's half length (0.12 s) at both
    edge = max(settling_time_s(cfg, 1 / WF.pri_s, WF.carrier_hz), 0.15)
    mid = (sig.time > t[0] + edge) & (sig.time < t[-1] - 0.15)
    assert mid.sum() > 30
    # theory: moving average 1 - D(f) with |D| <= 1 / (pi f L / PRF) = 0.017 at 80 Hz -> power 1 +- 0.034;
    # Butterworth |H|^2 = 1 - 25^-8; the rest of the 5 % is the mover's slow range walk over the band
    np.testing.assert_allclose(sig.power[mid] / ref.power[mid], 1.0, atol=0.05)
    # the reflector (100 x the mover's power) is gone: p(v,t) peaks at the mover's velocity in every window
    # and is the mover's alone (its zero bin holds only the mover's window leakage, 1.5 % at 2.6 bins)
    dv = WF.velocity_resolution(cfg.window_chirps)
    assert np.all(np.abs(sig.velocity[sig.p_vt[:, mid].argmax(axis=0)] - v) <= dv / 2 + 1e-9)
    assert np.abs(sig.p_vt[:, mid] - ref.p_vt[:, mid]).max() < 0.01
    assert np.abs(sig.range_distribution[:, mid] - ref.range_distribution[:, mid]).max() < 0.01


def test_static_scene_alone_is_empty_and_never_nan():
    t, iq = synthesise(_static_and_mover(v=0.0, duration=0.8), WF)  # both reflectors static
    for cfg in (DSPConfig(), DSPConfig(static_removal="butterworth")):
        sig = signatures(iq, WF, cfg, t0=t[0])
        for arr in (sig.p_vt, sig.mean_velocity, sig.range_distribution):
            assert np.isfinite(arr).all() and not arr.any()
        assert not sig.valid.any()


def test_causal_start_transient_shows_static_scene_at_zero_velocity():
    # documented edge behaviour of mti_initial="zero" (MATLAB's filter): the first windows show the static
    # reflectors at v = 0 and their ranges, fading within the settling time
    t, iq = synthesise(_static_and_mover(v=0.0, duration=1.0), WF)
    cfg = DSPConfig(static_removal="butterworth", mti_initial="zero")
    sig = signatures(iq, WF, cfg, t0=t[0])
    assert sig.valid[0]
    assert sig.velocity[sig.p_vt[:, 0].argmax()] == 0.0
    assert sig.range[sig.range_distribution[:, 0].argmax()] == pytest.approx(2.5, abs=WF.range_resolution / 2)
    late = sig.time - cfg.window_chirps * WF.pri_s / 2 > t[0] + settling_time_s(cfg, 1 / WF.pri_s, WF.carrier_hz)
    # after the settling time |y| < 1e-2 |x0| (x0: the static scene's coherent sum), so a window's total
    # power, nfft mean |y|^2 for the unit-energy boxcar, is below nfft 1e-4 |x0|^2
    x0 = project(iq, WF, cfg).coherent[0]
    assert late.any() and np.all(sig.power[late] <= cfg.window_chirps * 1e-4 * abs(x0) ** 2)
