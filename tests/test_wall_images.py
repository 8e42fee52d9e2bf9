"""Image-source multipath of the `facets` backend: mirror geometry, validity, merging, Fresnel factors,
double bounce (both antennas mirrored), the coarse image LOD."""
import numpy as np
import pytest

from processing.radar.antenna import Isotropic
from processing.radar.waveform import C0
from rtchannel.backends.facet_assemble import double_kind, kind_walls
from rtchannel.backends.facets import facet_paths
from rtchannel.backends.surface_scattering import fresnel, slab_reflection
from rtchannel.backends.wall_images import PlanarWall, in_convex_polygon, mirror, reflection_points
from rtchannel.motion.procedural import generate
from rtchannel.radar import Link, RadarConfig
from rtchannel.scene.rt_scene import get_scene
from rtchannel.motion.pose import Motion
from rtchannel.body.avatar import load_avatar
from rtchannel.body.skinning import skin_vertices

LOD = "2k"
WALL = PlanarWall("w", point=np.array([4.0, 0.0, 1.5]), normal=np.array([-1.0, 0.0, 0.0]),
                  polygon=np.array([[4, -4, 0], [4, 4, 0], [4, 4, 3], [4, -4, 3]], float),
                  relative_permittivity=5.24 - 0.4j, thickness=0.2)


def _short_motion(n_frames=3, offset=(0.0, 0.0, 0.0)) -> Motion:
    m = generate("walk", duration=1.0, start=(-1.0, 0.5))
    return Motion(m.rig, m.fps, m.rotations[:n_frames], m.positions[:n_frames] + np.asarray(offset))


def test_mirror_and_reflection_point_validity():
    src = np.array([3.0, 1.0, 1.0])
    assert np.allclose(mirror(src, WALL), [5.0, 1.0, 1.0])
    pts = np.array([[0.0, 0.0, 1.0], [3.9, 20.0, 1.0], [5.0, 0.0, 1.0]])
    image, q, valid = reflection_points(pts, src, WALL)
    # First: q on the wall inside the polygon; second: q far outside (y ~ 14 m); third: behind the wall.
    assert valid.tolist() == [True, False, False]
    assert q[0][0] == pytest.approx(4.0, abs=1e-12)
    # The path via q is as long as the straight line from the image (mirror geometry).
    assert (np.linalg.norm(pts[0] - q[0]) + np.linalg.norm(q[0] - src)) == pytest.approx(
        np.linalg.norm(pts[0] - image), rel=1e-14)
    assert in_convex_polygon(np.array([[4.0, 3.9, 2.9], [4.0, 4.1, 1.0]]), WALL).tolist() == [True, False]


def test_fresnel_limits():
    r_te, r_tm = fresnel(np.array([1.0, 0.3]), None)
    assert np.allclose(r_te, -1) and np.allclose(r_tm, 1)
    eta = 5.24 - 0.4j
    r_te, r_tm = fresnel(1.0, eta)
    assert r_te == pytest.approx((1 - np.sqrt(eta)) / (1 + np.sqrt(eta)), rel=1e-12)
    assert r_tm == pytest.approx(-r_te, rel=1e-12)  # normal incidence: no plane of incidence
    # A slab many skin depths thick reflects like the half-space (skin at 24 GHz: eta = 18.9 - 17.1 j).
    skin = 18.9 - 17.1j
    assert np.allclose(slab_reflection(0.6, skin, 0.05, 0.0124), fresnel(0.6, skin), atol=1e-9)


def test_image_extra_delay_equals_mirror_geometry():
    m = _short_motion()
    tx = np.array([3.0, 0.0, 1.1])
    radar = RadarConfig(links=[Link(name="r", tx=tuple(tx))])
    scene = get_scene("room", LOD, m.rig.height, radar.waveform.carrier_hz)
    ps = facet_paths(m, radar, scene=scene, lod=LOD, walls=True, trace_fps=None, min_relative_gain_db=None,
                     clutter=False)["r"]
    n_faces = len(scene.body_faces)
    av = load_avatar(LOD)
    verts = skin_vertices(av, m, [0])[0]
    cent = verts[av.faces].mean(axis=1)
    names = [w.name for w in scene.walls]
    # Analytic images: floor z = 0, wall_xp x = 4.
    images = {"floor": tx * [1, 1, -1], "wall_xp": np.array([8.0 - tx[0], tx[1], tx[2]])}
    direct = {i: k for k, i in enumerate(ps.ids) if i < n_faces}
    checked = 0
    for name, image in images.items():
        kind = 1 + 2 * names.index(name)
        cols = np.flatnonzero((ps.ids // n_faces == kind) & (ps.gains[0] != 0))
        assert cols.size > 20  # the floor and the wall behind the radar both light the body
        for col in cols:
            f = ps.ids[col] % n_faces
            extra = ps.delays[0, col] - ps.delays[0, direct[f]]
            expected = (np.linalg.norm(cent[f] - image) - np.linalg.norm(cent[f] - tx)) / C0
            assert abs(extra - expected) < 1e-12  # 1 ps
            checked += 1
    assert checked > 40


def test_monostatic_merge_equals_sum_of_both_images_and_walls_switch():
    m = _short_motion(n_frames=2)
    tx = (3.0, 0.0, 1.1)
    rx_near = (3.0, 0.0, 1.1 + 1e-7)  # a distinct receiver 0.1 um away: tx- and rx-image paths kept apart
    radar = RadarConfig(links=[Link(name="mono", tx=tx), Link(name="bi", tx=tx, rx=rx_near)])
    scene = get_scene("room", LOD, m.rig.height, radar.waveform.carrier_hz)
    n_faces = len(scene.body_faces)
    out = facet_paths(m, radar, scene=scene, lod=LOD, walls=True, trace_fps=None, min_relative_gain_db=None,
                      double_bounce="pairs", clutter=False)
    mono, bi = out["mono"], out["bi"]
    g_bi = dict(zip(bi.ids, bi.gains[0]))
    floor = 1 + 2 * [w.name for w in scene.walls].index("floor")
    cols = np.flatnonzero((mono.ids // n_faces == floor) & (mono.gains[0] != 0))
    assert cols.size > 0
    for col in cols:
        f = mono.ids[col] % n_faces
        both = g_bi.get(f + n_faces * floor, 0) + g_bi.get(f + n_faces * (floor + 1), 0)
        assert mono.gains[0, col] == pytest.approx(both, rel=1e-5)  # 0.1 um geometry change
    assert np.all(mono.ids // n_faces != floor + 1)  # the merged twin is not emitted
    # Double bounce via two walls: tx -> w1 -> f -> w2 -> rx and its reverse have one delay monostatically
    # and are merged into the (w1 < w2) kind; the same wall twice is its own reverse (one path per facet).
    n_w = len(scene.walls)
    walls_of = np.array([kind_walls(int(k), n_w) for k in mono.ids // n_faces])
    double = np.all(walls_of >= 0, axis=1)
    assert np.all(walls_of[double, 0] <= walls_of[double, 1])
    assert np.any(double & (walls_of[:, 0] == walls_of[:, 1]))
    cross = np.flatnonzero(double & (walls_of[:, 0] < walls_of[:, 1]) & (mono.gains[0] != 0))
    assert cross.size > 20
    for col in cross:
        f, (w1, w2) = mono.ids[col] % n_faces, walls_of[col]
        both = g_bi.get(f + n_faces * double_kind(w1, w2, n_w), 0) + g_bi.get(f + n_faces * double_kind(w2, w1, n_w), 0)
        assert mono.gains[0, col] == pytest.approx(both, rel=1e-5)
    no_walls = facet_paths(m, radar, scene=scene, lod=LOD, walls=False, trace_fps=None,
                           min_relative_gain_db=None, clutter=False)["mono"]
    assert np.all(no_walls.ids < n_faces)
    assert set(no_walls.ids) == set(mono.ids[mono.ids < n_faces])


def test_coarse_image_lod_keeps_image_power_and_direct_paths():
    m = generate("walk", duration=1.0, start=(-1.0, 0.3))
    m = Motion(m.rig, m.fps, m.rotations[40:52], m.positions[40:52])
    radar = RadarConfig(links=[Link(name="r", tx=(3.0, 0.0, 1.1))])
    scene = get_scene("room", "5k", m.rig.height, radar.waveform.carrier_hz)
    n_faces = len(scene.body_faces)
    # Diffuse only: the PO term of a facet is not area-weighted (a flat facet's specular lobe grows as A^2),
    # so only the coherent sum of PO facets is mesh-independent (next test).
    opts = dict(scene=scene, lod="5k", walls=True, trace_fps=None, min_relative_gain_db=None, po=False)
    fine = facet_paths(m, radar, image_lod=None, **opts, clutter=False)["r"]
    coarse = facet_paths(m, radar, image_lod="2k", **opts, clutter=False)["r"]
    # Direct paths are untouched (same ids, gains and delays).
    d_f, d_c = fine.ids < n_faces, coarse.ids < n_faces
    assert np.array_equal(fine.ids[d_f], coarse.ids[d_c])
    np.testing.assert_array_equal(fine.gains[:, d_f], coarse.gains[:, d_c])
    # Image ids are coarse facets (f_c < 2k faces) in the fine id slots, and far fewer.
    n_coarse = len(load_avatar("2k").faces)
    assert np.all(coarse.ids[~d_c] % n_faces < n_coarse)
    assert (~d_c).sum() < 0.6 * (~d_f).sum()
    # Diffuse gains are area-weighted, so each strong wall's image power per frame survives the coarser
    # mesh: measured within 0.1 dB (10k vs 2k, 5 s walk, median; 1.4 dB at the 5th/95th percentile of the
    # weakest wall); 1 dB bounds the frame-summed power of walls carrying > 1 % of the image power. A
    # wrong area scale or a lost mirror image is off by >= 3 dB.
    kind_f, kind_c = fine.ids // n_faces, coarse.ids // n_faces
    total = np.sum(np.abs(fine.gains[:, kind_f > 0]) ** 2)
    checked = 0
    for kind in np.unique(kind_f[kind_f > 0]):
        pf = np.sum(np.abs(fine.gains[:, kind_f == kind]) ** 2)
        pc = np.sum(np.abs(coarse.gains[:, kind_c == kind]) ** 2)
        if pf > 0.01 * total:
            assert abs(10 * np.log10(pc / pf)) < 1.0, f"kind {kind}: {10 * np.log10(pc / pf):.2f} dB"
            checked += 1
    assert checked >= 3
    assert np.all(np.isfinite(coarse.delays[coarse.gains != 0]))


def test_coarse_image_lod_keeps_coherent_image_power_with_defaults():
    # Defaults: PO on, random diffuse phases (fine and coarse facets have independent phases). The expected
    # coherent power of the diffuse image paths is their power sum, area-weighted on both meshes; the PO
    # part is the same surface integral on both. Over a 2 s walk the mean coherent image power of each link
    # measured +0.02 / +0.34 dB (coarse - fine, 5k direct mesh, two radars): 1 dB leaves room for the
    # speckle of a short walk; a lost wall or a wrong area scale is >= 3 dB.
    m = generate("walk", duration=2.0, start=(-1.0, 0.3))
    # Unit-gain antennas: the measurement above weights every wall alike (horns would hide the walls behind
    # the radars, whose images carry most of this power, and leave a shorter-speckle comparison).
    radar = RadarConfig(links=[Link(name="r", tx=(3.0, 0.0, 1.1)), Link(name="r2", tx=(0.0, -3.0, 1.1))],
                        antenna=Isotropic())
    f0 = radar.waveform.carrier_hz
    scene = get_scene("room", "5k", m.rig.height, f0)
    n_faces = len(scene.body_faces)
    opts = dict(scene=scene, lod="5k", walls=True, min_relative_gain_db=None)
    fine = facet_paths(m, radar, image_lod=None, **opts, clutter=False)
    coarse = facet_paths(m, radar, image_lod="2k", **opts, clutter=False)
    for name in fine:
        power = []
        for ps in (fine[name], coarse[name]):
            img = ps.ids >= n_faces
            tau = np.where(ps.gains[:, img] != 0, ps.delays[:, img], 0.0)
            power.append(np.mean(np.abs(np.sum(ps.gains[:, img] * np.exp(2j * np.pi * f0 * tau), axis=1)) ** 2))
        assert abs(10 * np.log10(power[1] / power[0])) < 1.0, name


def _floor_double(radar, m, scene):
    return facet_paths(m, radar, scene=scene, lod=LOD, walls=True, trace_fps=None, min_relative_gain_db=None,
                       double_bounce="floor", clutter=False)


@pytest.mark.parametrize("rx", [None, (2.2, 1.5, 1.4)])
def test_floor_double_bounce_is_the_image_geometry_times_gamma_squared(rx):
    m = _short_motion(n_frames=2)
    tx = np.array([3.0, 0.0, 1.1])
    # unit-gain antennas: the hand computation below is the scattering alone (patterns: test_facet_antennas)
    radar = RadarConfig(links=[Link(name="r", tx=tuple(tx), rx=rx)], antenna=Isotropic())
    rx = tx if rx is None else np.asarray(rx)
    scene = get_scene("room", LOD, m.rig.height, radar.waveform.carrier_hz)
    n_faces = len(scene.body_faces)
    w_floor = [w.name for w in scene.walls].index("floor")
    floor = scene.walls[w_floor]
    kind = double_kind(w_floor, w_floor, len(scene.walls))
    ps = _floor_double(radar, m, scene)["r"]
    cols = np.flatnonzero((ps.ids // n_faces == kind) & (ps.gains[0] != 0))
    assert cols.size > 50
    av = load_avatar(LOD)
    cent = skin_vertices(av, m, [0])[0][av.faces].mean(axis=1)
    tx_i, rx_i = tx * [1, 1, -1], rx * [1, 1, -1]  # the floor is z = 0
    f = ps.ids[cols] % n_faces
    d_i, d_r = np.linalg.norm(cent[f] - tx_i, axis=1), np.linalg.norm(cent[f] - rx_i, axis=1)
    np.testing.assert_allclose(ps.delays[0, cols], (d_i + d_r) / C0, rtol=0, atol=1e-12)  # 1 ps
    # Gain: the free-space path tx' -> facet -> rx' (same facet, phase and PO term) times the floor's
    # reflection at both points. A vertically polarised wave meets a horizontal floor in a vertical plane of
    # incidence, so it is pure TM: co-polar coefficient -r_tm, conjugated (synthesiser convention), at the
    # incidence cosines (z_antenna + z_c) / |c - antenna'|, times the floor's Kirchhoff roughness factor
    # exp(-(4 pi sigma_h cos / lambda)^2 / 2) at each (the same roughness its clutter scatters with).
    free = facet_paths(m, RadarConfig(links=[Link(name="r", tx=tuple(tx_i), rx=tuple(rx_i))], antenna=Isotropic()),
                       scene="free_space", lod=LOD, walls=False, trace_fps=None, min_relative_gain_db=None,
                       clutter=False)["r"]
    g_free = dict(zip(free.ids, free.gains[0]))
    both = np.array([g_free.get(i, 0) != 0 for i in f])
    assert both.mean() > 0.9  # the free-space run misses only facets whose floor leg the body blocks
    eta, thick, lam = complex(floor.relative_permittivity), floor.thickness, radar.waveform.wavelength
    from rtchannel.scene.material import kirchhoff_specular

    cosines = [(np.asarray(a)[2] + cent[f[both], 2]) / d for a, d in ((tx, d_i[both]), (rx, d_r[both]))]
    gamma = [np.conj(-slab_reflection(c, eta, thick, lam)[1]) * kirchhoff_specular(2 * c, floor.roughness_m, lam)
             for c in cosines]
    expected = np.array([g_free[i] for i in f[both]]) * gamma[0] * gamma[1]
    np.testing.assert_allclose(ps.gains[0, cols[both]], expected, rtol=1e-9)
    assert np.all(np.abs(gamma[0]) < 1) and np.ptp(np.abs(gamma[0])) > 0  # a real, angle-dependent loss


def test_double_bounce_switch_removes_exactly_its_paths():
    m = _short_motion(n_frames=2)
    radar = RadarConfig(links=[Link(name="r", tx=(3.0, 0.0, 1.1)), Link(name="b", tx=(3.0, 0.0, 1.1),
                                                                         rx=(2.2, 1.5, 1.4))])
    scene = get_scene("room", LOD, m.rig.height, radar.waveform.carrier_hz)
    n_faces, n_w = len(scene.body_faces), len(scene.walls)
    opts = dict(scene=scene, lod=LOD, walls=True, trace_fps=None, min_relative_gain_db=None)
    on = facet_paths(m, radar, double_bounce=True, **opts, clutter=False)
    off = facet_paths(m, radar, double_bounce=False, **opts, clutter=False)
    for name in on:
        kinds = on[name].ids // n_faces
        double = kinds > 2 * n_w
        assert set(kinds[double]) <= {double_kind(w, w, n_w) for w in range(n_w)}  # True: same wall twice
        w_floor = [w.name for w in scene.walls].index("floor")
        assert len(set(kinds[double])) >= 3 and np.any(kinds == double_kind(w_floor, w_floor, n_w))
        np.testing.assert_array_equal(on[name].ids[~double], off[name].ids)
        np.testing.assert_array_equal(on[name].gains[:, ~double], off[name].gains)


def test_double_bounce_wall_selection():
    from rtchannel.backends.facets import double_bounce_pairs

    def wall(name, z, normal):
        return PlanarWall(name, point=np.array([0.0, 0.0, z]), normal=np.asarray(normal, float),
                          polygon=np.zeros((3, 3)), relative_permittivity=5.0)
    walls = [wall("side", 1.5, [1, 0, 0]), wall("table", 0.7, [0, 0, 1]), wall("ground", 0.0, [0, 0, 1])]
    assert double_bounce_pairs("floor", walls) == [(2, 2)]  # the lowest upward-facing plane, whatever its name
    assert double_bounce_pairs("floor", walls[:1]) == []  # no floor: no floor double bounce
    assert double_bounce_pairs(True, walls) == [(0, 0), (1, 1), (2, 2)]
    assert len(double_bounce_pairs("pairs", walls)) == 9 and double_bounce_pairs(False, walls) == []
    assert double_bounce_pairs("table", walls) == [(1, 1)]
    with pytest.raises(ValueError, match="double_bounce"):
        double_bounce_pairs("ceiling", walls)


@pytest.mark.parametrize("eta, thickness", [(5.24 - 0.4j, 0.2), (5.24 - 0.4j, 0.0), (3.0 - 0.01j, 0.01), (None, 0.0)])
def test_compiled_wall_factor_matches_the_reference_maths(eta, thickness):
    from rtchannel.backends.surface_scattering import co_polar_reflection, wall_factor

    w = PlanarWall("w", point=np.zeros(3), normal=np.array([0.6, 0.0, 0.8]), polygon=np.zeros((3, 3)),
                   relative_permittivity=eta, thickness=thickness)
    rng = np.random.default_rng(1)
    k = rng.normal(size=(1000, 3))
    k /= np.linalg.norm(k, axis=1, keepdims=True)
    cos_w = np.abs(k @ w.normal)
    e = None if eta is None else complex(eta)
    from rtchannel.scene.material import kirchhoff_specular

    rough = kirchhoff_specular(2 * cos_w, w.roughness_m, 0.0124)  # the default 1 mm rms wall
    ref = rough * np.conj(co_polar_reflection(k, np.broadcast_to(w.normal, k.shape),
                                              *slab_reflection(cos_w, e, thickness or None, 0.0124)))
    np.testing.assert_allclose(wall_factor(w, cos_w, k, 0.0124), ref, rtol=0, atol=1e-14)  # |Gamma| <= 1
