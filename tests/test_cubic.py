"""processing.cubic (and pose's yaw matrix): the numpy routes that spare a points simulation SciPy's
interpolate and spatial packages compute exactly SciPy's values, bit for bit (the same operations in the same
order, so the tolerance is zero), and a not-a-knot spline through a cubic is that cubic."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline, CubicSpline, PchipInterpolator
from scipy.spatial.transform import Rotation
from scipy.special import logsumexp as scipy_logsumexp

from processing.cubic import HermiteSpline, hermite_spline, logsumexp, not_a_knot_spline, pchip_slopes


def _same(a, b) -> bool:
    """Bitwise equal, signs of zeros included."""
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a, b) and np.array_equal(
        np.signbit(a), np.signbit(b))


def _cases(seed: int, n_cases: int = 40):
    rng = np.random.default_rng(seed)
    for c in range(n_cases):
        n = int(rng.integers(4, 200))
        x = np.arange(n) / 30.0 + rng.uniform(0, 5) if c % 2 else np.cumsum(rng.uniform(1e-3, 1.0, n))
        y = rng.standard_normal((n, int(rng.integers(1, 25)))) * 10.0 ** rng.uniform(-9, 1)
        if c % 5 == 0:
            y = y[:, 0]
        # beyond both ends (extrapolated), inside, and exactly on every knot (the last one closes its piece)
        u = np.concatenate([rng.uniform(x[0] - 1, x[-1] + 1, 300), x])
        yield rng, x, y, u


def test_hermite_spline_is_scipys():
    for rng, x, y, u in _cases(1):
        dydx = rng.standard_normal(y.shape)
        ours, theirs = HermiteSpline(x, y, dydx), CubicHermiteSpline(x, y, dydx, axis=0)
        for nu in (0, 1):
            assert _same(ours(u, nu), theirs(u, nu))
        assert _same(ours.derivative()(u), theirs.derivative()(u))
        assert _same(hermite_spline(x, y, dydx, u[:7].reshape(7, 1)), theirs(u[:7].reshape(7, 1)))


def test_not_a_knot_spline_is_scipys():
    for _, x, y, u in _cases(2):
        ours, theirs = not_a_knot_spline(x, y), CubicSpline(x, y, axis=0)
        for nu in (0, 1):
            assert _same(ours(u, nu), theirs(u, nu))
        assert _same(ours.derivative()(u), theirs.derivative()(u))
    x = np.array([0.0, 0.4, 1.0])  # 3 knots: SciPy's own special case (a parabola)
    y = np.array([[1.0, 2.0], [0.5, -1.0], [2.0, 0.0]])
    assert _same(not_a_knot_spline(x, y)(x[:, None] * 0.7), CubicSpline(x, y)(x[:, None] * 0.7))


def test_not_a_knot_spline_through_a_cubic_is_that_cubic():
    # not-a-knot: the third derivative is continuous at the second and the last-but-one knot, so a cubic's
    # samples give the cubic itself (de Boor, A Practical Guide to Splines, ch. IV); 1e-12 of the values'
    # scale: a tridiagonal solve over 20 knots loses a few ulps per row, far from a wrong slope's O(1e-2)
    x = np.cumsum(np.linspace(0.05, 0.3, 20))
    p = np.poly1d([0.7, -1.3, 0.2, 4.0])
    s = not_a_knot_spline(x, p(x))
    u = np.linspace(x[0] - 0.2, x[-1] + 0.2, 501)
    assert np.allclose(s(u), p(u), rtol=0, atol=1e-12 * np.abs(p(u)).max())
    assert np.allclose(s(u, 1), p.deriv()(u), rtol=0, atol=1e-12 * np.abs(p.deriv()(u)).max())


def test_pchip_slopes_are_scipys_inside():
    for _, x, y, _u in _cases(3):
        y = np.round(y / np.abs(y).max() * 3)  # flat runs and sign changes: the zero-slope cases
        theirs = PchipInterpolator(x, y).derivative()(x)
        ours = pchip_slopes(x, y)
        assert _same(ours[1:-1], theirs[1:-1])
        assert not ours[[0, -1]].any()  # the ends: 0 (the key-frame curves hold their end values)


@pytest.mark.parametrize("axis", [0, 1])
def test_logsumexp_is_scipys(axis):
    rng = np.random.default_rng(4)
    for k in (1, 2, 5):
        a = rng.standard_normal((k, 50)) * 30
        a[-1, :10] = a[0, :10]  # ties: every maximal element is taken out of the sum
        a = a if axis == 0 else a.T
        assert _same(logsumexp(a, axis=axis), scipy_logsumexp(a, axis=axis))


def test_yaw_matrix_is_scipys():
    from rtchannel.motion.pose import _yaw_matrix

    for a in [0.0, -0.0, np.pi, -np.pi / 2, 1e-300, *np.random.default_rng(5).uniform(-70, 70, 500)]:
        assert np.array_equal(_yaw_matrix(a), Rotation.from_euler("z", a).as_matrix())


def _scipy_routes(monkeypatch):
    """Put SciPy's interpolants back where processing.cubic's now serve (the routes before this change)."""
    import processing.synthesis.exact as exact
    import rtchannel.motion.kinematics as km
    import rtchannel.motion.pose as pose

    monkeypatch.setattr(km, "hermite_spline", lambda x, y, d, u: CubicHermiteSpline(x, y, d)(u))
    def pchip_slopes_scipy(x, y):
        slopes = PchipInterpolator(x, y).derivative()(x)
        slopes[[0, -1]] = 0.0  # as kinematics.keyframes did
        return slopes

    monkeypatch.setattr(km, "pchip_slopes", pchip_slopes_scipy)
    monkeypatch.setattr(km, "logsumexp", scipy_logsumexp)
    monkeypatch.setattr(pose, "_yaw_matrix", lambda a: Rotation.from_euler("z", a).as_matrix())
    monkeypatch.setattr(exact, "HermiteSpline", lambda x, y, d: CubicHermiteSpline(x, y, d, axis=0))
    monkeypatch.setattr(exact, "not_a_knot_spline", lambda x, y: CubicSpline(x, y, axis=0))


@pytest.mark.parametrize("activity", ["walk", "fall", "sit", "stand", "pick"])
def test_procedural_motions_are_the_scipy_routes(activity, monkeypatch):
    from rtchannel.motion.pose import Motion

    new = Motion.procedural(activity, heading_deg=37.0, seed=3)
    _scipy_routes(monkeypatch)
    old = Motion.procedural(activity, heading_deg=37.0, seed=3)
    assert _same(new.positions, old.positions) and _same(new.rotations, old.rotations)


def test_points_signatures_are_the_scipy_routes(monkeypatch):
    # the points backend's paths carry no delay rates: the synthesiser's not-a-knot delay spline
    from rtchannel.motion.pose import Motion
    from rtchannel.pipeline import simulate

    new = simulate(Motion.procedural("walk", duration=1.5))
    _scipy_routes(monkeypatch)
    old = simulate(Motion.procedural("walk", duration=1.5))
    for name, sig in new.signatures.items():
        ref = old.signatures[name]
        assert _same(sig.p_vt, ref.p_vt) and _same(sig.mean_velocity, ref.mean_velocity)
        assert _same(sig.range_distribution, ref.range_distribution) and _same(sig.power, ref.power)
