"""The facets backend's speed cuts are exact: direct Embree casts answer as Mitsuba's ray_test, partial BVH
batches with unused cells answer as full ones, index-reading gain kernels equal the gathered route, the
compiled antenna pattern equals `processing.radar.antenna.gain`, and whole path sets are unchanged."""
import numpy as np
import pytest

from processing.radar import antenna
from rtchannel.backends import embree, visibility
from rtchannel.backends.facet_kernels import antenna_amplitudes
from rtchannel.backends.facets import facet_paths
from rtchannel.backends.surface_scattering import SurfaceMaterial, facet_gains, facet_gains_indexed
from rtchannel.body.avatar import load_avatar
from rtchannel.body.skinning import face_normals_and_areas, skin_vertices
from rtchannel.motion.procedural import generate
from rtchannel.radar import Link, RadarConfig
from rtchannel.scene.rt_scene import get_scene


def test_the_pinned_mitsuba_gives_the_direct_embree_route():
    """On the pinned Mitsuba (sionna-rt 2.2.0 -> mitsuba 3.9) the direct route must be live: were the library
    renamed or its self-test to fail, facets would fall back silently (about twice as slow), so CI says so."""
    import mitsuba

    assert mitsuba.__version__.startswith("3.9") and embree.available()


def test_a_failing_self_test_falls_back_to_mitsuba(monkeypatch):
    monkeypatch.setattr(embree, "_state", {})
    monkeypatch.setattr(embree, "_self_test", lambda: False)
    assert not embree.available()
    with pytest.raises(RuntimeError, match="not available"):
        embree.EmbreeScene(None, np.array([[0, 1, 2]]), 3)
    monkeypatch.undo()
    assert embree.available()


LOD = "2k"


def _walk(n_frames=6, first=45):
    m = generate("walk", duration=1.0, start=(-1.0, 0.3), fps=60.0)
    from rtchannel.motion.pose import Motion

    sl = slice(first, first + n_frames)
    return Motion(m.rig, m.fps, m.rotations[sl], m.positions[sl])


def _rays_at_body(verts, faces, n_frames, rng, n=4000):
    """Rays from points around the room to body centroids (and a little past them), per frame slot."""
    cells = rng.integers(0, n_frames, n)
    f = rng.integers(0, len(faces), n)
    target = verts[cells[:, None], faces[f]].mean(axis=1)
    origin = rng.uniform([-2.5, -2.5, 0.2], [2.5, 2.5, 2.5], (n, 3))
    d = target - origin
    dist = np.linalg.norm(d, axis=1)
    # half stop just short of the centroid (the facet itself must not count), half overshoot by 0.3 m
    t = np.where(rng.random(n) < 0.5, dist - 1e-4, dist + 0.3)
    return origin, d / dist[:, None], t, cells


def test_embree_casts_equal_mitsuba_ray_test_ray_by_ray():
    m = _walk()
    av = load_avatar(LOD)
    verts = skin_vertices(av, m)
    scene = get_scene("room", LOD, m.rig.height, 24.125e9)
    static = [(v, f) for _, v, f in scene.static_meshes]
    bounds = (np.array([-3.0, -3.0, -0.5]), np.array([3.0, 3.0, 3.0]))
    casters = [visibility.FrameBatchCaster(static, av.faces, verts.shape[1], bounds, 8, embree=e)
               for e in (True, False)]
    assert casters[0]._embree is not None and casters[1]._embree is None
    rng = np.random.default_rng(1)
    o, d, t, cells = _rays_at_body(verts, av.faces, len(verts), rng)
    hits = []
    for c in casters:
        c.load(verts)  # 6 poses in 8 cells: the two unused cells are NaN (Embree) or a copy (Mitsuba)
        hits.append(c.occluded_cells(o, d, t, cells))
    # Both are Embree on the same float32 triangles and rays: identical answers, and a mix of both.
    assert np.array_equal(hits[0], hits[1])
    assert 0.2 < hits[0].mean() < 0.9


def test_partial_batch_answers_as_a_full_batch():
    m = _walk(8)
    av = load_avatar(LOD)
    verts = skin_vertices(av, m)
    bounds = (np.array([-3.0, -3.0, -0.5]), np.array([3.0, 3.0, 3.0]))
    rng = np.random.default_rng(2)
    o, d, t, cells = _rays_at_body(verts[:3], av.faces, 3, rng)
    full = visibility.FrameBatchCaster([], av.faces, verts.shape[1], bounds, 8)
    full.load(verts)  # cells 3..7 hold real bodies
    part = visibility.FrameBatchCaster([], av.faces, verts.shape[1], bounds, 8)
    part.load(verts[:3])  # cells 3..7 NaN: Embree drops those triangles
    assert np.array_equal(full.occluded_cells(o, d, t, cells), part.occluded_cells(o, d, t, cells))
    # A wrong cell layout would show: rays of cell 0 sent into cell 5 meet another pose (or nothing).
    assert not np.array_equal(full.occluded_cells(o, d, t, cells), full.occluded_cells(o, d, t, (cells + 5) % 8))


def test_indexed_gains_equal_the_gathered_route_bitwise():
    m = _walk(3)
    av = load_avatar(LOD)
    verts = skin_vertices(av, m)
    norm, area, _ = face_normals_and_areas(verts, av.faces)
    cent = verts[:, av.faces].mean(axis=2)
    rng = np.random.default_rng(3)
    eb, ef = rng.integers(0, 3, 500), rng.integers(0, len(av.faces), 500)
    p_a, p_b = np.array([3.0, 0.0, 1.1]), rng.uniform(-3, 3, (500, 3))
    phase = np.exp(1j * rng.uniform(0, 2 * np.pi, 500))
    for mat in (SurfaceMaterial(eta=40 - 20j, scattering_coefficient=0.5), SurfaceMaterial(eta=None),
                SurfaceMaterial(eta=5 - 1j, scattering_coefficient=0.3, pattern="directive")):
        corners = verts[eb[:, None], av.faces[ef]]  # [500, 3, 3]
        ref = facet_gains(mat, 0.0124, cent[eb, ef], norm[eb, ef], area[eb, ef], corners, p_a, p_b, True, phase)
        got = facet_gains_indexed(mat, 0.0124, cent, norm, area, verts, av.faces, eb, ef, p_a, p_b, True, phase)
        assert np.array_equal(got, ref)  # same compiled arithmetic, only read in place
        assert np.abs(ref).max() > 0


@pytest.mark.parametrize("spec", [
    RadarConfig().antenna,
    antenna.GaussianBeam(hpbw_az_deg=20, hpbw_el_deg=50, look_at=(0.0, 1.0, 0.5), peak_gain_dbi=12.0),
    antenna.YagiBeam(hpbw_az_deg=40, hpbw_el_deg=60, look_at=(0.0, 0.0, 1.1)),
    antenna.Isotropic(),
])
def test_compiled_antenna_amplitudes_equal_the_reference(spec):
    rng = np.random.default_rng(4)
    pos = np.array([3.0, 0.0, 1.1])
    targets = np.concatenate([rng.normal(0, 3, (20000, 3)), [pos], [pos + (-1.0, 0.0, 0.0)]])
    ref, got = antenna.gain(spec, pos, targets), antenna_amplitudes(spec, pos, targets)
    # Same float64 formulas in another evaluation order: a few ulp (the pattern's exp/arctan2 amplify a
    # relative rounding of the direction, ~1e-16, by at most the exponent's magnitude, < 30 here).
    np.testing.assert_allclose(got, ref, rtol=1e-13, atol=0)
    if spec.kind != "isotropic":
        assert ref.max() / ref.min() > 10  # the targets span main lobe and floor


def test_facet_paths_through_embree_equal_the_mitsuba_route(monkeypatch):
    m = _walk(7)
    radar = RadarConfig(links=[Link(name="a", tx=(3.0, 0.0, 1.1)), Link(name="b", tx=(0.0, -3.0, 1.1))])
    opts = dict(scene=get_scene("room", LOD, m.rig.height, radar.waveform.carrier_hz), lod=LOD, trace_fps=20.0,
                batch_frames=4, double_bounce=True)
    fast = facet_paths(m, radar, **opts)
    visibility._CASTERS.clear()
    monkeypatch.setattr(embree, "available", lambda: False)
    slow = facet_paths(m, radar, **opts)
    visibility._CASTERS.clear()
    for k in fast:
        assert np.array_equal(fast[k].ids, slow[k].ids)
        assert np.array_equal(fast[k].gains, slow[k].gains)
        assert np.array_equal(fast[k].delays, slow[k].delays, equal_nan=True)
        assert np.any(fast[k].ids >= load_avatar(LOD).n_faces)  # wall images took part


def test_meshes_traced_side_by_side_equal_the_serial_route(monkeypatch):
    """The direct-path mesh, the wall-image mesh and the clutter run in threads, then the two links are
    assembled in two: the path sets are bit for bit those of one thread (each keeps its own caster), and the
    stage times of all are reported."""
    from rtchannel.backends import facets

    m = _walk(7)
    radar = RadarConfig(links=[Link(name="a", tx=(3.0, 0.0, 1.1)), Link(name="b", tx=(0.0, -3.0, 1.1))])
    opts = dict(lod="5k", image_lod="2k", trace_fps=20.0, batch_frames=4)
    timing = {}
    side_by_side = facet_paths(m, radar, timing=timing, **opts)
    monkeypatch.setattr(facets, "_side_by_side", lambda: False)
    serial = facet_paths(m, radar, **opts)
    for k in serial:
        assert np.array_equal(side_by_side[k].ids, serial[k].ids)
        assert np.array_equal(side_by_side[k].gains, serial[k].gains)
        assert np.array_equal(side_by_side[k].delays, serial[k].delays, equal_nan=True)
        assert np.any(serial[k].ids >= load_avatar("5k").n_faces)  # wall images (on the 2k mesh) took part
    assert {"bvh", "rays", "gains", "assemble", "clutter"} <= set(timing) and all(v >= 0 for v in timing.values())
