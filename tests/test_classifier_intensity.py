"""What the classifier input shows (`PreprocessConfig.intensity`, issue 27): the column-normalised p(v,t) of seed
eq. 7 or the spectrogram p(v,t) power(t) of seed eq. 6, on signatures the tests build."""
import numpy as np
import pytest

from processing.classifier.perturb import change_floor
from processing.classifier.preprocess import PreprocessConfig, preprocess
from processing.dsp.signatures import DSPConfig, Signature, _normalise, mean_velocity
from processing.errors import InputError
from processing.realdata.real_images import noise_aware

V = np.linspace(-6, 6, 317)
T = np.arange(383) * (5.0 / 384)
WINDOW = PreprocessConfig(v_range_mps=6.0, time_mode="window", window_s=5.0)
POWER = WINDOW.model_copy(update={"intensity": "power"})


def _signature(seed=0, noise=True):
    """A Glasgow-grid signature as the image reader makes it (317 velocity bins over +-6 m/s, 383 columns of
    13 ms): a 0.25 m/s wide line in columns 120-259, exponential noise of mean 40 dB below its peak, and the
    image's colour floor 35 dB below it (cells under it read 0: ~4 % of the noise cells show, as ~5-20 % of
    a campaign-1 image's cells are non-zero). Without noise the line's power ramps from -10 to 0 dB."""
    rng = np.random.default_rng(seed)
    centre = np.zeros(T.size)
    centre[120:260] = 2.0 * np.sin(np.pi * np.arange(140) / 139) + 0.3
    amp = np.zeros(T.size)
    amp[120:260] = 1.0 if noise else np.linspace(0.1, 1.0, 140)
    power = amp * np.exp(-0.5 * ((V[:, None] - centre) / 0.25) ** 2)
    if noise:
        power += 1e-4 * rng.exponential(size=(V.size, T.size))
        power[power < 10 ** -3.5] = 0.0
    p, valid, total = _normalise(power, DSPConfig().empty_floor)
    mv = mean_velocity(p, V, 6.0, DSPConfig(mean_velocity="seed"), periodic=False)
    return noise_aware(Signature(time=T, velocity=V, p_vt=p, mean_velocity=mv, range=np.zeros(0),
                                 range_distribution=np.zeros((0, T.size)), valid=valid, power=total))


def _input(sig, cfg):
    return preprocess(sig.p_vt, sig.velocity, sig.time, cfg, sig.valid, sig.power)


def test_power_intensity_puts_each_column_at_its_power():
    """Two columns with the same p(v,t), one 100 times the other's power: with 'power' the weaker one sits
    20 dB lower (half of the 40 dB display), with 'p' they are the same; a constant power changes nothing."""
    p = np.zeros((64, 64))
    p[40, :] = 1.0
    power = np.ones(64)
    power[32:] = 0.01
    cfg = PreprocessConfig(v_range_mps=None, time_mode="resample")
    shown = preprocess(p, None, None, cfg.model_copy(update={"intensity": "power"}), power=power)
    assert shown[40, :32] == pytest.approx(1.0) and shown[40, 32:] == pytest.approx(0.5)
    np.testing.assert_array_equal(preprocess(p, None, None, cfg, power=power)[40], 1.0)
    sig = _signature()
    spectrogram = _input(sig, POWER)
    np.testing.assert_array_equal(preprocess(sig.p_vt, V, T, POWER, sig.valid, np.full(T.size, 3.0)),
                                  _input(sig, WINDOW))
    assert spectrogram.shape == (64, 64) and np.isfinite(spectrogram).all()


def test_the_crop_is_the_same_for_both_intensities():
    """A noise-free line whose power ramps up 10 dB over its span: the crop is found from p(v,t) for both, so
    the line occupies the same input columns at the same rows; only the brightness differs."""
    sig = _signature(noise=False)
    for mode in ("window", "active"):
        cfg = PreprocessConfig(v_range_mps=6.0, time_mode=mode, window_s=3.0, n_time=100)
        a, b = _input(sig, cfg), _input(sig, cfg.model_copy(update={"intensity": "power"}))
        on = a.max(axis=0) > 0
        assert 20 < on.sum() < 100 and np.array_equal(on, b.max(axis=0) > 0)
        np.testing.assert_array_equal(a[:, on].argmax(axis=0), b[:, on].argmax(axis=0))
        assert b[:, on].max(axis=0).min() < 0.8  # the weak end: up to 10 dB (a quarter of the display) down


@pytest.mark.parametrize("db", [5.0, 10.0])
def test_a_higher_floor_barely_changes_the_power_image(db):
    """The perturbation grid's higher floor: a pedestal of (10^(db/10) - 1) F, F the quiet columns' mean power
    (1.8e-5 here: the noise's 1e-4 x P(cell above the colour floor) x its mean there, 4.2 e^-3.16). In p(v,t)
    it fills every quiet column (a column's p spreads it over 317 bins, ~14 dB under the line's peak p, where
    the colour floor left 0). In the spectrogram, on the input's 0.19 m/s bins (4.9 of the image's, holding
    4.6 times the line's peak cell), it sits at 4.9 x 2.2 F / 4.6 = -44 dB under the peak for +5 dB, below the
    40 dB display, and at 4.9 x 9 F / 4.6 = -37.6 dB for +10 dB: 2.4 dB (0.06 of the display) above its bottom."""
    sig = _signature()
    high = change_floor(sig, db)
    d_p = np.abs(_input(high, WINDOW) - _input(sig, WINDOW)).mean()
    d_power = np.abs(_input(high, POWER) - _input(sig, POWER)).mean()
    assert d_p > 0.1
    assert d_power < (0.005 if db == 5.0 else 0.06)


def test_power_intensity_needs_the_column_power():
    sig = _signature()
    with pytest.raises(InputError, match="column power"):
        preprocess(sig.p_vt, V, T, POWER, sig.valid, None)
    assert PreprocessConfig().intensity == "p"  # default, and what checkpoints without the field load as
