"""The `facets` backend: delays, delay rates, robustness, end-to-end through the shared synthesiser."""
import numpy as np
import pytest

from processing.radar.receiver import noise_power_per_sample
from processing.radar.waveform import C0
from rtchannel.body.avatar import load_avatar
from rtchannel.backends.facets import LinkSpec, facet_paths, mesh_paths, trace_frame_indices
from rtchannel.backends.surface_scattering import SurfaceMaterial, diffuse_phases
from rtchannel.motion.procedural import generate
from rtchannel.radar import Link, RadarConfig
from rtchannel.scene.rt_scene import RadarPlacementError, RTScene, get_scene
from rtchannel.pipeline import process_paths
from rtchannel.motion.pose import Motion
from rtchannel.body.skinning import skin_vertices

LOD = "2k"
TX = (3.0, 0.0, 1.1)


def _motion(n_frames=4, offset=(0.0, 0.0, 0.0), start=(-1.0, 0.3), first=45, fps=60.0) -> Motion:
    """A few frames of a walk, from mid-stride (the walk starts after a 0.5 s quiet pad)."""
    m = generate("walk", duration=1.0, start=start, fps=fps)
    sl = slice(first, first + n_frames)
    return Motion(m.rig, m.fps, m.rotations[sl], m.positions[sl] + np.asarray(offset))


def _radar(*links) -> RadarConfig:
    return RadarConfig(links=list(links) or [Link(name="r", tx=TX)])


def test_moving_body_toward_radar_shortens_nearest_delay_exactly():
    m = _motion(2)
    radar = _radar()
    p0 = facet_paths(m, radar, scene="free_space", lod=LOD, walls=False, trace_fps=None, clutter=False)["r"]
    col = np.nanargmin(p0.delays[0])
    av = load_avatar(LOD)
    c = skin_vertices(av, m, [0])[0][av.faces[p0.ids[col]]].mean(axis=0)
    # Moving along the nearest centroid's line of sight shortens the nearest distance by exactly 0.1 m
    # (every other point gets closer by at most 0.1 m), so the shortest delay drops by 2 * 0.1 / c0.
    u = (np.asarray(TX) - c) / np.linalg.norm(np.asarray(TX) - c)
    m1 = Motion(m.rig, m.fps, m.rotations, m.positions + 0.1 * u)
    p1 = facet_paths(m1, radar, scene="free_space", lod=LOD, walls=False, trace_fps=None, clutter=False)["r"]
    change = np.nanmin(p0.delays[0]) - np.nanmin(p1.delays[0])
    assert abs(change - 2 * 0.1 / C0) < 1e-12  # 1 ps (float64 delays: ~1e-18 s)


def test_delay_rates_match_delay_differences():
    m = _motion(12, first=180, fps=240.0)
    # "central" skin velocities are the motion's own finite differences, so rate and delay history must
    # agree to the O(h^2) truncation (1e-5 of the peak rate measured at 240 fps). (The default "spline"
    # velocities differ by up to 2 % at one kink of the procedural walk: a property of the motion.)
    ps = facet_paths(m, _radar(), scene="free_space", lod=LOD, walls=False, velocity_method="central",
                     trace_fps=None, clutter=False)["r"]
    on = np.all(ps.gains != 0, axis=0)
    assert on.sum() > 100
    fd = np.gradient(ps.delays[:, on], m.times, axis=0)[2:-2]
    rate = ps.delay_rates[2:-2, on]
    assert np.max(np.abs(fd - rate)) < 1e-4 * np.max(np.abs(rate))
    assert np.max(np.abs(rate)) > 1e-9  # walking body: rates are not trivially zero


def test_trace_fps_interpolates_between_traced_frames():
    m = _motion(13)
    radar = _radar()
    full = facet_paths(m, radar, scene="free_space", lod=LOD, walls=False, trace_fps=None,
                       min_relative_gain_db=None, clutter=False)["r"]
    idx = trace_frame_indices(m.n_frames, m.fps, 15.0)
    assert idx.tolist() == [0, 4, 8, 12]
    coarse = facet_paths(m, radar, scene="free_space", lod=LOD, walls=False, trace_fps=15.0,
                         min_relative_gain_db=None, clutter=False)["r"]
    # At a traced frame the gains are the full-rate ones, except that grazing facets may flip visibility
    # with float32 ray rounding (the frame sits in another BVH cell): measured 1 of 921 paths, 1e-11 of
    # the power.
    g_full, g_coarse = dict(zip(full.ids, full.gains[4])), dict(zip(coarse.ids, coarse.gains[4]))
    diff = np.array([abs(g_full.get(i, 0) - g_coarse.get(i, 0)) for i in set(g_full) | set(g_coarse)])
    assert (diff > 1e-9 * np.abs(full.gains[4]).max()).sum() <= 0.01 * len(diff)
    assert np.sum(diff ** 2) < 1e-6 * np.sum(np.abs(full.gains[4]) ** 2)
    # Delays are exact at every frame whatever the trace rate (only visibility/gains are interpolated).
    both = np.intersect1d(full.ids, coarse.ids)
    cf, cc = np.searchsorted(full.ids, both), np.searchsorted(coarse.ids, both)
    on = (full.gains[:, cf] != 0) & (coarse.gains[:, cc] != 0)
    assert on.sum() > 1000
    assert np.array_equal(coarse.delays[:, cc][on], full.delays[:, cf][on])
    assert np.all(np.isfinite(coarse.delays[coarse.gains != 0]))


def test_end_to_end_signatures_are_finite():
    m = _motion(8)
    radar = _radar(Link(name="r1", tx=TX), Link(name="r2", tx=(0.0, -3.0, 1.1)))
    paths = facet_paths(m, radar, scene="room", lod=LOD, walls=True, min_relative_gain_db=-30, clutter=False)
    for ps in paths.values():
        assert ps.persistent and ps.delay_rates is not None
        assert np.all(np.isfinite(ps.gains)) and np.all(np.isfinite(ps.delays[ps.gains != 0]))
    res = process_paths(paths, radar, keep_iq=True)
    for lr in res.values():
        assert np.all(np.isfinite(lr.iq)) and np.abs(lr.iq).max() > 0
        assert np.all(np.isfinite(lr.signature.p_vt))


def test_degenerate_triangles_are_skipped_without_nan():
    av = load_avatar(LOD)
    m = _motion(2)
    v = skin_vertices(av, m, [0, 1])
    faces = np.array(av.faces, np.int64)
    bad = np.arange(0, len(faces), 50)
    faces[bad, 2] = faces[bad, 1]  # zero-area slivers
    scene = RTScene("free_space", faces, v[0], 24.125e9)
    mat = SurfaceMaterial(eta=18.9 - 17.1j, scattering_coefficient=0.5)
    link = LinkSpec("r", np.asarray(TX), np.asarray(TX))
    ps = mesh_paths(scene, m.times, v, faces, None, [link], C0 / 24.125e9, mat, po=True)["r"]
    assert not np.isin(ps.ids, bad).any()
    assert np.all(np.isfinite(ps.gains)) and ps.n_paths > 100


def test_body_touching_a_wall_gives_finite_paths():
    m = _motion(3, start=(3.85, 0.0))  # the body crosses the x = 4 m wall of the room
    radar = _radar(Link(name="r", tx=(1.5, 0.0, 1.1)))
    ps = facet_paths(m, radar, scene="room", lod=LOD, walls=True, clutter=False)["r"]
    assert ps.n_paths > 50
    assert np.all(np.isfinite(ps.gains)) and np.all(np.isfinite(ps.delays[ps.gains != 0]))
    scene = get_scene("room", LOD, m.rig.height, radar.waveform.carrier_hz)
    # Facets outside the room (beyond the wall) are never seen directly.
    av = load_avatar(LOD)
    cx = skin_vertices(av, m, [0])[0][av.faces].mean(axis=1)[:, 0]
    direct = ps.ids[(ps.ids < len(scene.body_faces)) & (ps.gains[0] != 0)]
    assert np.all(cx[direct] < 4.0)


def test_body_hidden_behind_a_wall_gives_zero_signal():
    m = _motion(8)
    radar = _radar(Link(name="out", tx=(6.0, 0.0, 1.1)))  # outside the room, behind the x = 4 m wall
    ps = facet_paths(m, radar, scene="room", lod=LOD, walls=True, clutter=False)["out"]
    assert np.all(ps.gains == 0) and ps.n_paths == 1
    quiet = radar.model_copy(update={"receiver": None})  # noiseless receiver: nothing at all
    res = process_paths({"out": ps}, quiet, keep_iq=True)["out"]
    assert np.all(res.iq == 0)
    assert np.all(np.isfinite(res.signature.p_vt)) and not np.any(res.signature.valid)
    # the default receiver records its own thermal noise and nothing else: k T F fs per complex sample
    # (234 x 128 samples: the estimate's spread is 10 log10(1 + 1/sqrt(30k)) = 0.03 dB)
    res = process_paths({"out": ps}, radar, keep_iq=True)["out"]
    expected = noise_power_per_sample(radar.receiver, radar.waveform.fs)
    assert abs(10 * np.log10(np.mean(np.abs(res.iq) ** 2) / expected)) < 0.2
    # the DSP knows the receiver's noise level: noise alone is never taken for a target
    assert np.all(np.isfinite(res.signature.p_vt)) and not res.signature.valid.any()
    assert np.all(res.signature.mean_velocity == 0.0)


def test_antenna_inside_the_body_path_is_rejected():
    m = generate("walk", duration=2.5, start=(1.0, 0.0))  # walks through the radar at x = 3 m
    with pytest.raises(RadarPlacementError, match="the body at t"):
        facet_paths(m, _radar(Link(name="r", tx=(3.0, 0.0, 1.1))), scene="free_space", lod=LOD, walls=False,
                    clutter=False)


def test_diffuse_phases_are_seeded_fixed_per_facet_and_shared_by_its_paths():
    m = _motion(6)
    radar = _radar()
    n_faces = load_avatar(LOD).n_faces
    # Diffuse only (po=False): each gain is real and positive times the wall factors times its facet's
    # phase, so the ratio of two seeds is the facet's phase ratio on every path and in every frame.
    opts = dict(scene="room", lod=LOD, walls=True, trace_fps=None, min_relative_gain_db=None, po=False,
                double_bounce=True)
    a = facet_paths(m, radar, seed=0, **opts, clutter=False)["r"]
    b = facet_paths(m, radar, seed=1, **opts, clutter=False)["r"]
    again = facet_paths(m, radar, seed=0, **opts, clutter=False)["r"]
    assert np.array_equal(a.gains, again.gains)  # same seed, same gains
    assert np.array_equal(a.ids, b.ids) and np.array_equal(a.gains != 0, b.gains != 0)
    on = a.gains != 0
    f = a.ids % n_faces
    ph0, ph1 = diffuse_phases(0, n_faces), diffuse_phases(1, n_faces)
    kinds = np.broadcast_to(a.ids // n_faces, a.gains.shape)[on]
    assert len(np.unique(kinds)) > 5  # direct, single and double bounce paths
    np.testing.assert_allclose(b.gains[on] / a.gains[on], np.broadcast_to(ph1[f] / ph0[f], a.gains.shape)[on],
                               rtol=1e-9)
    np.testing.assert_allclose(np.abs(b.gains), np.abs(a.gains), rtol=1e-12)  # the same power per path
    assert np.std(np.angle(b.gains[on] / a.gains[on])) > 1.0  # really different phases (uniform: 1.81 rad)
    # The direct path of a moving facet has its facet's phase in every frame (Doppler stays coherent).
    direct = a.ids < n_faces
    g = a.gains[:, direct]
    seen = g != 0
    assert seen.sum() > 3 * direct.sum()
    np.testing.assert_allclose((g / np.abs(np.where(seen, g, 1)))[seen],
                               np.broadcast_to(ph0[a.ids[direct]], g.shape)[seen], rtol=0, atol=1e-12)
    # The coarse image mesh has its own seeded phases (stream (seed, its number of faces)), shared by its paths.
    m2 = _motion(2)
    coarse = facet_paths(m2, radar, scene="room", lod="5k", image_lod="2k", trace_fps=None, min_relative_gain_db=None,
                         po=False, seed=3, clutter=False)["r"]
    coarse1 = facet_paths(m2, radar, scene="room", lod="5k", image_lod="2k", trace_fps=None, min_relative_gain_db=None,
                          po=False, seed=4, clutter=False)["r"]
    n5, n2 = load_avatar("5k").n_faces, n_faces
    img = (coarse.ids >= n5) & (coarse.gains[0] != 0)
    fc = coarse.ids[img] % n5
    np.testing.assert_allclose(coarse1.gains[0, img] / coarse.gains[0, img],
                               diffuse_phases(4, n2)[fc] / diffuse_phases(3, n2)[fc], rtol=1e-9)
