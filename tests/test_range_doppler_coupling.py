"""Range-Doppler coupling (issue 24): a moving path beats at gamma (tau + kappa dtau/dt) in fast time, the
Doppler shift inside the chirp adding to its range frequency, in the exact, gridded and projection
synthesisers alike."""
import numpy as np
import pytest

from processing.dsp.config import DSPConfig
from processing.dsp.signatures import signatures
from processing.pathset import PathSet
from processing.radar.waveform import C0, Waveform
from processing.synthesis.exact import coupling_s, synthesise
from processing.synthesis.projection import synthesise_projection

GLASGOW_WF = Waveform(carrier_hz=5.8e9, bandwidth_hz=400e6, pri_s=1e-3, samples_per_chirp=128, max_range_m=24.0)


def _point(r0: float, v: float, times: np.ndarray, n_copies: int = 1) -> PathSet:
    """A point approaching at v m/s from r0 m (n_copies identical paths: more than 64 takes the grid)."""
    tau = 2 * (r0 - v * times) / C0
    rates = np.full_like(tau, -2 * v / C0)
    return PathSet(times=times, delays=np.repeat(tau[:, None], n_copies, 1),
                   gains=np.full((times.size, n_copies), 1.0 / n_copies, complex),
                   ids=np.arange(n_copies), delay_rates=np.repeat(rates[:, None], n_copies, 1))


def _peak_bin(iq_row: np.ndarray, pad: int = 64) -> float:
    """Fast-time beat frequency of a single tone in range bins (zero-padded FFT, parabolic peak)."""
    spec = np.abs(np.fft.fft(iq_row, pad * iq_row.size))
    k = int(spec.argmax())
    a, b, c = np.log(spec[k - 1]), np.log(spec[k]), np.log(spec[(k + 1) % spec.size])
    return (k + 0.5 * (a - c) / (a - 2 * b + c)) / pad


@pytest.mark.parametrize("method,copies", [("exact", 1), ("grid", 100)])
def test_a_point_at_4_mps_lands_its_range_peak_f_d_over_slope_away(method, copies):
    """f_D / slope in delay is f_D T_chirp range bins: 2 x 4 / 0.0517 m x 1 ms = 0.155 bins on the Glasgow
    radar; the peak must move by that within 0.05 bins (the padded FFT's parabolic peak is ~0.005 bins)."""
    wf = GLASGOW_WF
    times = np.arange(0.0, 0.05, 1 / 60)
    t_moving, iq_moving = synthesise(_point(3.0, 4.0, times, copies), wf, method=method)
    k = 20
    r_k = 3.0 - 4.0 * t_moving[k]
    static = PathSet(times=times, delays=np.full((times.size, copies), 2 * r_k / C0),
                     gains=np.full((times.size, copies), 1.0 / copies, complex), ids=np.arange(copies),
                     delay_rates=np.zeros((times.size, copies)))
    _, iq_static = synthesise(static, wf, method=method)
    shift = _peak_bin(iq_moving[k]) - _peak_bin(iq_static[k])
    f_d = 2 * 4.0 / (C0 / wf.carrier_hz)
    expected = -f_d * wf.chirp_s  # approaching: tau shrinks, the Doppler shift lowers the beat frequency
    assert expected == pytest.approx(-0.155, abs=0.002)
    assert shift == pytest.approx(expected, abs=0.05)
    assert coupling_s(wf) * wf.slope == pytest.approx(wf.start_hz + wf.slope * 64 / wf.fs, rel=1e-12)


def _brute_force_iq(r0: float, v: float, wf: Waveform, t_n: np.ndarray) -> np.ndarray:
    """Beat signal with tau evaluated at every ADC sample: exp(j 2 pi (f_s tau(t) + gamma t' tau(t)))."""
    tp = np.arange(wf.samples_per_chirp) / wf.fs
    tau = 2 * (r0 - v * (t_n[:, None] + tp[None, :])) / C0
    return np.exp(1j * 2 * np.pi * (wf.start_hz * tau + wf.slope * tp[None, :] * tau))


@pytest.mark.parametrize("method,copies", [("exact", 1), ("grid", 100)])
def test_fast_target_p_vt_matches_a_brute_force_synthesis(method, copies):
    """Glasgow radar and DSP, a 4 m/s target: p(v,t) within L1 0.01 (mean over columns) of the synthesis
    with tau at every ADC sample; without the coupling term it was 0.10 (issue 24)."""
    wf = GLASGOW_WF
    dsp = DSPConfig.glasgow()
    times = np.arange(0.0, 1.0, 1 / 60)
    paths = _point(4.0, 4.0, times, copies)
    t, iq = synthesise(paths, wf, method=method)
    ref = signatures(_brute_force_iq(4.0, 4.0, wf, t), wf, dsp, t0=t[0])
    got = signatures(iq, wf, dsp, t0=t[0])
    l1 = np.abs(got.p_vt - ref.p_vt).sum(axis=0).mean()
    assert l1 < 0.01, l1
    _, proj = synthesise_projection(paths, wf, dsp, method=method)
    from processing.dsp.signatures import signatures_from_projection

    via_projection = signatures_from_projection(proj, dsp)
    assert np.abs(via_projection.p_vt - ref.p_vt).sum(axis=0).mean() < 0.01
