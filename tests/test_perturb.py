"""Perturbations of an image's signature (`processing.classifier.perturb`) on a signature the test builds:
317 velocity bins over +-6 m/s, 383 columns of 13 ms (the Glasgow 5 s pixel grid), a Gaussian line (0.25 m/s
wide) whose centre follows a known curve during an active span in the middle, over a noise floor 50 dB
below the line's peak pixel (its columns 37 dB below the active ones, as in the campaign-1 images)."""
import dataclasses

import numpy as np
import pytest

from processing.classifier.perturb import (
    DEFAULT_GRID,
    QUICK_GRID,
    Perturbation,
    apply,
    change_floor,
    motion_kept,
    quiet_columns,
    scale_velocity,
    shift_time,
    stretch_time,
)
from processing.dsp.signatures import DSPConfig, Signature, _normalise, mean_velocity
from processing.errors import InputError
from processing.realdata.real_images import noise_aware

V = np.linspace(-6, 6, 317)
DV = V[1] - V[0]  # 0.0380 m/s
T = np.arange(383) * (5.0 / 384)
ACTIVE = slice(120, 260)  # 140 columns (1.8 s) of motion in the middle of the 5 s clip


def _signature(noise_halfwidth: float = 6.0, seed: int = 0) -> Signature:
    """Built as the image reader builds one (power image -> _normalise -> seed mean velocity -> noise_aware)."""
    rng = np.random.default_rng(seed)
    centre = np.zeros(T.size)
    k = np.arange(ACTIVE.stop - ACTIVE.start)
    centre[ACTIVE] = 2.0 * np.sin(np.pi * k / k[-1]) + 0.3  # 0.3 .. 2.3 m/s, never 0 while active
    amp = np.zeros(T.size)
    amp[ACTIVE] = 1.0
    line = amp * np.exp(-0.5 * ((V[:, None] - centre) / 0.25) ** 2)
    noise = 1e-5 * rng.exponential(size=(V.size, T.size)) * (np.abs(V) <= noise_halfwidth)[:, None]
    p, valid, total = _normalise(line + noise, DSPConfig().empty_floor)
    mv = mean_velocity(p, V, 6.0, DSPConfig(mean_velocity="seed"), periodic=False)
    sig = Signature(time=T, velocity=V, p_vt=p, mean_velocity=mv, range=np.zeros(0),
                    range_distribution=np.zeros((0, T.size)), valid=valid, power=total)
    return noise_aware(sig)


@pytest.fixture(scope="module")
def sig():
    return _signature()


def _finite(s: Signature) -> None:
    for name in ("p_vt", "mean_velocity", "power"):
        assert np.all(np.isfinite(getattr(s, name))), name
    assert s.p_vt.shape == (V.size, T.size) and s.valid.shape == (T.size,) and s.valid.dtype == bool
    assert np.all(s.mean_velocity[~s.valid] == 0)  # the reader's rule: no mean velocity where not valid
    np.testing.assert_allclose(s.p_vt.sum(axis=0)[s.power > 0], 1.0, atol=1e-9)


def test_fixture_signature_is_what_the_test_says(sig):
    assert sig.valid[ACTIVE].all() and sig.valid.sum() == ACTIVE.stop - ACTIVE.start
    assert np.abs(sig.mean_velocity[ACTIVE]).min() > 0.2


@pytest.mark.parametrize("k", [-60, -13, 1, 25, 100])
def test_shift_moves_the_mean_velocity_curve_by_k_columns(sig, k):
    dt = T[1] - T[0]
    s = shift_time(sig, k * dt)
    _finite(s)
    # the whole active span stays inside the clip for these k: the curve is the same, k columns later
    src = np.arange(ACTIVE.start - 5, ACTIVE.stop + 5)
    np.testing.assert_allclose(s.mean_velocity[src + k], sig.mean_velocity[src], atol=1e-9)
    np.testing.assert_array_equal(s.valid[src + k], sig.valid[src])
    # entering columns: copies of quiet columns, i.e. the noise floor (not zero, not NaN, not active)
    entered = np.arange(k) if k > 0 else np.arange(T.size + k, T.size)
    quiet = quiet_columns(sig)
    assert np.all(s.power[entered] > 0) and not s.valid[entered].any()
    assert s.power[entered].max() <= sig.power[quiet].max() * (1 + 1e-9)
    for j in entered[:3]:  # each is one of the quiet columns, exactly
        assert min(np.abs(s.p_vt[:, j] - sig.p_vt[:, q]).max() for q in quiet) < 1e-12


def test_quiet_columns_are_the_lowest_power_tenth(sig):
    q = quiet_columns(sig)
    assert q.size == round(0.1 * T.size) and np.all(np.diff(q) > 0)
    assert sig.power[q].max() <= np.sort(sig.power)[q.size - 1]


def test_identities(sig):
    for s in (shift_time(sig, 0.0), shift_time(sig, 0.004), stretch_time(sig, 1.0), scale_velocity(sig, 1.0),
              change_floor(sig, 0.0), apply(sig, Perturbation.make("none"))):
        for f in dataclasses.fields(Signature):
            a, b = getattr(s, f.name), getattr(sig, f.name)
            if isinstance(a, np.ndarray):
                np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("factor", [0.8, 0.9, 1.1, 1.25])
def test_velocity_scale_scales_the_mean_velocity(factor):
    # noise only within |v| <= 4.5 m/s so that no mass leaves the +-6 m/s axis at x1.25 (lost mass is lost)
    sig = _signature(noise_halfwidth=4.5)
    s = scale_velocity(sig, factor)
    _finite(s)
    np.testing.assert_array_equal(s.valid, sig.valid)  # column power kept: no mass lost
    # Tolerance: the rescaled density is exact (bin i spread uniformly over factor * its edges, centroid
    # factor * v_i); rebinning puts each output bin's mass at the bin centre, at most half a bin from its
    # centroid, so the mean moves by at most dv / 2 (0.019 m/s). Measured: below 1e-6 m/s for this smooth line.
    np.testing.assert_allclose(s.mean_velocity, factor * sig.mean_velocity, atol=DV / 2, rtol=0)


@pytest.mark.parametrize("factor", [0.75, 0.85, 1.15, 1.33])
def test_stretch_changes_the_active_duration_by_the_factor(sig, factor):
    s = stretch_time(sig, factor)
    _finite(s)
    n0, n1 = sig.valid.sum(), s.valid.sum()
    assert abs(n1 - factor * n0) <= 2, (n0, n1, factor * n0)
    # about the clip centre: the active span's midpoint stays put (within a column)
    def mid(v):
        return np.flatnonzero(v).mean()

    assert abs(mid(s.valid) - mid(sig.valid)) <= 1.0
    # the curve's peak speed is kept (a pace change, not a velocity change)
    assert s.mean_velocity.max() == pytest.approx(sig.mean_velocity.max(), abs=0.02)
    if factor < 1:  # columns whose source lies before/after the recording: noise floor, never zero
        assert np.all(s.power > 0)


@pytest.mark.parametrize("db", [5.0, 10.0])
def test_raising_the_floor_raises_the_quiet_columns_by_db(sig, db):
    s = change_floor(sig, db)
    _finite(s)
    q = quiet_columns(sig)
    gain = 10 * np.log10(s.power[q].mean() / sig.power[q].mean())
    assert gain == pytest.approx(db, abs=1e-9)  # the pedestal is (10^(db/10) - 1) x their mean pixel power
    # the peak rises by far less: the dynamic range shrinks by about db
    assert 10 * np.log10(s.power.max() / sig.power.max()) < 0.5


def test_lowering_the_floor_lowers_the_quiet_columns_at_most_by_db(sig):
    s = change_floor(sig, -5.0)
    _finite(s)
    q = quiet_columns(sig)
    drop = 10 * np.log10(s.power[q].mean() / sig.power[q].mean())
    assert -5.0 <= drop < -0.5
    np.testing.assert_array_equal(s.valid, sig.valid)


def test_grids_and_no_nan_anywhere(sig):
    assert len(DEFAULT_GRID) == 18 and DEFAULT_GRID[0].kind == "none"
    assert [p.value for p in DEFAULT_GRID if p.kind == "shift"] == [-1.5, -1.0, -0.5, 0.5, 1.0, 1.5]
    assert {p.kind for p in QUICK_GRID} == {"none", "shift", "stretch", "velocity", "floor"}
    assert len({p.name for p in DEFAULT_GRID}) == len(DEFAULT_GRID)
    empty = dataclasses.replace(sig, p_vt=np.zeros_like(sig.p_vt), power=np.zeros(T.size),
                                valid=np.zeros(T.size, bool), mean_velocity=np.zeros(T.size))
    for p in DEFAULT_GRID:
        _finite(apply(sig, p))
        _finite(apply(empty, p))
        assert motion_kept(empty, p) == 1.0  # nothing above the floor: nothing to lose, never NaN
        assert 0.0 <= motion_kept(sig, p) <= 1.0


def test_bad_values_are_input_errors(sig):
    for f, v in ((stretch_time, 0.0), (stretch_time, np.nan), (scale_velocity, -1.0), (change_floor, np.inf)):
        with pytest.raises(InputError):
            f(sig, v)
    with pytest.raises(InputError):
        Perturbation.make("rotate", 1.0)


def _centre() -> np.ndarray:
    """The fixture line's centre velocity [m/s] per active column (as `_signature` draws it)."""
    k = np.arange(ACTIVE.stop - ACTIVE.start)
    return 2.0 * np.sin(np.pi * k / k[-1]) + 0.3


def _moving_mass(lo: float, hi: float) -> np.ndarray:
    """Per active column, the line's mass (unit Gaussian of 0.25 m/s) at lo <= |v| < hi, from the normal CDF."""
    from scipy.stats import norm

    c = _centre()
    band = lambda a, b: norm.cdf((b - c) / 0.25) - norm.cdf((a - c) / 0.25)  # noqa: E731
    return band(lo, hi) + band(-hi, -lo)


def test_motion_kept_is_one_where_nothing_leaves_the_image(sig):
    for p in (Perturbation.make("none"), Perturbation.make("floor", 10.0), Perturbation.make("floor", -5.0),
              Perturbation.make("shift", 1.0), Perturbation.make("shift", -1.5),  # active span 1.56-3.39 s
              Perturbation.make("stretch", 1.33), Perturbation.make("stretch", 0.75),
              Perturbation.make("velocity", 1.25)):  # peak 2.3 m/s -> 2.9 + 4 sigma, inside +-6 m/s
        assert motion_kept(sig, p) == pytest.approx(1.0, abs=1e-3), p.name


def test_motion_kept_by_a_shift_that_cuts_the_active_span(sig):
    dt = T[1] - T[0]
    # the line is symmetric about the middle of its span: cutting its first half keeps half its motion power
    half = Perturbation.make("shift", -(ACTIVE.start + 70) * dt)
    assert motion_kept(sig, half) == pytest.approx(0.5, abs=0.005)
    gone = Perturbation.make("shift", -ACTIVE.stop * dt)
    assert motion_kept(sig, gone) < 1e-3  # what is left is the noise floor's positive residue


def test_motion_kept_by_a_large_stretch_and_velocity_scale(sig):
    moving = _moving_mass(0.5, np.inf)
    # x20 about the clip centre c = 191 keeps the columns within 191 +- 191/20 (182..200)
    j = np.arange(ACTIVE.start, ACTIVE.stop)
    inside = np.abs(j - 191) * 20 <= 191
    assert motion_kept(sig, Perturbation.make("stretch", 20.0)) == pytest.approx(
        moving[inside].sum() / moving.sum(), abs=0.01)
    # x3 keeps the bins that land within the +-6 m/s axis, |v| <= 2 m/s
    assert motion_kept(sig, Perturbation.make("velocity", 3.0)) == pytest.approx(
        _moving_mass(0.5, 2.0).sum() / moving.sum(), abs=0.02)
