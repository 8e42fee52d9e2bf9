"""Consistent surfaces (issue 37 part 3): the link's polarisation in the wall, floor and PO reflections, one
Kirchhoff roughness per wall for the clutter and the body's bounces, and the compiled kernels pinned to the
numpy reference for both polarisations and rough surfaces."""
import numpy as np
import pytest

from processing.radar.antenna import GaussianBeam, Isotropic, link_polarization
from processing.radar.waveform import C0
from processing.errors import InputError
from rtchannel.backends.facets import LinkSpec, mesh_paths
from rtchannel.backends.rcs import sphere_mesh
from rtchannel.backends.surface_scattering import (SurfaceMaterial, co_polar_reflection, facet_gains, fresnel,
                                                   slab_reflection, wall_factor)
from rtchannel.backends.wall_images import PlanarWall
from rtchannel.scene.material import kirchhoff_scattering, kirchhoff_specular
from rtchannel.scene.rt_scene import RTScene


def concrete(f_hz: float) -> complex:
    """ITU-R P.2040 concrete (1-100 GHz): eps' = 5.24, sigma = 0.0462 f_GHz^0.7822 S/m."""
    sigma = 0.0462 * (f_hz / 1e9) ** 0.7822
    return complex(5.24, -sigma / (2 * np.pi * f_hz * 8.8541878128e-12))


PEC_PO = SurfaceMaterial(eta=None, scattering_coefficient=0.0)  # pure physical optics: a PEC sphere's glint


def _floor(eta, roughness=0.0):
    big = 200.0
    return PlanarWall("floor", point=np.zeros(3), normal=np.array([0.0, 0.0, 1.0]),
                      polygon=np.array([[-big, -big, 0], [big, -big, 0], [big, big, 0], [-big, big, 0]], float),
                      relative_permittivity=eta, thickness=0.0, roughness_m=roughness)


def _side_wall(eta):
    big = 200.0
    return PlanarWall("side", point=np.zeros(3), normal=np.array([0.0, 1.0, 0.0]),
                      polygon=np.array([[-big, 0, -big], [big, 0, -big], [big, 0, big], [-big, 0, big]], float),
                      relative_permittivity=eta, thickness=0.0, roughness_m=0.0)


def _image_to_direct_db(f_hz, radius, centre, tx_list, wall):
    """{(tx index, pol): 20 log10 |sum of tx-image paths| / |sum of direct paths|} of a PEC sphere (PO) at
    `centre`, for links tx -> sphere -> rx with rx 5 cm beside tx, both antennas "V" or both "H"."""
    lam = C0 / f_hz
    v, f = sphere_mesh(radius, 5)
    v = v + centre
    scene = RTScene("free_space", f, v, f_hz, sionna=False)
    links = []
    for i, tx in enumerate(tx_list):
        rx = np.asarray(tx) + [0.0, 0.0, 0.05] if wall.normal[2] < 0.5 else np.asarray(tx) + [0.0, 0.05, 0.0]
        for pol in ("V", "H"):
            ant = Isotropic(polarization=pol)
            links.append(LinkSpec(f"{i}{pol}", np.asarray(tx, float), rx, ant, ant))
    ps = mesh_paths(scene, np.array([0.0, 0.1]), np.stack([v, v]), f, None, links, lam, PEC_PO, walls=[wall],
                    po=True, seed=None, double_bounce=False)
    out = {}
    for link in links:
        p = ps[link.name]
        kind = p.ids // len(f)
        phasor = p.gains[0] * np.exp(2j * np.pi * f_hz * np.nan_to_num(p.delays[0]))
        direct, image = abs(phasor[kind == 0].sum()), abs(phasor[kind == 1].sum())
        out[(int(link.name[0]), link.name[1])] = 20 * np.log10(image / direct)
    return out


@pytest.mark.parametrize("f_hz, radius", [(5.8e9, 0.25), (24.125e9, 0.1)])
def test_floor_image_of_a_point_scatterer_is_gamma_te_for_h_and_gamma_tm_for_v(f_hz, radius):
    """A PEC sphere (PO; ka = 30 and 50, far field: 2 D^2 / lambda = 10 m and 6.5 m < 30 m) 1 m above a concrete
    floor (ITU-R P.2040), seen from 30 m at grazing angles of 10 and 30 deg at the floor: its floor-image path
    tx' -> sphere -> rx is the direct path times Gamma (at the reflection point) times the spreading ratio
    |s - tx| / |s - tx'|, a sphere scattering pi a^2 at every bistatic angle (geometrical optics). The plane of
    incidence is vertical, so Gamma is r_TM for vertical and r_TE for horizontal polarisation.

    Tolerances. PO's sphere return departs from pi a^2 as the bistatic angle beta of the image path (~2x the
    grazing angle) grows (over a perfect mirror, measured: -0.17 dB at beta = 20 deg, +0.37 dB at 60 deg), plus
    its ~1/(ka) ripple: the full ratio is held to 0.5 dB at 10 deg grazing. At both angles the reflection alone,
    the ratio over concrete less the ratio over a perfect mirror (same geometry, |Gamma| = 1), must be
    20 log10 |Gamma| within 0.1 dB, Gamma taken at the grazing angle of the glint (the sphere's specular point
    for tx' -> sphere -> rx, a from the centre along the bisector: 0.2 deg steeper than the centre's at 30 deg,
    which is 0.2 dB of |r_TM| near Brewster's angle, 24 deg grazing); what is left is the Fresnel coefficient's
    variation over the glint's first Fresnel zone (sqrt(lambda a / 2) = 8 cm at 5.8 GHz: +-0.1 deg)."""
    eta = concrete(f_hz)
    centre = np.array([0.0, 0.0, 1.0])
    txs, gamma, spread = [], {}, {}
    for i, graze in enumerate((10.0, 30.0)):
        d = 30.0
        tx = np.array([d, 0.0, d * np.tan(np.radians(graze)) - centre[2]])  # tx' -> centre meets the floor at `graze`
        txs.append(tx)
        img = tx * [1, 1, -1]
        u = [(p - centre) / np.linalg.norm(p - centre) for p in (img, tx)]
        glint = centre + radius * (u[0] + u[1]) / np.linalg.norm(u[0] + u[1])
        sin_g = (glint[2] - img[2]) / np.linalg.norm(glint - img)  # tx' -> glint crosses the floor at this angle
        r_te, r_tm = fresnel(sin_g, eta)
        gamma[(i, "V")], gamma[(i, "H")] = 20 * np.log10(abs(r_tm)), 20 * np.log10(abs(r_te))
        spread[i] = 20 * np.log10(np.linalg.norm(centre - tx) / np.linalg.norm(centre - img))
    got = _image_to_direct_db(f_hz, radius, centre, txs, _floor(eta))
    mirror = _image_to_direct_db(f_hz, radius, centre, txs, _floor(None))
    for (i, pol), g_db in gamma.items():
        assert got[(i, pol)] - mirror[(i, pol)] == pytest.approx(g_db, abs=0.1), (i, pol)
        if i == 0:
            assert got[(i, pol)] == pytest.approx(g_db + spread[i], abs=0.5), pol
    # the two polarisations differ by far more than the tolerance: the test tells them apart
    assert min(got[(i, "H")] - got[(i, "V")] for i in range(2)) > 3.0


def test_vertical_wall_in_a_horizontal_geometry_swaps_the_roles():
    """The same sphere and a vertical concrete wall, antennas and sphere at one height: the plane of incidence is
    horizontal, so vertical polarisation is TE (r_TE) and horizontal TM (r_TM); 24 GHz, grazing 10 deg (beta =
    20 deg: 0.5 dB as above)."""
    f_hz, graze = 24.125e9, 10.0
    eta = concrete(f_hz)
    centre = np.array([0.0, 1.0, 1.0])
    d = 30.0
    tx = np.array([d, d * np.tan(np.radians(graze)) - centre[1], 1.0])
    r_te, r_tm = fresnel(np.sin(np.radians(graze)), eta)
    spread = np.linalg.norm(centre - tx) / np.linalg.norm(centre - tx * [1, -1, 1])
    got = _image_to_direct_db(f_hz, 0.1, centre, [tx], _side_wall(eta))
    assert got[(0, "V")] == pytest.approx(20 * np.log10(abs(r_te) * spread), abs=0.5)
    assert got[(0, "H")] == pytest.approx(20 * np.log10(abs(r_tm) * spread), abs=0.5)
    assert got[(0, "V")] - got[(0, "H")] > 3.0


def test_horizontal_floor_reflection_is_r_te_and_pec_gives_minus_one():
    """Horizontally polarised rays over the floor: the field is across the (vertical) plane of incidence, so the
    co-polar coefficient is r_te at every angle and azimuth; over a conductor -1 (a horizontal dipole's image is
    in antiphase)."""
    for angle, az in ((20.0, 0.0), (70.0, 40.0), (89.0, 130.0)):
        a, b = np.radians(angle), np.radians(az)
        k = np.array([np.sin(a) * np.cos(b), np.sin(a) * np.sin(b), -np.cos(a)])
        r_te, r_tm = fresnel(np.cos(a), concrete(24.125e9))
        assert co_polar_reflection(k, [0, 0, 1.0], r_te, r_tm, "H") == pytest.approx(r_te, abs=1e-12)
        assert co_polar_reflection(k, [0, 0, 1.0], -1.0, 1.0, "H") == pytest.approx(-1.0, abs=1e-12)


# ---------------------------------------------------------------------------------------------- roughness
def test_rough_image_path_is_the_kirchhoff_factor_at_normal_and_oblique_incidence():
    """A wall of rms height 1 mm at 24.125 GHz scales a specular reflection by exp(-(4 pi sigma cos / lambda)^2 / 2):
    at normal incidence (4 pi 1e-3 / 0.012427)^2 = 1.0226, factor 0.5997 (-4.44 dB); at 60 deg (cos 0.5) 0.8800
    (-1.11 dB). The hand values have 4 digits: 5e-5; the phase is untouched (1e-12)."""
    lam = C0 / 24.125e9
    eta = concrete(24.125e9)
    for cos_i, want in ((1.0, 0.5997), (0.5, 0.8800)):
        k = np.array([[np.sqrt(1 - cos_i ** 2), 0.0, -cos_i]])
        for pol in ("V", "H"):
            rough = wall_factor(_floor(eta, 1e-3), np.array([cos_i]), k, lam, pol)
            smooth = wall_factor(_floor(eta, 0.0), np.array([cos_i]), k, lam, pol)
            assert abs(rough[0] / smooth[0]) == pytest.approx(want, abs=5e-5)
            assert np.angle(rough[0] / smooth[0]) == pytest.approx(0.0, abs=1e-12)
    assert kirchhoff_specular(2.0, 1e-3, lam) == pytest.approx(0.5997, abs=5e-5)


def test_diffuse_and_specular_fractions_add_up_to_the_reflected_power():
    """S^2 + rho_s^2 = 1 at every incidence (the Kirchhoff split); S at normal incidence is the old clutter's
    0.80 at 24 GHz and 0.24 at 5.8 GHz for 1 mm (by hand: sqrt(1 - exp(-(4 pi 1e-3 / lambda)^2))); a smooth
    material has S = 0."""
    cos = np.linspace(0.0, 1.0, 11)
    for lam in (C0 / 24.125e9, C0 / 5.8e9):
        s, rho = kirchhoff_scattering(cos, 1e-3, lam), kirchhoff_specular(2 * cos, 1e-3, lam)
        np.testing.assert_allclose(s ** 2 + rho ** 2, 1.0, rtol=0, atol=1e-14)
    assert kirchhoff_scattering(1.0, 1e-3, C0 / 24.125e9) == pytest.approx(0.80, abs=0.005)
    assert kirchhoff_scattering(1.0, 1e-3, C0 / 5.8e9) == pytest.approx(0.24, abs=0.005)
    mat = SurfaceMaterial(eta=concrete(24e9), roughness_m=0.0)
    assert mat.kernel_surface() == (0.0, 0.0) and mat.normal_scattering_coefficient(0.0124) == 0.0


def test_a_rough_patch_splits_its_power_between_diffuse_and_po_as_the_image_factor_says():
    """One large flat patch seen at normal incidence by a monostatic radar (far field): its PO return is the
    smooth patch's times rho_s (the factor of an image reflection at the same incidence) and its diffuse power
    S^2 times the S = 1 Lambertian one: the clutter and the body's bounces see the same wall."""
    lam = C0 / 24.125e9
    eta = concrete(24.125e9)
    corners = np.array([[[0.0, -0.2, -0.2], [0.0, 0.2, -0.2], [0.0, 0.0, 0.2]]])
    c, n = corners.mean(axis=1), np.array([[1.0, 0.0, 0.0]])
    area = np.array([0.5 * 0.4 * 0.4])
    tx = c[0] + [30.0, 0.0, 0.0]  # on the patch's normal: normal incidence exactly
    rough = SurfaceMaterial(eta=eta, roughness_m=1e-3)
    smooth = SurfaceMaterial(eta=eta, roughness_m=0.0)
    full = SurfaceMaterial(eta=eta, scattering_coefficient=1.0)
    def po(m):
        return (facet_gains(m, lam, c, n, area, corners, tx, tx, True)
                - facet_gains(m, lam, c, n, area, corners, tx, tx, False))

    rho = kirchhoff_specular(2.0, 1e-3, lam)
    assert abs(po(rough)[0]) == pytest.approx(rho * abs(po(smooth)[0]), rel=1e-12)
    s = kirchhoff_scattering(1.0, 1e-3, lam)
    d_rough = facet_gains(rough, lam, c, n, area, corners, tx, tx, False)
    assert abs(d_rough[0]) == pytest.approx(s * abs(facet_gains(full, lam, c, n, area, corners, tx, tx, False)[0]),
                                            rel=1e-12)
    wf = wall_factor(_floor(eta, 1e-3), np.array([1.0]), np.array([[0.0, 0.0, -1.0]]), lam)
    assert abs(wf[0]) / abs(fresnel(1.0, eta)[0]) == pytest.approx(rho, rel=1e-12)


def test_scene_walls_and_clutter_patches_share_one_roughness_per_wall():
    from rtchannel.backends.clutter import scene_patches
    from rtchannel.backends.rcs import sphere_mesh as body

    v, f = body(0.1, 1)
    scene = RTScene("room", f, v + [0, 0, 1.0], 24.125e9, sionna=False, roughness_m={"floor": 3e-3, "wall_xp": 0.0})
    rough = {w.name: w.roughness_m for w in scene.walls}
    assert rough["floor"] == 3e-3 and rough["wall_xp"] == 0.0 and rough["wall_yn"] == 1e-3
    p = scene_patches(scene, 24.125e9, 0.5)
    names = [name for name, _, _ in scene.static_meshes]
    by_shape = {names[k]: set(p.roughness[p.shape == k]) for k in np.unique(p.shape)}
    assert by_shape["floor"] == {3e-3} and by_shape["wall_xp"] == {0.0} and by_shape["wall_yn"] == {1e-3}
    floor = next(w for w in scene.walls if w.name == "floor")
    assert scene.material("floor").roughness_m == 3e-3 == floor.material.roughness_m
    with pytest.raises(InputError, match="roughness_m"):
        RTScene("room", f, v + [0, 0, 1.0], 24.125e9, sionna=False, roughness_m=-1.0)


# ------------------------------------------------------------------------------ compiled against numpy
@pytest.mark.parametrize("pol", ["V", "H"])
@pytest.mark.parametrize("mat", [SurfaceMaterial(eta=concrete(24e9), roughness_m=1e-3, thickness=0.2),
                                 SurfaceMaterial(eta=18.9 - 17.1j, scattering_coefficient=0.5, thickness=0.05),
                                 SurfaceMaterial(eta=concrete(5.8e9), roughness_m=0.0)])
def test_compiled_gains_equal_the_numpy_reference_for_both_polarisations(mat, pol):
    rng = np.random.default_rng(7)
    n_e = 400
    corners = rng.normal(size=(n_e, 3, 3)) * 0.03 + rng.normal(size=(n_e, 1, 3))
    c = corners.mean(axis=1)
    cr = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    n = cr / np.linalg.norm(cr, axis=1, keepdims=True)
    area = 0.5 * np.linalg.norm(cr, axis=1)
    p_a, p_b = np.array([4.0, 1.0, 1.2]), np.array([3.0, -2.0, 0.7])
    n = n * np.sign(np.einsum("ij,ij->i", n, p_a - c))[:, None]
    ok = np.einsum("ij,ij->i", n, p_b - c) > 0
    args = (mat, 0.0124, c[ok], n[ok], area[ok], corners[ok], p_a, p_b, True)
    got = facet_gains(*args, polarization=pol)
    ref = facet_gains(*args, polarization=pol, compiled=False)
    np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-16)
    if pol == "H" and mat.roughness_m is None:  # the polarisation reaches the kernel: H differs from V
        assert np.abs(got - facet_gains(*args, polarization="V")).max() > 1e-3 * np.abs(got).max()


@pytest.mark.parametrize("pol", ["V", "H"])
def test_compiled_wall_factor_equals_the_reference_for_both_polarisations(pol):
    w = PlanarWall("w", point=np.zeros(3), normal=np.array([0.6, 0.0, 0.8]), polygon=np.zeros((3, 3)),
                   relative_permittivity=5.24 - 0.4j, thickness=0.2, roughness_m=1.5e-3)
    rng = np.random.default_rng(2)
    k = rng.normal(size=(500, 3))
    k /= np.linalg.norm(k, axis=1, keepdims=True)
    cos_w = np.abs(k @ w.normal)
    ref = np.conj(co_polar_reflection(k, w.normal, *slab_reflection(cos_w, w.relative_permittivity, 0.2, 0.0124), pol))
    ref = ref * kirchhoff_specular(2 * cos_w, 1.5e-3, 0.0124)
    np.testing.assert_allclose(wall_factor(w, cos_w, k, 0.0124, pol), ref, rtol=0, atol=1e-14)


# -------------------------------------------------------------------------------------------- antennas
def test_polarization_is_validated_and_a_link_must_be_co_polarised():
    from pydantic import ValidationError

    assert Isotropic().polarization == "V"
    with pytest.raises(ValidationError, match="polarization must be 'V'"):
        Isotropic(polarization="X")
    horn = GaussianBeam(boresight=(1, 0, 0), hpbw_az_deg=30, hpbw_el_deg=30)
    assert link_polarization(horn, None) == "V"
    h = horn.model_copy(update={"polarization": "H"})
    assert link_polarization(h, h) == "H"
    with pytest.raises(InputError, match="same polarization"):
        link_polarization(horn, h)
    from processing.radar.antenna import directivity_dbi

    assert directivity_dbi(h) == directivity_dbi(horn)  # the power pattern does not depend on it


def test_radars_of_different_polarisations_share_one_facets_run():
    """One backend run with a "V" and an "H" link (two radars of a dataset item): each gets its own floor
    reflection; the direct paths (Lambertian skin, Gamma by polarisation split) differ too."""
    from rtchannel.motion.procedural import generate
    from rtchannel.radar import Link, RadarConfig
    from rtchannel.backends.facets import facet_paths

    m = generate("walk", duration=0.3)
    h = Isotropic(polarization="H")
    radar = RadarConfig(links=[Link(name="v", tx=(3.0, 0.0, 1.1)), Link(name="h", tx=(3.0, 0.0, 1.1), tx_antenna=h,
                                                                        rx_antenna=h)], antenna=Isotropic())
    ps = facet_paths(m, radar, scene="room", lod="2k", trace_fps=None, clutter=False, min_relative_gain_db=None,
                     walls="floor", double_bounce=False)
    assert np.array_equal(ps["v"].ids, ps["h"].ids)
    assert not np.allclose(ps["v"].gains, ps["h"].gains)
    bad = RadarConfig(links=[Link(name="x", tx=(3.0, 0.0, 1.1), rx_antenna=h)], antenna=Isotropic())
    with pytest.raises(InputError, match="same polarization"):
        facet_paths(m, bad, scene="room", lod="2k", clutter=False)
