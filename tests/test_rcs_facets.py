"""Amplitude calibration of the `facets` backend: sphere and plate RCS against closed forms.

The RCS is read back from the path set through the monostatic radar equation,
sigma = (4 pi)^3 R^4 |sum|^2 / lambda^2, with the radar R = 100 m away (far field of the 0.2 m targets:
2 D^2 / lambda = 6.5 m). Coherent sums use the synthesiser's phase exp(+j 2 pi f tau); the diffuse model
is checked on the power (incoherent) sum, the quantity Sionna's diffuse model defines. Diffuse facets carry
a fixed random phase each (`diffuse_phases`), so their coherent sum is random: it is checked through its
expectation over seeds (equal to the power sum); the PO checks use S = 0 (no diffuse part).
"""
import numpy as np
import pytest

from processing.radar.waveform import C0
from rtchannel.backends.facets import LinkSpec, mesh_paths
from rtchannel.backends.rcs import plate_mesh, sphere_mesh
from processing.radar.propagation import (lambertian_plate_rcs as diffuse_plate_rcs,
                                          lambertian_sphere_rcs as diffuse_sphere_rcs, optical_sphere_rcs,
                                          path_amplitude as rcs_amplitude, plate_po_rcs as po_plate_rcs)
from rtchannel.backends.surface_scattering import SurfaceMaterial, triangle_phase_integral
from rtchannel.scene.rt_scene import RTScene

F0 = 24.125e9
LAM = C0 / F0
R = 100.0
PEC_PO = SurfaceMaterial(eta=None, scattering_coefficient=0.0)  # pure physical optics
PEC_DIFFUSE = SurfaceMaterial(eta=None, scattering_coefficient=1.0)  # pure Lambertian diffuse, |Gamma| = 1


def _rcs(vertices, faces, material, po, seed=0, scene=None):
    scene = RTScene("free_space", faces, vertices, F0) if scene is None else scene
    tx = np.array([R, 0.0, 0.0])
    v = np.stack([vertices, vertices])
    ps = mesh_paths(scene, np.array([0.0, 0.1]), v, faces, None, [LinkSpec("l", tx, tx)], LAM, material,
                    po=po, seed=seed)["l"]
    g, tau = ps.gains[0], ps.delays[0]
    on = g != 0
    k = (4 * np.pi) ** 3 * R ** 4 / LAM ** 2
    coherent = k * abs(np.sum(g[on] * np.exp(2j * np.pi * F0 * tau[on]))) ** 2
    return coherent, k * np.sum(abs(g[on]) ** 2), int(on.sum())


def test_triangle_phase_integral_matches_fine_quadrature():
    rng = np.random.default_rng(3)
    corners = rng.normal(size=(3, 3)) * 0.02
    n = 120  # midpoint rule on n^2 sub-triangles: error ~ (|w| h)^2 / 24 with h = edge / n
    u, v = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    up = np.concatenate([np.column_stack([u.ravel() + 1 / 3, v.ravel() + 1 / 3])[(u + v).ravel() < n],
                         np.column_stack([u.ravel() + 2 / 3, v.ravel() + 2 / 3])[(u + v).ravel() < n - 1]]) / n
    pts = corners[0] + up[:, :1] * (corners[1] - corners[0]) + up[:, 1:] * (corners[2] - corners[0])
    area = 0.5 * np.linalg.norm(np.cross(corners[1] - corners[0], corners[2] - corners[0]))
    for scale in (0.0, 1e-3, 0.5, 5.0, 60.0):  # rad across the facet: Taylor branch, general branch
        w = rng.normal(size=3) * scale / 0.02
        exact = triangle_phase_integral(corners[None], w[None])[0]
        quad = area * np.mean(np.exp(1j * (pts - corners.mean(0)) @ w))
        assert abs(exact - quad) < 2e-3 * area  # quadrature error bound above, < 1e-3 at 60 rad


def test_plate_po_gives_textbook_broadside_rcs():
    v, f = plate_mesh(0.2, 0.2, 8)
    coherent, incoherent, n = _rcs(v, f, PEC_PO, po=True)
    # Exact for a flat plate; the residual is the wavefront curvature at 100 m (phase <= 0.1 rad at the
    # corners), which lowers the sum by < 0.1 %.
    assert n == len(f)
    assert coherent == pytest.approx(po_plate_rcs(0.04, LAM), rel=2e-3)


def test_plate_diffuse_gives_its_own_closed_form():
    v, f = plate_mesh(0.2, 0.2, 8)
    coherent, incoherent, _ = _rcs(v, f, PEC_DIFFUSE, po=False)
    assert incoherent == pytest.approx(diffuse_plate_rcs(0.04, 1.0), rel=1e-4)  # every facet at theta = 0
    # Without the random surface phase (seed None) the equal-phase diffuse facets add up N times the
    # power: the coherent sum would grow with the mesh resolution.
    coherent, _, _ = _rcs(v, f, PEC_DIFFUSE, po=False, seed=None)
    assert coherent == pytest.approx(len(f) * diffuse_plate_rcs(0.04, 1.0), rel=1e-3)


def test_plate_diffuse_coherent_power_expectation_is_the_power_sum():
    # With independent uniform phases E|sum a_f e^{j phi_f}|^2 = sum |a_f|^2 whatever the mesh. For N equal
    # terms |sum|^2 / (N a^2) has mean 1 and variance 1 - 1/N, so the mean of 100 seeds has a standard
    # deviation of 0.1: +-0.35 is 3.5 sigma. The power sum itself does not depend on the seed.
    v, f = plate_mesh(0.2, 0.2, 4)
    scene = RTScene("free_space", f, v, F0)
    runs = np.array([_rcs(v, f, PEC_DIFFUSE, po=False, seed=s, scene=scene)[:2] for s in range(100)])
    closed = diffuse_plate_rcs(0.04, 1.0)
    np.testing.assert_allclose(runs[:, 1], closed, rtol=1e-4)
    assert np.mean(runs[:, 0]) == pytest.approx(closed, rel=0.35)
    assert np.std(runs[:, 0]) > 0.5 * closed  # really random (an equal-phase sum would give 32 x closed)


def test_sphere_po_and_diffuse_closed_forms():
    a = 0.1
    v, f = sphere_mesh(a, 5)  # 20480 facets, edge 3.3 mm: 2 k x sagitta = 0.03 rad
    coherent, _, _ = _rcs(v, f, PEC_PO, po=True)
    # PO's sphere RCS ripples by ~1/(ka) = 2 % about pi a^2 (shadow-boundary term, ka = 50); faceting
    # (inscribed facets, 0.03 rad) adds ~1 %: 5 % tolerance.
    assert coherent == pytest.approx(optical_sphere_rcs(a), rel=0.05)
    _, incoherent, _ = _rcs(v, f, PEC_DIFFUSE, po=False)
    # Riemann sum of 4 cos^2(theta) dA over the lit hemisphere; the limb facets are the only error: 1 %.
    assert incoherent == pytest.approx(diffuse_sphere_rcs(a, 1.0), rel=0.01)


def test_rcs_amplitude_is_the_points_convention():
    sigma, r1, r2 = 0.7, 3.0, 4.5
    expected = LAM * np.sqrt(sigma) / ((4 * np.pi) ** 1.5 * r1 * r2)
    assert rcs_amplitude(sigma, r1, r2, LAM) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("mat", [SurfaceMaterial(eta=18.9 - 17.1j, scattering_coefficient=0.5, thickness=0.05),
                                 SurfaceMaterial(eta=5.2 - 0.4j, scattering_coefficient=0.3, thickness=0.002),
                                 SurfaceMaterial(eta=None, scattering_coefficient=1.0)])
def test_compiled_lambertian_gains_match_the_reference_maths(mat):
    from rtchannel.backends.surface_scattering import (diffuse_sqrt_rcs, gamma_magnitude, lambertian_gains,
                                                       slab_reflection, te_fraction)
    rng = np.random.default_rng(7)
    c = rng.normal(size=(500, 3))
    n = rng.normal(size=(500, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    area = rng.uniform(0, 1e-3, 500)
    p_a, p_b = np.array([3.0, 0.5, 1.1]), rng.normal(size=(500, 3)) * 3
    k_i = (c - p_a) / np.linalg.norm(c - p_a, axis=1, keepdims=True)
    u_b = (p_b - c) / np.linalg.norm(p_b - c, axis=1, keepdims=True)
    cos_i = np.clip(-np.sum(n * k_i, axis=1), 0, 1)
    r_te, r_tm = slab_reflection(cos_i, mat.eta, mat.thickness, LAM)
    ref = rcs_amplitude(diffuse_sqrt_rcs(mat, k_i, u_b, n, area, gamma_magnitude(r_te, r_tm, te_fraction(k_i, n))) ** 2,
                        np.linalg.norm(c - p_a, axis=1), np.linalg.norm(c - p_b, axis=1), LAM)
    got = lambertian_gains(mat, LAM, c, n, area, np.broadcast_to(p_a, c.shape), p_b)
    assert np.count_nonzero(ref) > 50
    np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-30)  # same maths, different evaluation order


@pytest.mark.parametrize("mat", [SurfaceMaterial(eta=18.9 - 17.1j, scattering_coefficient=0.5, thickness=0.05),
                                 SurfaceMaterial(eta=None, scattering_coefficient=0.0)])
def test_compiled_po_gains_match_the_reference_maths(mat):
    from rtchannel.backends.surface_scattering import co_polar_reflection, facet_gains, po_sqrt_rcs, slab_reflection
    rng = np.random.default_rng(11)
    n_el = 2000
    # Triangles from 0.1 mm (the Taylor branch of the integral) to 5 cm (many wavelengths) across.
    corners = rng.normal(size=(n_el, 1, 3)) + rng.normal(size=(n_el, 3, 3)) * 10 ** rng.uniform(-4, -1.3, (n_el, 1, 1))
    c = corners.mean(axis=1)
    cr = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area = 0.5 * np.linalg.norm(cr, axis=1)
    n = cr / (2 * area[:, None])
    p_a, p_b = np.array([3.0, 0.5, 1.1]), rng.normal(size=(n_el, 3)) * 3
    p_b[::3] = p_a  # monostatic ones take the compiled shortcut (bisector = incidence)
    ra, rb = np.linalg.norm(c - p_a, axis=1), np.linalg.norm(c - p_b, axis=1)
    k_i, u_b = (c - p_a) / ra[:, None], (p_b - c) / rb[:, None]
    half = -k_i + u_b
    cos_b = np.sum(n * half, axis=1) / np.linalg.norm(half, axis=1)
    rho = -co_polar_reflection(k_i, half / np.linalg.norm(half, axis=1)[:, None],
                               *slab_reflection(cos_b, mat.eta, mat.thickness, LAM))
    ref_po = (np.sqrt(1 - mat.scattering_coefficient ** 2) * LAM / ((4 * np.pi) ** 1.5 * ra * rb)
              * po_sqrt_rcs(corners, -k_i, u_b, n, rho, LAM))
    ref = facet_gains(mat, LAM, c, n, area, corners, p_a, p_b, False) + ref_po
    got = facet_gains(mat, LAM, c, n, area, corners, p_a, p_b, True)
    assert np.count_nonzero(ref_po) > 500
    # Same maths; the compiled integral uses exp[jp, jq] = exp(j (p + q) / 2) sinc((q - p) / 2), whose
    # rounding differs by ~1e-16 x the largest phase (~30 rad here) relative to the facet's area.
    np.testing.assert_allclose(got, ref, rtol=1e-11, atol=1e-12 * np.abs(ref).max())


def test_a_rough_material_needs_the_wavelength():
    # Found by mypy: without it Kirchhoff's S divided by None deep inside numpy (TypeError).
    from rtchannel.backends.surface_scattering import diffuse_sqrt_rcs

    down, up = np.array([[0.0, 0.0, -1.0]]), np.array([[0.0, 0.0, 1.0]])
    with pytest.raises(ValueError, match="a rough material needs the wavelength"):
        diffuse_sqrt_rcs(SurfaceMaterial(eta=5.2 - 0.4j, roughness_m=1e-3), down, up, up, np.ones(1), np.ones(1))


def test_propagation_formulas_have_one_home_and_read_back():
    """The radar equation's path coefficient and its read-back are inverses; the points backend and the
    compiled facets kernels use the same constant (one home: processing.radar.propagation)."""
    from processing.radar import propagation
    from rtchannel.backends import facet_kernels, points

    sigma, r1, r2 = 0.49, 2.7, 3.4
    a = propagation.path_amplitude(sigma, r1, r2, LAM)
    assert propagation.rcs_from_amplitude(a, r1, r2, LAM) == pytest.approx(sigma, rel=1e-12)
    assert propagation.received_power_ratio(sigma, r1, r2, LAM, 10.0, 2.0) == pytest.approx(20 * a ** 2, rel=1e-12)
    assert facet_kernels.FOUR_PI_1_5 is propagation.FOUR_PI_1_5
    pts = np.array([[[1.0, 2.0, 1.0]]])
    assert points.link_delays(pts, np.zeros(3), np.array([3.0, 0, 1.1]))[0, 0] == pytest.approx(
        (np.sqrt(6) + np.sqrt(4 + 4 + 0.01)) / 299792458.0, rel=1e-14)
