"""Range-Doppler map and the Glasgow preset: point targets land in the right (range, velocity) cell, the map
is consistent with the range distribution, it is stored in signature.h5, and the preset reproduces the
dataset script's processing."""
import warnings

import numpy as np
import pytest
from scipy.signal import butter, get_window, lfilter, spectrogram

from processing.dsp.signatures import GLASGOW_DSP, DSPConfig, signatures
from processing.pathset import PathSet
from processing.io.signature_file import read_signature_file, write_signature_file
from processing.synthesis.exact import NyquistWarning, synthesise, coupling_s
from processing.radar.waveform import C0, Waveform

WF = Waveform()
# the Glasgow dataset's radar: Ancortek, 5.8 GHz, 400 MHz, 1 ms sawtooth chirp, 128 samples (0.375 m bins)
GWF = Waveform(carrier_hz=5.8e9, bandwidth_hz=400e6, pri_s=1e-3, samples_per_chirp=128, max_range_m=12.0)


def _targets(wf, r0, v, duration, gains=None):
    """Point targets at ranges r0 [m] (list) approaching at v [m/s] (list)."""
    times = np.arange(0, duration, 1 / 60)
    r = np.asarray(r0)[None, :] - np.asarray(v)[None, :] * times[:, None]
    g = np.ones_like(r, complex) if gains is None else np.tile(np.asarray(gains, complex), (times.size, 1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NyquistWarning)
        return synthesise(PathSet(times, 2 * r / C0, g, ids=np.arange(r.shape[1])), wf)


def _peak_cells(sig):
    rd = sig.range_doppler  # [R, V, T]
    flat = rd.reshape(-1, rd.shape[2]).argmax(axis=0)
    ir, iv = np.unravel_index(flat, rd.shape[:2])
    return sig.range[ir], sig.range_doppler_velocity[iv], iv


@pytest.mark.parametrize("frac", [-1.0, -0.93, -0.4, 0.27, 0.81, 0.97])
def test_point_target_peaks_in_its_range_doppler_cell(frac):
    v, r0 = frac * WF.v_max, 5.0
    t, iq = _targets(WF, [r0], [v], 0.5)
    sig = signatures(iq, WF, DSPConfig(), t0=t[0])
    r_pk, v_pk, iv = _peak_cells(sig)
    r_true = r0 - v * sig.range_doppler_time - coupling_s(WF) * v  # where FMCW shows it (range-Doppler coupling)
    assert np.all(np.abs(r_pk - r_true) <= WF.range_resolution / 2 + 1e-9)
    dv = WF.velocity_resolution(64)  # the map refers to the centre carrier: the axis step of Waveform.v_max
    np.testing.assert_allclose(np.diff(sig.range_doppler_velocity), dv, rtol=1e-12)
    if frac == -1.0:  # Doppler exactly -PRF/2: the Nyquist bin, index 0, labelled -v_max
        assert np.all(iv == 0) and sig.range_doppler_velocity[0] == pytest.approx(-WF.v_max, rel=1e-12)
    else:
        assert np.all(np.abs(v_pk - v) <= dv / 2 + 1e-9)
    # p(v,t) of the same windows agrees (its own axis: the coherent sum's carrier)
    k = np.searchsorted(sig.time, sig.range_doppler_time)
    pv = sig.velocity[sig.p_vt[:, k].argmax(axis=0)]
    assert np.all(np.abs(np.mod(pv - v + sig.v_max, 2 * sig.v_max) - sig.v_max) <= 1.01 * dv / 2 + 1e-9)


def test_map_axes_stride_and_parseval_consistency_with_range_distribution():
    t, iq = _targets(WF, [3.0, 6.5], [1.1, -2.4], 1.0, gains=[1.0, 0.5])
    cfg = DSPConfig()
    sig = signatures(iq, WF, cfg, t0=t[0])
    k = cfg.rd_stride(WF.pri_s)
    assert k == 6  # 0.1 s / (32 x 0.5 ms) = 6.25 -> 6 windows (96 ms) apart, more than a window (2)
    np.testing.assert_array_equal(sig.range_doppler_time, sig.time[::k])
    assert sig.range_doppler.shape == (sig.range.size, 64, sig.time[::k].size)
    assert sig.range_doppler.dtype == np.float32
    # Parseval: with the unit-energy boxcar, sum_v |FFT|^2 = nfft x (window mean power) in each range bin,
    # so the map summed over velocity, normalised, is the range distribution of the same window
    col = sig.range_doppler.sum(axis=1)
    np.testing.assert_allclose(col / col.sum(axis=0), sig.range_distribution[:, ::k], rtol=1e-5, atol=1e-7)
    assert signatures(iq, WF, DSPConfig(range_doppler=False)).range_doppler is None
    assert signatures(iq, WF, DSPConfig(range_doppler_stride=1)).range_doppler.shape[2] == sig.time.size


def test_map_is_stored_in_signature_file(tmp_path):
    t, iq = _targets(WF, [4.0], [1.5], 0.6)
    sigs = {"radar1": signatures(iq, WF, DSPConfig(), t0=t[0]),
            "radar2": signatures(iq, WF, DSPConfig(range_doppler=False), t0=t[0])}
    path = write_signature_file(tmp_path / "signature.h5", sigs, activity="walk", backend="points", seed=0,
                                direction_deg=0.0, config={})
    attrs, back = read_signature_file(path)
    assert attrs["version"] == "2"
    a, b = sigs["radar1"], back["radar1"]
    for key in ("range_doppler", "range_doppler_time", "range_doppler_velocity", "p_vt", "range"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
    assert b.carrier_hz == a.carrier_hz and b.v_max == a.v_max and isinstance(b.v_max, float)
    assert back["radar2"].range_doppler is None and back["radar2"].range_doppler_velocity is None


GLASGOW_V = [-5.95, -2.2, 0.8, 3.1, 5.9]  # up to the +-6 m/s crop
DV_PAD = C0 / (2 * GWF.carrier_hz * 800 * GWF.pri_s)  # 0.032 m/s: the preset's zero-padded velocity step
LATE = 0.55  # s: the causal 3.75 Hz filter started at rest has settled (-40 dB) after 0.51 s


@pytest.mark.parametrize("v", GLASGOW_V)
def test_glasgow_preset_doppler_tone_lands_in_its_padded_bin(v):
    # a Doppler tone at a fixed range (bin 18.67, no range migration) isolates the axis convention: a
    # Hamming-windowed tone's main lobe is symmetric about its frequency, so the largest zero-padded sample
    # is the nearest one, within DV_PAD / 2
    t = np.arange(1500) * GWF.pri_s
    m = np.arange(GWF.samples_per_chirp)
    tau0, tau = 2 * 7.0 / C0, 2 * (7.0 - v * t) / C0
    iq = np.exp(2j * np.pi * (GWF.slope * tau0 * m[None, :] / GWF.fs + GWF.carrier_hz * tau[:, None]))
    sig = signatures(iq.astype(np.complex64), GWF, GLASGOW_DSP)
    assert sig.velocity.min() >= -6.0 and sig.velocity.max() <= 6.0 and sig.velocity.size == 2 * int(6 / DV_PAD) + 1
    assert sig.carrier_hz == GWF.carrier_hz and sig.v_max == pytest.approx(GWF.v_max, rel=1e-12)
    late = sig.time > LATE
    assert np.all(np.abs(sig.velocity[sig.p_vt[:, late].argmax(axis=0)] - v) <= DV_PAD / 2 + 1e-9)
    r_pk, v_pk, _ = _peak_cells(sig)
    rd_late = sig.range_doppler_time > LATE
    assert np.all(np.abs(v_pk[rd_late] - v) <= DV_PAD / 2 + 1e-9)
    assert np.all(np.abs(r_pk[rd_late] - 7.0) <= GWF.range_resolution / 2)


@pytest.mark.parametrize("v", [-5.0, -2.2, 0.8, 3.1, 5.0])  # main lobes (+-0.26 m/s) inside the crop
def test_glasgow_preset_moving_point_target(v):
    # a real mover, centred in the preset's band (bins 10..30 = 3.75..11.25 m) over the 1 s run. In a 0.2 s
    # window it crosses up to 3 range bins: each bin sees it for dR / |v|, which spreads its line over
    # |v| / dR Hz (flat-topped), so a peak can sit up to lambda |v| / (4 dR) from v (0.20 m/s at 5.9 m/s)
    # beyond the native half bin lambda / (4 W PRI) = 0.065 m/s; the eq.-8 mean (a centroid) is not moved
    duration = 1.0
    t, iq = _targets(GWF, [7.5 + v * duration / 2], [v], duration)
    sig = signatures(iq, GWF, GLASGOW_DSP, t0=t[0])
    tol = GWF.wavelength / (4 * 200 * GWF.pri_s) + GWF.wavelength * abs(v) / (4 * GWF.range_resolution)
    late = sig.time > LATE
    assert np.all(np.abs(sig.velocity[sig.p_vt[:, late].argmax(axis=0)] - v) <= tol)
    assert np.all(np.abs(sig.mean_velocity[late] - v) < 0.05)
    r_pk, v_pk, _ = _peak_cells(sig)
    rd_late = sig.range_doppler_time > LATE
    assert np.all(np.abs(v_pk[rd_late] - v) <= tol)
    r_true = 7.5 + v * duration / 2 - v * sig.range_doppler_time
    assert np.all(np.abs(r_pk - r_true)[rd_late] <= GWF.range_resolution / 2 + 1e-9)


def test_glasgow_preset_reproduces_the_dataset_script():
    # the script, written out with scipy: rectangular range FFT, positive half, butter(4, 0.0075, 'high') as
    # b, a with filter() (lfilter) per bin, spectrogram(x, 200, 190, 800) (hamming(200), symmetric) per bin
    # 10..30, sum of |S|; our p(v,t) is (sum |S|)^2 normalised per column, on ascending velocity
    t, iq = _targets(GWF, [5.0, 8.0, 10.5], [1.5, -3.0, 0.4], 1.2, gains=[1.0, 0.6, 0.3])
    sig = signatures(iq, GWF, GLASGOW_DSP, t0=t[0])
    rng = np.fft.fft(iq.astype(np.complex128), axis=1)[:, :64]
    b, a = butter(4, 0.0075, "high")
    mti = lfilter(b, a, rng, axis=0)
    win = get_window("hamming", 200, fftbins=False)
    total = 0
    for k in range(10, 31):
        _, _, s = spectrogram(mti[:, k], window=win, nperseg=200, noverlap=190, nfft=800, detrend=False,
                              return_onesided=False, mode="complex")
        total = total + np.abs(s)  # [800 FFT-ordered frequencies, T]
    assert total.shape[1] == sig.time.size
    # velocity index i holds FFT bin (400 - i) mod 800 (v = -f lambda / 2, ascending); then the +-6 m/s crop
    v_full = (np.arange(800) - 400) * C0 / (2 * GWF.carrier_hz * 800 * GWF.pri_s)
    ref = total[(400 - np.arange(800)) % 800][np.abs(v_full) <= 6.0] ** 2
    ref /= ref.sum(axis=0)
    np.testing.assert_allclose(sig.p_vt, ref, rtol=1e-5, atol=1e-9 * ref.max())
