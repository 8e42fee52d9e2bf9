"""Partial shadows of the clutter (issue 37 part 3): single knife-edge diffraction (ITU-R P.526) with the edge
found among the body's vertices."""
import numpy as np
import pytest
from scipy.special import fresnel as fresnel_integrals

from rtchannel.backends.knife_edge import (NU_MAX, fresnel_nu, itu_j_db, knife_edge_amplitude, segment_amplitudes,
                                           shadow_nu)

LAM = 299792458.0 / 24.125e9
POS = np.array([0.0, 0.0, 1.0])
TARGET = np.array([6.0, 0.0, 1.0])  # a 6 m segment along x
D1 = 2.5  # the screen's distance from the antenna [m]


def exact_loss_db(nu):
    """Knife-edge loss from the Fresnel integrals: E/E0 = (1 + j)/2 int_nu^inf exp(-j pi t^2 / 2) dt."""
    s, c = fresnel_integrals(nu)
    return -20 * np.log10(np.abs((1 + 1j) / 2 * ((0.5 - c) - 1j * (0.5 - s))))


def half_plane(edge_height_m: float, spacing: float = 0.004, size: float = 0.6) -> np.ndarray:
    """Vertices [1, N, 3] of a half-plane screen across the segment at x = D1 filling z <= 1 + edge_height_m (a
    grid whose top row is the edge)."""
    y = np.arange(-size, size + 1e-9, spacing)
    z = 1.0 + edge_height_m - np.arange(0.0, 2 * size, spacing)
    yy, zz = np.meshgrid(y, z)
    return np.column_stack([np.full(yy.size, D1), yy.ravel(), zz.ravel()])[None]


def _amplitude(edge_height_m, blocked):
    v = half_plane(edge_height_m)
    return segment_amplitudes(POS, TARGET[None], v, np.array([0]), np.array([blocked]), LAM)[0]


def test_itu_approximation_against_the_fresnel_integrals():
    """ITU-R P.526's J(nu) is within 0.5 dB of the exact loss for nu > -0.7 (the approximation's stated use),
    and 0 dB at -0.78 (its cut-off), 6.0 dB at grazing, 20.5 dB at nu = 2.4."""
    nu = np.linspace(-0.7, 5.0, 300)
    assert np.abs(itu_j_db(nu) - exact_loss_db(nu)).max() < 0.5
    assert float(itu_j_db(-0.78)) == pytest.approx(0.0, abs=0.02)
    assert float(knife_edge_amplitude(0.0)) == pytest.approx(0.5, abs=0.002)  # exact 0.5; ITU: 6.03 dB
    assert float(itu_j_db(2.4)) == pytest.approx(20.5, abs=0.1)
    assert float(exact_loss_db(2.4)) == pytest.approx(20.5, abs=0.5)


def test_half_plane_on_the_line_of_sight_gives_half_the_field():
    """An edge exactly on the segment, whether the ray cast counts it as blocking or not: amplitude 0.5 within
    0.01 (the ITU curve gives 0.4995; the vertex grid's row is on the line of sight, so nu = 0 exactly)."""
    assert _amplitude(0.0, blocked=False) == pytest.approx(0.5, abs=0.01)
    assert _amplitude(0.0, blocked=True) == pytest.approx(0.5, abs=0.01)


def test_clearance_of_nu_minus_078_is_no_loss_and_nu_24_is_20_db():
    """Screen edge below the segment by h (clear) and above it (blocked), nu from the geometry
    (nu = h sqrt(2 (d1 + d2) / (lambda d1 d2))): -0.78 gives 0 dB (within 0.1 dB), 2.4 gives J = 20.5 dB within
    0.3 dB (the vertex grid's 4 mm rows quantise h: 0.04 in nu, 0.2 dB at that slope)."""
    d2 = np.linalg.norm(TARGET - POS) - D1
    per_nu = 1.0 / float(fresnel_nu(1.0, D1, d2, LAM))  # metres of edge height per unit of nu
    clear = _amplitude(-0.78 * per_nu, blocked=False)
    assert 20 * np.log10(clear) == pytest.approx(0.0, abs=0.1)
    deep = _amplitude(2.4 * per_nu, blocked=True)
    assert -20 * np.log10(deep) == pytest.approx(20.5, abs=0.3)


def test_the_field_goes_smoothly_from_clear_to_deep_shadow():
    """Sweeping the edge from nu = -1.2 to 4.5 the segment in 5 mm steps: the amplitude never
    rises, equals the ITU curve at the geometric nu (capped at NU_MAX) (the grid's top row is the edge, so the
    estimate is exact up to rounding: 1e-9) and ends at J(NU_MAX)."""
    d2 = np.linalg.norm(TARGET - POS) - D1
    per_nu = 1.0 / float(fresnel_nu(1.0, D1, d2, LAM))
    hs = np.arange(-1.2 * per_nu, 4.5 * per_nu, 0.005)
    amp = np.array([_amplitude(h, blocked=h > 0) for h in hs])
    assert amp[0] == pytest.approx(1.0, abs=1e-12)
    assert np.all(np.diff(amp) <= 1e-12)
    want = knife_edge_amplitude(np.minimum(fresnel_nu(hs, D1, d2, LAM), NU_MAX))
    np.testing.assert_allclose(amp, want, rtol=0, atol=1e-9)
    assert amp[-1] == pytest.approx(float(knife_edge_amplitude(NU_MAX)), rel=1e-9)


def test_nu_estimates_many_segments_and_frames_at_once():
    """Vectorised: segments to several targets and two frames, each nu as for the single segment."""
    v = np.concatenate([half_plane(0.0), half_plane(0.05)])
    targets = np.array([TARGET, TARGET + [0.0, 0.0, -0.02], TARGET])
    frame = np.array([0, 0, 1])
    hit = np.array([False, True, True])
    nu = shadow_nu(POS, targets, v, frame, hit, LAM)
    one = [shadow_nu(POS, targets[i:i + 1], v[frame[i]:frame[i] + 1], np.array([0]), hit[i:i + 1], LAM)[0]
           for i in range(3)]
    np.testing.assert_allclose(nu, one, rtol=0, atol=1e-12)
    assert nu[0] == pytest.approx(0.0, abs=1e-9) and nu[1] > 0 and nu[2] > nu[1]


def test_a_large_sphere_seen_through_its_silhouette():
    """A 0.5 m sphere (mesh, triangles given: its silhouette from the antenna is used) 2.5 m along a 6 m
    segment, its radius 3.7 Fresnel radii (r1 = 0.134 m): grazing its edge gives ~half the field (the edge is
    curved and sampled by 2.9 cm facets: a vertex up to ~5 mm off the tangent, 0.05 in nu, 0.03 in amplitude);
    through its centre the shadow is at the cap, J(NU_MAX); 0.1 m clear of it (nu = -1.05) no loss."""
    from rtchannel.backends.rcs import sphere_mesh

    v, f = sphere_mesh(0.5, 4)
    radius = 0.5 * np.cos(np.pi / 5 / 16)  # the facets' inscribed radius is ~0.2 % short of 0.5 m
    centre = np.array([D1, 0.0, 1.0])
    cases = [(radius, False, 0.5, 0.03), (0.0, True, float(knife_edge_amplitude(NU_MAX)), 1e-9),
             (radius + 0.1, False, 1.0, 1e-9)]
    for offset, hit, want, tol in cases:
        verts = (v + centre - [0.0, 0.0, offset])[None]  # the segment passes `offset` above the centre
        amp = segment_amplitudes(POS, TARGET[None], verts, np.array([0]), np.array([hit]), LAM, faces=f)[0]
        assert amp == pytest.approx(want, abs=tol), offset
