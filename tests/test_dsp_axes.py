"""Axis conventions (velocity axis, Nyquist bin, v_max, carrier), the fast-time stage (weights, offset) and
the two-stage structure of the DSP."""
import warnings

import numpy as np
import pytest
from pydantic import ValidationError

from processing.dsp.signatures import DSPConfig, GLASGOW_DSP, project, signatures, signatures_from_projection
from processing.fast_time import Projection, coherent_weights, path_response, range_weights
from processing.pathset import PathSet
from processing.synthesis.exact import NyquistWarning, synthesise
from processing.radar.waveform import C0, Waveform

from conftest import moving_point_paths

WF = Waveform()
MODES = {"coherent": DSPConfig(), "incoherent": DSPConfig(range_sum="incoherent"),
         "magnitude": DSPConfig(range_sum="magnitude", doppler_window="hann")}


def _run(v, cfg, r0=5.0, duration=0.4, wf=WF):
    times = np.arange(0, duration, 1 / 60)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NyquistWarning)  # v = v_max exactly is at the aliasing limit
        t, iq = synthesise(moving_point_paths(r0 - v * times, times), wf)
    return signatures(iq, wf, cfg, t0=t[0]), iq


@pytest.mark.parametrize("mode", list(MODES))
def test_velocity_axis_is_ascending_from_minus_vmax_with_the_carrier_it_refers_to(mode):
    cfg = MODES[mode]
    sig, _ = _run(1.0, cfg)
    n = cfg.nfft
    dv = C0 / (2 * sig.carrier_hz * n * WF.pri_s)
    np.testing.assert_allclose(sig.velocity, (np.arange(n) - n // 2) * dv, rtol=1e-12)
    assert sig.v_max == pytest.approx(C0 / (4 * sig.carrier_hz * WF.pri_s), rel=1e-12)
    assert sig.velocity[0] == pytest.approx(-sig.v_max, rel=1e-12) and sig.velocity[n // 2] == 0.0
    if mode == "coherent":
        h, f_eff = coherent_weights(WF, cfg)
        assert sig.carrier_hz == f_eff
        # the weights sit early in the chirp: below the centre frequency, above the start
        assert WF.start_hz < f_eff < WF.carrier_hz
    else:  # per-range-bin Doppler refers to mid-chirp: exactly the waveform's carrier and v_max
        assert sig.carrier_hz == WF.carrier_hz and sig.v_max == pytest.approx(WF.v_max, rel=1e-12)


@pytest.mark.parametrize("mode", ["incoherent", "magnitude"])
def test_nyquist_bin_is_index_zero_labelled_minus_vmax(mode):
    cfg = MODES[mode]
    dv = WF.velocity_resolution(64)
    # slow-time frequency exactly +-PRF/2: the Nyquist bin, index 0 (labelled -v_max) for either sign
    for v in (WF.v_max, -WF.v_max):
        sig, _ = _run(v, cfg)
        assert np.all(sig.p_vt.argmax(axis=0) == 0)
    # the top bin is v_max - dv, the second -v_max + dv
    sig, _ = _run(WF.v_max - dv, cfg)
    assert np.all(sig.p_vt.argmax(axis=0) == 63)
    sig, _ = _run(-WF.v_max + dv, cfg)
    assert np.all(sig.p_vt.argmax(axis=0) == 1)


def test_odd_fft_length_has_symmetric_axis():
    sig, _ = _run(1.0, DSPConfig(range_sum="incoherent", window_chirps=63, hop_chirps=32))
    np.testing.assert_allclose(sig.velocity, -sig.velocity[::-1], atol=1e-12)
    dv = WF.velocity_resolution(63)
    assert abs(sig.velocity[sig.p_vt[:, 3].argmax()] - 1.0) <= dv / 2


@pytest.mark.parametrize("m0", [0, 8, 16, 40])
def test_coherent_offset_weights_vanish_on_skipped_samples_and_doppler_stays_right(m0):
    cfg = DSPConfig(coherent_offset_samples=m0)
    h, f_eff = coherent_weights(WF, cfg)
    assert np.all(h[:m0] == 0) and np.abs(h[m0]) > 0
    h0, f0_eff = coherent_weights(WF, DSPConfig(coherent_offset_samples=0))
    # the pulse moves by m0 samples; its band (and so its shape) changes slightly with the segment length
    assert f_eff - f0_eff == pytest.approx(WF.slope * m0 / WF.fs, abs=WF.slope * 1.0 / WF.fs)
    for v in (-3.7, 2.3, 5.5):
        sig, _ = _run(v, cfg)
        dv = C0 / (2 * sig.carrier_hz * 64 * WF.pri_s)
        assert np.all(np.abs(sig.velocity[sig.p_vt.argmax(axis=0)] - v) <= dv / 2 + 1e-9)
        assert np.all(np.abs(sig.mean_velocity - v) < 0.05)


def test_default_offset_and_seed_weight_concentration():
    assert not coherent_weights(WF, DSPConfig())[0][: WF.samples_per_chirp // 16].any()  # default m0 = N // 16
    h, _ = coherent_weights(WF, DSPConfig(coherent_offset_samples=0))
    w2 = np.abs(h) ** 2
    assert w2[:8].sum() / w2.sum() > 0.85  # the module docstring's "91 % on the first 8 of 128"
    with pytest.raises(ValueError, match="fewer than 8"):
        coherent_weights(WF, DSPConfig(coherent_offset_samples=125))


def test_weights_describe_the_projection_of_a_path():
    # what a synthesiser without IQ evaluates: a * path_response(W, tau) equals the projection of the IQ
    tau, a = 2 * 3.3 / C0, 0.4 + 0.3j
    times = np.array([0.0, 0.01])
    _, iq = synthesise(PathSet(times, np.full((2, 1), tau), np.full((2, 1), a), ids=np.array([0])), WF)
    cfg = DSPConfig()
    proj = project(iq, WF, cfg)
    w, rng = range_weights(WF, cfg)
    np.testing.assert_allclose(rng, proj.range)
    scale = np.abs(proj.profiles).max()
    np.testing.assert_allclose(proj.profiles[0], a * path_response(w, tau, WF), atol=1e-6 * scale)
    h, _ = coherent_weights(WF, cfg)
    np.testing.assert_allclose(proj.coherent[0], a * path_response(h, tau, WF), rtol=1e-6)
    # and the matrix form of the range FFT agrees with the FFT the DSP uses
    np.testing.assert_allclose(iq @ w, proj.profiles, atol=1e-6 * scale)


@pytest.mark.parametrize("mode", list(MODES))
def test_two_stage_entry_point_gives_identical_results(mode):
    cfg = MODES[mode]
    times = np.arange(0, 0.5, 1 / 60)
    t, iq = synthesise(moving_point_paths(4.0 - 1.2 * times + 0.1 * np.sin(9 * times), times), WF)
    a = signatures(iq, WF, cfg, t0=t[0])
    p = project(iq, WF, cfg, t0=t[0])
    b = signatures_from_projection(p, cfg)
    for key in ("time", "velocity", "p_vt", "mean_velocity", "range", "range_distribution", "valid", "power",
                "range_doppler", "range_doppler_time", "range_doppler_velocity"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
    # a projection built by hand (as a synthesiser would) goes through the same slow-time stage
    c = signatures_from_projection(Projection(profiles=p.profiles, range=p.range, waveform=WF, coherent=p.coherent,
                                              coherent_carrier_hz=p.coherent_carrier_hz, t0=t[0]), cfg)
    np.testing.assert_array_equal(a.p_vt, c.p_vt)


def test_config_validation_messages():
    with pytest.raises(ValidationError, match="fft_points .* must be at least window_chirps"):
        DSPConfig(window_chirps=64, fft_points=32)
    with pytest.raises(ValidationError, match="must not exceed window_chirps"):
        DSPConfig(window_chirps=64, hop_chirps=65)
    with pytest.raises(ValidationError, match="unknown window 'hanning-ish'"):
        DSPConfig(doppler_window="hanning-ish")
    with pytest.raises(ValidationError, match="below min_range_m"):
        DSPConfig(min_range_m=3.0, max_range_m=2.0)
    with pytest.raises(ValidationError, match="window_chirps"):
        DSPConfig(window_chirps=2)


def test_glasgow_preset_values():
    g = GLASGOW_DSP
    assert (g.window_chirps, g.hop_chirps, g.nfft) == (200, 10, 800)  # 200-chirp window, overlap 190, 4x padding
    assert g.doppler_window == "hamming" and g.doppler_window_symmetric and g.range_window == "boxcar"
    assert g.static_removal == "butterworth" and g.mti_order == 4 and not g.mti_zero_phase
    assert g.mti_initial == "zero" and g.mti_cutoff_hz == pytest.approx(0.0075 * 1000 / 2)  # butter(4, 0.0075)
    assert g.range_sum == "magnitude" and g.range_bins == "positive_half" and g.velocity_crop_mps == 6.0
    # bins 10..30 at c / 2B = 0.375 m
    wf = Waveform(carrier_hz=5.8e9, bandwidth_hz=400e6, pri_s=1e-3, samples_per_chirp=128)
    k = np.round(np.array([g.min_range_m, g.max_range_m]) / wf.range_resolution).astype(int)
    assert tuple(k) == (10, 30)
