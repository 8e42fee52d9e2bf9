"""A point at known range and radial velocity lands in the right range and velocity bin."""
import numpy as np
import pytest

from processing.dsp.signatures import DSPConfig, signatures
from processing.pathset import PathSet
from processing.synthesis.exact import NyquistWarning, coupling_s, synthesise
from processing.radar.waveform import C0, Waveform
from rtchannel.backends.points import link_delays

from conftest import moving_point_paths

WF = Waveform()
VMAX = WF.v_max
DV = WF.velocity_resolution(64)
# Off-grid velocities (fractions of v_max that fall between bins) up to 0.9 v_max, both signs.
VELOCITIES = [-0.9 * VMAX, -0.61 * VMAX, -0.17 * VMAX, 0.06 * VMAX, 0.43 * VMAX, 0.77 * VMAX, 0.9 * VMAX]
MODES = [DSPConfig(), DSPConfig(range_sum="incoherent"), DSPConfig(doppler_window="hann")]


def _run(paths, cfg=DSPConfig(), wf=WF):
    t, iq = synthesise(paths, wf)
    return signatures(iq, wf, cfg, t0=t[0])


def _check(sig, v, range_of_t):
    # Peak within half a velocity bin; eq. 8 mean within 0.05 m/s (what the rectangular window's
    # leakage allows, see processing.dsp.signatures.mean_velocity); range peak within half a range bin of
    # where an FMCW radar shows a moving point: r - kappa v (range-Doppler coupling, `coupling_s`: the
    # Doppler shift inside the chirp moves the beat frequency by f_D, 0.45 bins at 0.9 v_max here).
    peak_v = sig.velocity[sig.p_vt.argmax(axis=0)]
    assert np.all(np.abs(peak_v - v) <= DV / 2 + 1e-9), (v, peak_v)
    assert np.all(np.abs(sig.mean_velocity - v) < 0.05), (v, np.abs(sig.mean_velocity - v).max())
    peak_r = sig.range[sig.range_distribution.argmax(axis=0)]
    apparent = range_of_t(sig.time) - coupling_s(WF) * v
    assert np.all(np.abs(peak_r - apparent) <= WF.range_resolution / 2 + 1e-9)
    assert np.allclose(sig.p_vt.sum(axis=0), 1.0) and sig.valid.all()


@pytest.mark.parametrize("cfg", MODES, ids=["seed", "incoherent", "hann"])
@pytest.mark.parametrize("v", VELOCITIES)
def test_monostatic_point_velocity_and_range(v, cfg):
    times = np.arange(0, 0.6, 1 / 60)
    r0 = 5.0
    sig = _run(moving_point_paths(r0 - v * times, times), cfg)
    _check(sig, v, lambda t: r0 - v * t)


@pytest.mark.parametrize("v", VELOCITIES)
def test_bistatic_point_velocity_and_range(v):
    # tx and rx 1 m apart; the point moves on their bisector so that the bistatic range
    # (half the total path) is exactly R(t) = R0 - v t.
    tx, rx = np.array([0.0, -0.5, 1.0]), np.array([0.0, 0.5, 1.0])
    times = np.arange(0, 0.6, 1 / 60)
    r = 5.0 - v * times
    pts = np.stack([np.sqrt(r ** 2 - 0.25), 0 * r, 0 * r + 1.0], axis=-1)[:, None, :]
    tau = link_delays(pts, tx, rx)
    np.testing.assert_allclose(tau[:, 0], 2 * r / C0, rtol=1e-12)
    paths = PathSet(times, tau, np.ones_like(tau, complex), ids=np.array([0]))
    _check(_run(paths), v, lambda t: 5.0 - v * t)


def test_bistatic_asymmetric_geometry_uses_half_the_total_path():
    """A bistatic link whose target is much nearer the transmitter than the receiver: the radar sees the
    range (r_tx + r_rx) / 2 and the radial velocity -d/dt of it. The geometry is chosen so that a wrong
    bistatic delay cannot pass: using either leg alone (2 r_tx / c or 2 r_rx / c) puts the range >= 1.5
    range bins and the velocity >= 2 velocity bins away from the expected ones (asserted below). The whole
    chain runs: the points backend's paths for a bistatic `Link`, the synthesiser and the DSP."""
    from dataclasses import replace

    from rtchannel.backends.points import point_paths
    from rtchannel.motion.procedural import generate
    from rtchannel.radar import Link, RadarConfig

    tx, rx = np.array([1.0, 0.0, 1.0]), np.array([-5.0, 6.0, 1.0])
    motion = generate("fall", fps=60.0, seed=0)
    motion = replace(motion, positions=motion.positions[:37], rotations=motion.rotations[:37])  # 0.6 s
    times = motion.times
    start, velocity = np.array([2.0, 1.5, 1.0]), np.array([1.2, -0.9, 0.0])  # 1.5 m/s, away from tx
    pts = start + times[:, None] * velocity  # [F, 3]
    r_tx, r_rx = np.linalg.norm(pts - tx, axis=1), np.linalg.norm(pts - rx, axis=1)
    r_bi = (r_tx + r_rx) / 2
    v_bi, v_tx = -np.gradient(r_bi, times), -np.gradient(r_tx, times)
    # the geometry tells a right bistatic delay from a wrong one
    assert np.all(np.abs(r_tx - r_bi) > 1.5 * WF.range_resolution)
    assert np.all(np.abs(r_rx - r_bi) > 1.5 * WF.range_resolution)
    assert np.all(np.abs(v_tx - v_bi) > 2 * DV)
    radar = RadarConfig(links=[Link(name="bi", tx=tuple(tx), rx=tuple(rx))], receiver=None)
    paths = point_paths(motion, radar, gains=np.ones(1), trajectories=pts[:, None, :], scale="seed")["bi"]
    np.testing.assert_allclose(paths.delays[:, 0], (r_tx + r_rx) / C0, rtol=1e-12)
    sig = _run(paths)
    # nearly constant velocity (the bistatic angle turns slowly over 0.6 s): the velocity expected in a window is
    # that at its centre; tolerances as `_check` (half a velocity bin, half a range bin around the coupling shift)
    v_mid = np.interp(sig.time, times, v_bi)
    peak_v = sig.velocity[sig.p_vt.argmax(axis=0)]
    assert np.all(np.abs(peak_v - v_mid) <= DV / 2 + 1e-9), (peak_v, v_mid)
    peak_r = sig.range[sig.range_distribution.argmax(axis=0)]
    apparent = np.interp(sig.time, times, r_bi) - coupling_s(WF) * v_mid
    assert np.all(np.abs(peak_r - apparent) <= WF.range_resolution / 2 + 1e-9), (peak_r, apparent)


def test_trajectory_at_30fps_still_shows_5_m_per_s():
    # At 30 fps the frame-rate Nyquist velocity lambda/(4 T_f) is only 0.09 m/s: delays must be
    # interpolated to every chirp for 5 m/s to appear.
    v = 5.0
    times = np.arange(0, 0.5 + 1e-9, 1 / 30)
    sig = _run(moving_point_paths(4.5 - v * times, times))
    _check(sig, v, lambda t: 4.5 - v * t)


def test_velocity_above_vmax_warns():
    times = np.arange(0, 0.3, 1 / 60)
    with pytest.warns(NyquistWarning, match="v_max"):
        _run(moving_point_paths(5.0 - 7.0 * times, times))


def test_range_beyond_unambiguous_warns():
    times = np.arange(0, 0.2, 1 / 60)
    r = WF.max_unambiguous_range + 5.0
    with pytest.warns(NyquistWarning, match="unambiguous range"):
        synthesise(moving_point_paths(r - 1.0 * times, times), WF)


def test_no_signal_gives_defined_zero_output():
    times = np.arange(0, 0.5, 1 / 60)
    paths = PathSet(times, np.full((times.size, 3), np.nan), np.zeros((times.size, 3)), ids=np.arange(3))
    sig = _run(paths)
    for arr in (sig.p_vt, sig.mean_velocity, sig.range_distribution):
        assert np.isfinite(arr).all() and not arr.any()
    assert not sig.valid.any()


def test_chunking_does_not_change_iq():
    times = np.arange(0, 0.4, 1 / 60)
    paths = moving_point_paths(3.0 + 0.5 * np.sin(2 * np.pi * times), times)
    _, a = synthesise(paths, WF, chunk_chirps=37)
    _, b = synthesise(paths, WF, chunk_chirps=5000)
    np.testing.assert_array_equal(a, b)


def test_beat_frequency_and_phase_follow_seed_eq3():
    # One chirp, one path: s(m) = a exp(j (2 pi gamma tau m / fs + 2 pi f_start tau)).
    tau, a = 2 * 4.2 / C0, 0.7 - 0.2j
    paths = PathSet(np.array([0.0, 1e-3]), np.full((2, 1), tau), np.full((2, 1), a), ids=np.array([0]))
    _, iq = synthesise(paths, WF)
    m = np.arange(WF.samples_per_chirp)
    expected = a * np.exp(1j * (2 * np.pi * WF.slope * tau * m / WF.fs + 2 * np.pi * WF.start_hz * tau))
    np.testing.assert_allclose(iq[0], expected, atol=1e-6)


def test_appearing_path_fades_in_without_jump():
    times = np.arange(0, 0.2, 1 / 60)
    gains = np.ones((times.size, 1), complex)
    delays = np.full((times.size, 1), 2 * 3.0 / C0)
    gains[:6] = 0
    delays[:6] = np.nan
    t, iq = synthesise(PathSet(times, delays, gains, ids=np.array([0])), WF)
    amp = np.abs(iq[:, 0])
    assert np.isfinite(amp).all()
    # linear fade over one frame interval (1/60 s = 33.3 chirps): steps of at most PRI * 60
    assert np.abs(np.diff(amp)).max() <= 1.01 * WF.pri_s * 60
    assert amp[t < times[5]].max() == 0 and amp[-1] == pytest.approx(1.0, rel=1e-6)


def test_frame_local_paths_with_delay_rates():
    # Sionna-like paths: no identity across frames, Doppler given by delay rates.
    v = 2.3
    times = np.arange(0, 0.6, 1 / 30)
    tau = (2 * (4.0 - v * times) / C0)[:, None]
    paths = PathSet(times, tau, np.ones_like(tau, complex), ids=None, delay_rates=np.full_like(tau, -2 * v / C0))
    _check(_run(paths), v, lambda t: 4.0 - v * t)
