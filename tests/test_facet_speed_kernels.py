"""The facets backend's fused kernels (issue 26) compute what the numpy formulations they replace compute: the
compiled skinning blend, face normals and centroids, the monostatic twin evaluated in the forward path's pass,
the facing / wall-hit / ray set-up of `visibility`, the monostatic delay shortcut of `_fill_paths`, the
path-set checks in blocks and `merged` without re-checking."""
import numpy as np
import pytest

from processing.errors import InputError
from processing.pathset import PathSet
from processing.radar.waveform import C0
from rtchannel.backends import embree, facet_assemble, facet_kernels, visibility
from rtchannel.backends.clutter import merged
from rtchannel.backends.wall_images import PlanarWall, in_convex_polygon, mirror
from rtchannel.body import skinning
from rtchannel.body.avatar import load_avatar
from rtchannel.body.skinning import face_frames, face_normals_and_areas, matrix_derivatives, rest_for_motion
from rtchannel.motion import pose
from rtchannel.motion.procedural import generate

# Bit-for-bit where numpy sums three or four terms as its einsum does here (two SIMD lanes); elsewhere the
# same products in another order: a few ulp of metres.
ULP_M = 1e-14


@pytest.fixture(scope="module")
def walk():
    m = generate("walk", duration=1.0, start=(-1.0, 0.3), fps=30.0)
    return m, load_avatar("2k")


def test_compiled_blend_equals_the_sparse_einsum_route(walk):
    m, av = walk
    mats = np.concatenate([m.skinning_matrices(), matrix_derivatives(m)])
    rest = rest_for_motion(av, m)
    fast = skinning.blend_points(av.weights, rest, mats)
    ref = pose.blend_points(av.weights, rest, mats)
    assert len(rest) >= skinning.COMPILED_MIN_POINTS and fast.shape == ref.shape
    np.testing.assert_allclose(fast, ref, rtol=0, atol=ULP_M)
    few = skinning.blend_points(av.weights[:40], rest[:40], mats)  # markers: the numpy route itself
    assert np.array_equal(few, pose.blend_points(av.weights[:40], rest[:40], mats))


def test_face_frames_equal_face_normals_and_areas_and_the_corner_mean(walk):
    m, av = walk
    v = pose.blend_points(av.weights, rest_for_motion(av, m), m.skinning_matrices()[:4]).copy()
    v[1, av.faces[7, 1]] = v[1, av.faces[7, 0]]  # a collapsed triangle: the neighbours' normal
    n, a, d, c = face_frames(v, av.faces)
    n_ref, a_ref, d_ref = face_normals_and_areas(v, av.faces)
    assert d[1, 7] and d.sum() >= 1
    assert np.array_equal(a, a_ref) and np.array_equal(d, d_ref) and np.array_equal(n, n_ref)
    assert np.array_equal(c, (v[:, av.faces[:, 0]] + v[:, av.faces[:, 1]] + v[:, av.faces[:, 2]]) / 3)


@pytest.mark.parametrize("eta, thickness, po", [(40 - 20j, 0.0, True), (None, 0.0, True), (5 - 1j, 0.01, True),
                                                (40 - 20j, 0.0, False)])
def test_twin_in_the_same_pass_equals_the_swapped_call_bitwise(walk, eta, thickness, po):
    m, av = walk
    v = pose.blend_points(av.weights, rest_for_motion(av, m), m.skinning_matrices()[:3])
    norm, area, _ = face_normals_and_areas(v, av.faces)
    cent = v[:, av.faces].mean(axis=2)
    rng = np.random.default_rng(5)
    e = 3000
    eb, ef = rng.integers(0, 3, e), rng.integers(0, len(av.faces), e)
    p_a = np.broadcast_to([3.0, 0.0, 1.1], (e, 3)).copy()
    p_b = rng.uniform(-3, 3, (e, 3))
    p_b[:10] = p_a[:10]  # monostatic elements: the reverse takes its own Fresnel coefficients
    twin = rng.random(e) < 0.5
    args = (cent, norm, area, v, av.faces, eb, ef)
    par = (eta, thickness, 0.0124, 0.5, 0.1, po)
    d, s, d_rev, s_rev = facet_kernels.indexed_gains(*args, p_a, p_b, *par, reverse=twin)
    d0, s0 = facet_kernels.indexed_gains(*args, p_a, p_b, *par)
    d1, s1 = facet_kernels.indexed_gains(*args, p_b, p_a, *par)
    assert np.array_equal(d, d0) and np.array_equal(d_rev[twin], d1[twin])
    if po:
        assert np.array_equal(s, s0) and np.array_equal(s_rev[twin], s1[twin])
        assert not np.array_equal(s1[twin], s0[twin])  # the reverse path differs (polarisation)
    assert np.abs(d1).max() > 0


def _numpy_facing(normals, centroids, usable, pos):
    return usable & (np.einsum("bfi,bfi->bf", normals, pos - centroids) > 0)


def _numpy_wall_hits(centroids, normals, need, h_c, h_src, image, wall):
    b, f = np.nonzero(need & (h_c > 0) & (np.einsum("bfi,bfi->bf", normals, image - centroids) > 0))
    c = centroids[b, f]
    q = c + (h_c[b, f] / (h_c[b, f] + h_src))[:, None] * (image - c)
    inside = in_convex_polygon(q, wall)
    return b[inside], f[inside], q[inside]


def _frames(walk, n=4):
    m, av = walk
    v = pose.blend_points(av.weights, rest_for_motion(av, m), m.skinning_matrices()[:n])
    n_, _, d, c = face_frames(v, av.faces)
    return v, n_, ~d, c


def _square(centre, normal, half):
    """A square [4, 3] of half-width `half` (m) in the plane through `centre` with `normal`."""
    u = np.cross(normal, [0.0, 0.0, 1.0] if abs(normal[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    return np.array([centre + half * (a * u + b * v) for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))])


def test_facing_and_wall_hits_select_as_numpy(walk):
    _, normals, usable, cent = _frames(walk)
    sources = np.array([[3.0, 0.0, 1.1], [0.2, -3.0, 1.3]])
    at, s, b, f = visibility._facing(normals, cent, usable, sources)
    for k, pos in enumerate(sources):
        ref = _numpy_facing(normals, cent, usable, pos)
        assert np.array_equal(np.flatnonzero(ref), at[s == k] - k * ref.size)
        assert np.array_equal(np.nonzero(ref), (b[s == k], f[s == k]))
    # a tilted wall (summation order matters) and the floor, with polygons cutting the body's images
    n_t = np.array([0.9, 0.2, 0.1]) / np.linalg.norm([0.9, 0.2, 0.1])
    tilted = PlanarWall(name="tilted", point=np.array([-3.0, 0.0, 0.0]), normal=n_t,
                        polygon=_square(np.array([-3.0, 0.3, 1.0]), n_t, 0.8), relative_permittivity=5 - 0.1j)
    floor = PlanarWall(name="floor", point=np.zeros(3), normal=np.array([0.0, 0.0, 1.0]),
                       polygon=_square(np.array([-0.8, 0.3, 0.0]), np.array([0.0, 0.0, 1.0]), 0.3),
                       relative_permittivity=5 - 0.1j)
    pos = sources[0]
    for wall in (tilted, floor):
        nw = np.asarray(wall.normal, float)
        h_c = (cent - wall.point) @ nw
        h_src = float((pos - wall.point) @ nw)
        image = mirror(pos, wall)
        poly = np.asarray(wall.polygon, float)
        got = visibility._wall_hits(cent, normals, usable, h_c, h_src, image, poly,
                                    np.cross(np.roll(poly, -1, axis=0) - poly, nw))
        ref = _numpy_wall_hits(cent, normals, usable, h_c, h_src, image, wall)
        assert 0 < len(ref[0]) < usable.sum()
        for x, y in zip(got, ref):
            assert np.array_equal(x, y)


def test_packed_rays_equal_the_numpy_set_up(walk):
    """The compiled ray records carry the numpy route's float32 origins, directions and lengths bit for bit."""
    _, _, usable, cent = _frames(walk)
    b, f = np.nonzero(usable)
    rng = np.random.default_rng(6)
    start = rng.uniform(-3, 3, (b.size, 3))
    stop = np.where(rng.random(b.size) < 0.5, 1e-4, 1e-3)
    stop[:3] = 50.0  # no length left: never cast, never free
    offsets = rng.uniform(-40, 40, (usable.shape[0], 3))
    end = cent[b, f]
    rays, valid = np.empty((b.size, 12), np.float32), np.empty(b.size, bool)
    embree.pack_rays(start, np.zeros(0, np.int64), end, stop, b, offsets, rays, rays.view(np.uint32), valid)
    d = end - start
    dist = np.sqrt(np.einsum("ij,ij->i", d, d))
    t = dist - stop
    assert np.array_equal(rays[:, 0:3], (start + offsets[b]).astype(np.float32))
    assert np.array_equal(rays[:, 4:7], (d / np.where(dist > 0, dist, 1.0)[:, None]).astype(np.float32))
    assert np.array_equal(rays[:, 8], np.maximum(t, 0.0).astype(np.float32))
    assert np.array_equal(valid, t > 0) and not valid[:3].any()
    assert (rays.view(np.uint32)[:, 9] == 0xFFFFFFFF).all() and not rays[:, [3, 7]].any()
    sources = np.array([[3.0, 0.0, 1.1], [0.0, 3.0, 1.0]])
    s_idx = rng.integers(0, 2, b.size)
    direct, ok2 = np.empty_like(rays), np.empty_like(valid)
    embree.pack_direct(sources, s_idx, cent, b, f, 1e-4, offsets, direct, direct.view(np.uint32), ok2)
    ref, ok1 = np.empty_like(rays), np.empty_like(valid)
    embree.pack_rays(sources[s_idx], np.zeros(0, np.int64), end, np.array([1e-4]), b, offsets, ref,
                          ref.view(np.uint32), ok1)
    assert np.array_equal(direct.view(np.uint32), ref.view(np.uint32)) and np.array_equal(ok1, ok2)


def test_fill_paths_monostatic_shortcut_equals_the_two_leg_formula(walk):
    m, av = walk
    mats = m.skinning_matrices()
    v = pose.blend_points(av.weights, rest_for_motion(av, m), mats)
    vel = np.gradient(v, 1 / m.fps, axis=0)
    k, faces = len(v), av.faces.astype(np.int64)
    fidx = np.array([3, 50, 700, 1200])
    pa = np.array([[3.0, 0.0, 1.1]] * 4)
    pb = pa.copy()
    pb[1] = [2.0, -1.0, 0.5]  # one bistatic path among monostatic ones
    g_trace = np.ones((2, 4), complex)
    g_trace[:, 2] = 0  # absent
    slot, nxt, w = np.zeros(k, np.int64), np.ones(k, np.int64), np.linspace(0, 1, k)
    gains, delays, rates = np.empty((k, 4), complex), np.empty((k, 4)), np.empty((k, 4))
    facet_assemble._fill_paths(v, vel, faces, fidx, pa, pb, g_trace, slot, nxt, w, True, gains, delays, rates)
    corner = [v[:, faces[fidx, i]] for i in range(3)]
    cent = (corner[0] + corner[1] + corner[2]) / 3.0
    cvel = sum(vel[:, faces[fidx, i]] for i in range(3)) / 3.0
    da, db = cent - pa, cent - pb
    ra = np.sqrt((da[..., 0] ** 2 + da[..., 1] ** 2) + da[..., 2] ** 2)
    rb = np.sqrt((db[..., 0] ** 2 + db[..., 1] ** 2) + db[..., 2] ** 2)
    dot_a = (cvel[..., 0] * da[..., 0] + cvel[..., 1] * da[..., 1]) + cvel[..., 2] * da[..., 2]
    dot_b = (cvel[..., 0] * db[..., 0] + cvel[..., 1] * db[..., 1]) + cvel[..., 2] * db[..., 2]
    present = np.array([True, True, False, True])
    assert np.array_equal(delays[:, present], ((ra + rb) / C0)[:, present])
    assert np.array_equal(rates[:, present], ((dot_a / ra + dot_b / rb) / C0)[:, present])
    assert np.isnan(delays[:, 2]).all() and not rates[:, 2].any()


def _pathset(k=40, p=3000, seed=7):
    rng = np.random.default_rng(seed)
    g = (rng.normal(size=(k, p)) + 1j * rng.normal(size=(k, p))) * (rng.random((k, p)) < 0.7)
    d = np.where(g != 0, rng.uniform(1e-9, 1e-7, (k, p)), np.nan)
    return np.arange(k) / 10.0, d, g


@pytest.mark.parametrize("spoil, message", [
    (lambda d, g: g.__setitem__((39, 2999), np.nan + 0j), "NaN/inf gains"),
    (lambda d, g: g.__setitem__((5, 7), complex(1.0, np.inf)), "NaN/inf gains"),
    (lambda d, g: (g.__setitem__((20, 5), 1.0), d.__setitem__((20, 5), np.nan)), "no finite delay"),
    (lambda d, g: (g.__setitem__((20, 5), 1.0), d.__setitem__((20, 5), np.inf)), "no finite delay"),
    (lambda d, g: (g.__setitem__((38, 1), 1.0), d.__setitem__((38, 1), -1e-9)), "negative delays"),
])
def test_blocked_path_set_checks_name_the_same_problems(spoil, message):
    t, d, g = _pathset()
    PathSet(times=t, delays=d, gains=g)
    PathSet(times=t, delays=np.asfortranarray(d), gains=np.asfortranarray(g))  # strided gains: checked as well
    spoil(d, g)
    with pytest.raises(InputError, match=message):
        PathSet(times=t, delays=d, gains=g)
    with pytest.raises(InputError, match=message):
        PathSet(times=t, delays=np.asfortranarray(d), gains=np.asfortranarray(g))


def test_merged_equals_the_checked_concatenation():
    t, d, g = _pathset()
    a = PathSet(times=t, delays=d, gains=g, ids=np.arange(d.shape[1]), delay_rates=np.ones_like(d), link="r")
    b = PathSet(times=t, delays=d[:, :5], gains=g[:, :5], ids=100 + np.arange(5), link="r")
    got = merged(a, b)
    ref = PathSet(times=t, delays=np.concatenate([d, d[:, :5]], axis=1), gains=np.concatenate([g, g[:, :5]], axis=1),
                  ids=np.concatenate([a.ids, b.ids]), link="r",
                  delay_rates=np.concatenate([np.ones_like(d), np.zeros_like(d[:, :5])], axis=1))
    for field in ("times", "delays", "gains", "ids", "delay_rates"):
        assert np.array_equal(getattr(got, field), getattr(ref, field), equal_nan=True)
    assert got.link == "r" and a.n_paths == d.shape[1]  # the inputs are left alone
    with pytest.raises(ValueError, match="frame times"):
        merged(a, PathSet(times=t + 1, delays=d[:, :5], gains=g[:, :5], ids=np.arange(5), link="r"))


def test_assemble_appends_an_extra_path_set_like_merged():
    # a link on which no facet is ever visible still carries the extra (clutter) paths, after the absent
    # path; an extra at other frame times is refused
    t, d, g = _pathset(k=6, p=4)
    extra = PathSet(times=t, delays=d, gains=g, ids=100 + np.arange(4), link="r")
    faces = np.array([[0, 1, 2]])
    verts = np.zeros((6, 3, 3))
    args = ("r", np.zeros(3), np.zeros(3), [], t, np.arange(6), 1, None)
    alone = facet_assemble.assemble([({}, verts, None, faces)], *args)
    got = facet_assemble.assemble([({}, verts, None, faces)], *args, extra=extra)
    ref = merged(alone, extra)
    for field in ("delays", "gains", "ids", "delay_rates"):
        assert np.array_equal(getattr(got, field), getattr(ref, field), equal_nan=True)
    with pytest.raises(ValueError, match="frame times"):
        facet_assemble.assemble([({}, verts, None, faces)], *args,
                                extra=PathSet(times=t + 1, delays=d, gains=g, ids=np.arange(4), link="r"))
