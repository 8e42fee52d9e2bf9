"""Windows carry signal only above the receiver noise: the expected noise-only column power, and the
detection that keeps the mean velocity of noise-only windows at 0."""
import numpy as np
import pytest

from processing.dsp.signatures import DSPConfig, noise_column_power, signatures
from processing.pathset import PathSet
from processing.radar.receiver import ReceiverConfig, noise_power_per_sample, receive
from processing.synthesis.exact import synthesise
from processing.radar.waveform import C0, Waveform

WF = Waveform()
RX = ReceiverConfig(transmit_power_dbm=19.0, noise_figure_db=12.0)


@pytest.mark.parametrize("cfg", [DSPConfig(), DSPConfig(range_sum="incoherent"),
                                 DSPConfig(range_sum="magnitude", range_window="hann")],
                         ids=["coherent", "incoherent", "magnitude"])
def test_noise_column_power_matches_noise_only_recordings(cfg):
    iq = receive(np.zeros((8192, WF.samples_per_chirp), np.complex64), RX, WF, seed=3)
    p_n = noise_power_per_sample(RX, WF.fs)
    sig = signatures(iq, WF, cfg)  # noise level unknown to the DSP: every window counts
    expected = noise_column_power(WF, cfg, p_n, sig.p_vt.shape[0])
    # 255 windows of 64 bins (overlapping by half): the mean column power's spread is ~1 %, i.e. 0.05 dB;
    # the magnitude mode's independence assumption (Hann correlates neighbouring range bins) costs more
    tol = 0.6 if cfg.range_sum == "magnitude" else 0.15
    assert abs(10 * np.log10(sig.power.mean() / expected)) < tol
    det = signatures(iq, WF, cfg, noise_power=p_n)
    assert not det.valid.any() and np.all(det.mean_velocity == 0.0)
    np.testing.assert_array_equal(det.p_vt, sig.p_vt)  # what was received (noise) is still shown


def test_a_target_above_the_noise_is_detected_and_its_velocity_kept():
    # 0.5 m^2 at 4 m approaching at 1 m/s for the second half of a 2 s recording (absent before)
    t = np.linspace(0.0, 2.0, 121)
    r = 5.0 - np.clip(t - 1.0, 0.0, None)
    gains = np.where(t >= 1.0, WF.wavelength * np.sqrt(0.5) / ((4 * np.pi) ** 1.5 * r ** 2), 0.0).astype(complex)
    ps = PathSet(t, (2 * r / C0)[:, None], gains[:, None], ids=np.array([0]))
    _, iq = synthesise(ps, WF)
    iq = receive(iq, RX, WF, seed=1)
    sig = signatures(iq, WF, DSPConfig(), noise_power=noise_power_per_sample(RX, WF.fs))
    late = sig.time > 1.1
    early = sig.time < 0.9
    assert sig.valid[late].all() and not sig.valid[early].any()
    assert np.all(sig.mean_velocity[early] == 0.0)
    assert abs(np.median(sig.mean_velocity[late]) - 1.0) < 0.1
