"""Scene-dependent modelling (issue 26): body LOD from the wavelength, walls culled by range window and
antenna pattern, traced frames from the fastest limb, each as a facets option whose choice is reported."""
import numpy as np
import pytest

from processing.errors import InputError
from processing.radar.antenna import Isotropic, YagiBeam
from rtchannel.backends.facets import LinkSpec
from rtchannel.backends.scene_model import (RANGE_MARGIN_BINS, adaptive_trace_indices, aspect_rate_deg_s,
                                            fastest_speed, fresnel_facet_m, lod_for_wavelength, median_edge_m,
                                            walls_in_view)
from rtchannel.backends.wall_images import PlanarWall

C0 = 299_792_458.0


def _wall(name, x, normal_x):
    """A 4 m x 3 m wall in the plane x = `x`, facing +x (normal_x 1) or -x (-1)."""
    poly = np.array([[x, -2, 0], [x, 2, 0], [x, 2, 3], [x, -2, 3]], float)
    return PlanarWall(name=name, point=poly.mean(axis=0), normal=np.array([normal_x, 0.0, 0.0]), polygon=poly,
                      relative_permittivity=5.0 + 0.1j)


def test_fresnel_facet_size_on_paper():
    # sqrt(lambda rho / 2): 24.125 GHz, rho 5 cm -> sqrt(0.012427 * 0.05 / 2) = 1.763 cm
    assert fresnel_facet_m(C0 / 24.125e9) == pytest.approx(0.01763, rel=1e-3)
    assert fresnel_facet_m(C0 / 5.8e9, 0.05) == pytest.approx(np.sqrt(C0 / 5.8e9 * 0.025), rel=1e-12)


def test_lod_follows_the_wavelength():
    # the avatars' median edges are ordered full < 10k < 5k < 2k; the rule picks the coarsest that fits
    edges = [median_edge_m(lod) for lod in ("full", "10k", "5k", "2k")]
    assert edges == sorted(edges)
    assert lod_for_wavelength(C0 / 24.125e9) == "10k"  # limit 1.76 cm, 10k median ~1.6 cm, 5k ~2.3 cm
    assert lod_for_wavelength(C0 / 77e9) == "full"  # 0.99 cm: only the full mesh
    assert lod_for_wavelength(C0 / 2.4e9) == "2k"  # 5.6 cm: the coarsest avatar
    limit = fresnel_facet_m(C0 / 5.8e9)
    chosen = lod_for_wavelength(C0 / 5.8e9)
    assert median_edge_m(chosen) <= limit
    finer = [lod for lod in ("full", "10k", "5k", "2k") if median_edge_m(lod) > median_edge_m(chosen)]
    assert all(median_edge_m(lod) > limit for lod in finer)


def test_walls_beyond_the_range_window_are_culled():
    # monostatic antenna at x = 0: a wall at distance D gives image paths of half-length >= D
    link = [LinkSpec("r", np.array([0.0, 0, 1]), np.array([0.0, 0, 1]))]
    res = 0.3
    near, far = _wall("near", 5.0, -1), _wall("far", -(4.0 + RANGE_MARGIN_BINS * res + 0.05), 1)
    edge = _wall("edge", -(4.0 + RANGE_MARGIN_BINS * res - 0.05), 1)
    kept, culled = walls_in_view([near, far, edge], link, max_range_m=4.0, range_resolution_m=res)
    assert [w.name for w in kept] == ["edge"]  # near is 5 m away: beyond 4 + 3 x 0.3 m too
    assert set(culled) == {"near", "far"}
    kept, _ = walls_in_view([near], link, max_range_m=6.0, range_resolution_m=res)
    assert [w.name for w in kept] == ["near"]


def test_walls_behind_a_yagi_are_culled_by_its_back_lobe():
    # a Yagi looking along +x sees the wall behind it at most at its front-to-back ratio (20 dB)
    yagi = YagiBeam(boresight=(1, 0, 0), hpbw_az_deg=30, hpbw_el_deg=30, front_to_back_db=20, floor_db=30)
    pos = np.array([0.0, 0, 1.5])
    link = [LinkSpec("r", pos, pos, yagi, yagi)]
    behind, ahead = _wall("behind", -1.0, 1), _wall("ahead", 4.0, -1)
    kept, culled = walls_in_view([behind, ahead], link, 10.0, 0.3, wall_cut_db=-15.0)
    assert [w.name for w in kept] == ["ahead"] and "behind" in culled
    kept, _ = walls_in_view([behind, ahead], link, 10.0, 0.3, wall_cut_db=-25.0)  # -20 dB is above -25
    assert [w.name for w in kept] == ["behind", "ahead"]
    iso = [LinkSpec("r", pos, pos, Isotropic(), Isotropic())]
    kept, _ = walls_in_view([behind, ahead], iso, 10.0, 0.3, wall_cut_db=-15.0)
    assert len(kept) == 2


def test_adaptive_trace_frames_follow_the_distance_travelled():
    t = np.arange(301) / 60.0  # 5 s at 60 fps
    speed = np.full(301, 2.0)  # 2 m/s: 0.5 m every 0.25 s = 15 frames
    idx = adaptive_trace_indices(t, speed, 0.5)
    assert idx[0] == 0 and idx[-1] == 300
    assert np.all(np.diff(idx[:-1]) == 15)
    still = adaptive_trace_indices(t, np.zeros(301), 0.5, max_gap_s=1.0)  # at rest: once a second
    assert np.all(np.diff(still[:-1]) == 60)
    with pytest.raises(InputError):
        adaptive_trace_indices(t, speed, 0.0)


def test_fastest_speed_ignores_one_bad_vertex():
    v = np.zeros((3, 1000, 3))
    v[:, :, 0] = 1.0
    v[:, 0, 0] = 100.0  # one vertex skinned badly
    assert np.allclose(fastest_speed(v), 1.0)


def _plate(times, centre, angle_deg):
    """Two triangles of a 10 cm square plate [K, 4, 3] at centres [K, 3], its normal turned by angle_deg [K]
    about z from +x (toward a radar on the +x axis)."""
    a = np.radians(angle_deg)
    normal = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=-1)
    side = np.stack([-np.sin(a), np.cos(a), np.zeros_like(a)], axis=-1)  # in-plane, horizontal
    up = np.array([0.0, 0.0, 1.0])
    corners = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
    v = np.stack([centre + 0.05 * (i * side + j * up) for i, j in corners], axis=1)
    faces = np.array([[0, 1, 2], [0, 2, 3]])  # counter-clockwise seen from the normal's side
    assert np.allclose(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])[:, :2] / 0.01, normal[:, :2])
    return v, faces


def test_aspect_rate_on_paper():
    t = np.arange(61) / 60.0
    radar = np.array([[5.0, 0.0, 0.0]])
    # a plate at the origin turning at 30 deg/s about z (from 20 deg, away from the kink of |angle| at 0): its
    # normal leaves the line of sight at 30 deg/s, up to the parallax of its triangles' centroids (4.7 cm off
    # the axis at 5 m: < 1 %)
    v, f = _plate(t, np.zeros((61, 3)), 20.0 + 30.0 * t)
    assert np.allclose(aspect_rate_deg_s(t, v, f, radar), 30.0, rtol=0.01)
    # a plate (turned 20 deg off the radar) sliding sideways at 1 m/s across the boresight at range R: the line
    # of sight turns at v / R rad/s there (the far plate needs half the traced frames of the near one)
    for r in (2.0, 4.0):
        centre = np.stack([np.zeros(61), t - 0.5, np.zeros(61)], axis=-1)
        v, f = _plate(t, centre, np.full(61, 20.0))
        rate = aspect_rate_deg_s(t, v, f, np.array([[r, 0.0, 0.0]]))
        assert rate[30] == pytest.approx(np.degrees(1.0 / r), rel=0.01)  # centroids 2.4 cm off the centre: ~d / R
    # facing away from every antenna in both frames: no path, no rate
    v, f = _plate(t, np.zeros((61, 3)), 180.0 + 30.0 * t)
    assert np.all(aspect_rate_deg_s(t, v, f, radar) == 0.0)
    assert np.all(np.isfinite(aspect_rate_deg_s(t[:2], v[:2], f, radar)))


@pytest.fixture(scope="module")
def short_walk():
    from rtchannel.motion.procedural import generate

    return generate("walk", duration=1.0, speed=1.0, start=(-1.0, 0.0), pad_before=0.0, pad_after=0.3)


def test_facets_report_what_the_scene_options_chose(short_walk):
    from rtchannel.pipeline import simulate
    from rtchannel.radar import RadarConfig

    res = simulate(short_walk, RadarConfig(), backend="facets", lod="auto", walls="auto", trace_step_m=0.3,
                   clutter=False)
    stats = res.config["backend_stats"]
    assert stats["lod"] == "10k"  # 24.125 GHz
    assert stats["walls"] == ["floor", "wall_xp", "wall_xn", "wall_yp", "wall_yn"]  # all within 10 m, isotropic
    assert 2 <= stats["traced_frames"] < short_walk.n_frames
    for sig in res.signatures.values():
        assert np.all(np.isfinite(sig.p_vt))
    named = simulate(short_walk, RadarConfig(), backend="facets", walls="floor", clutter=False)
    assert named.config["backend_stats"]["walls"] == ["floor"]
    with pytest.raises(InputError, match="no wall named 'ceiling'"):
        simulate(short_walk, RadarConfig(), backend="facets", walls="ceiling", clutter=False)


def test_aspect_trace_step_traces_far_motion_coarser(short_walk):
    """The same sideways walk traced by the aspect rule: 4 m from the radar gets fewer traced frames than 1.5 m;
    one rule at a time, and a step must be positive."""
    from rtchannel.backends.facets import facet_paths
    from rtchannel.radar import Link, RadarConfig

    walk = short_walk
    counts = []
    for x in (1.5, 4.0):  # the radar on the +x axis looks at the walk's line (along x) from its end: move it aside
        radar = RadarConfig(links=[Link(name="a", tx=(0.0, -x, 1.0))])
        st = {}
        paths = facet_paths(walk, radar, scene="free_space", lod="2k", walls=False, trace_step_deg=10.0,
                            stats=st)
        assert np.all(np.isfinite(paths["a"].delays[np.isfinite(paths["a"].delays)]))
        counts.append(st["traced_frames"])
    assert 2 <= counts[1] < counts[0] < walk.n_frames
    with pytest.raises(InputError, match="give one"):
        facet_paths(walk, RadarConfig(), scene="free_space", lod="2k", trace_step_m=0.3, trace_step_deg=5.0)
    with pytest.raises(InputError, match="trace_max_gap_s must be positive"):
        facet_paths(walk, RadarConfig(), scene="free_space", lod="2k", walls=False, trace_step_deg=5.0,
                    trace_max_gap_s=0.0)
    with pytest.raises(InputError, match="trace_step_deg must be positive"):
        facet_paths(walk, RadarConfig(), scene="free_space", lod="2k", walls=False, trace_step_deg=0.0)
