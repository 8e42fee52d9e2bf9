"""Static clutter of the mesh backends: the returns of the scene's walls, floor and furniture.

Real radars see the room as well as the person; the slow-time MTI removes those static returns, but not
completely: a causal filter starting at rest passes them for its settling time (the start-up transient of
real recordings), and the body shadows part of the room frame by frame (a moving notch the MTI keeps).

The scene's static triangles are cut into patches no larger than half a range bin (`patch_size_m`), so the
clutter spreads over the range bins it occupies. Each patch is a persistent path antenna -> patch ->
antenna with the same surface model as the body's facets (`surface_scattering.facet_gains`): the diffuse
Lambertian term with the wall's own roughness (`Wall.roughness_m`, default `WALL_ROUGHNESS_M`: S from the
Kirchhoff model at each patch's incidence, `rtchannel.scene.material`; a fixed random phase per patch) and
the physical-optics term scaled by the same roughness's specular factor, whose patches add up coherently to
the wall's specular return; the body's wall and floor bounces use that same factor (`wall_factor`). The
link's polarisation ("V" or "H", its antennas') sets the reflection coefficients. A patch counts only when
the segments antenna -> patch are free of static geometry; the body shadows them partially, by single
knife-edge diffraction (`knife_edge`: 1 clear, 0.5 grazing, 22.6 dB deep), evaluated at the backend's traced
frames (the 2k body) and faded linearly between them. Antenna patterns apply as for every path.

A reduced set, not every triangle of a detailed scene: patches finer than half a range bin add nothing the
DSP can resolve, and the patches of one delay cell (1/16 of a range bin) are merged into one path
(`CELLS_PER_RANGE_BIN`), so an 8 m x 8 m room costs a few hundred paths, not tens of thousands.
"""
from __future__ import annotations

import copy
import math
import weakref
from dataclasses import dataclass

import numba
import numpy as np

from processing.constants import EPSILON_0_F_M
from processing.fast_time import max_range
from processing.pathset import PathSet
from processing.radar.propagation import bistatic_delay
from processing.radar.waveform import C0
from rtchannel.backends.knife_edge import box_margin_m, segment_amplitudes
from rtchannel.scene.material import WALL_ROUGHNESS_M  # noqa: F401 - its old home; the default wall's rms height
CLUTTER_ID_BASE = 1 << 40  # clutter path ids start here: never a facet id (facet + faces x kind)
CELLS_PER_RANGE_BIN = 16  # delay cells of the merged clutter paths per range bin c / 2B
MAX_PATCHES = 200_000  # bounds memory for very large scenes (a 8 m x 8 m room at 0.19 m is ~12k patches)


@dataclass(frozen=True)
class Patches:
    """Clutter patches: triangles [K, 3, 3] (m) with centroids, unit normals [K, 3], areas [K] (m^2), and per
    patch its shape index, slab (complex permittivity, thickness [m]) at the carrier and rms roughness [m]."""

    corners: np.ndarray
    centroids: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    shape: np.ndarray
    eta: np.ndarray
    thickness: np.ndarray
    roughness: np.ndarray | None = None


def patch_size_m(range_resolution_m: float) -> float:
    """Largest patch edge [m]: half a range bin, within 0.1-0.5 m."""
    return float(min(max(0.5 * range_resolution_m, 0.1), 0.5))


def _subdivide(a: np.ndarray, b: np.ndarray, c: np.ndarray, n: int) -> np.ndarray:
    """The n^2 congruent sub-triangles [n^2, 3, 3] of triangle (a, b, c) on a barycentric grid."""
    pts = lambda i, j: a + (b - a) * (i / n) + (c - a) * (j / n)  # noqa: E731
    out = []
    for i in range(n):
        for j in range(n - i):
            out.append((pts(i, j), pts(i + 1, j), pts(i, j + 1)))
            if i + j < n - 1:
                out.append((pts(i + 1, j), pts(i + 1, j + 1), pts(i, j + 1)))
    return np.array(out)


_PATCHES: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def scene_patches(rt_scene, frequency_hz: float, size_m: float) -> Patches:
    """Patches of every static triangle of an `RTScene` (edges at most `size_m` [m]); computed once per
    scene, carrier and size (the geometry is static)."""
    mine = _PATCHES.setdefault(rt_scene, {})
    key = (float(frequency_hz), float(size_m))
    if key not in mine:
        mine[key] = _patches(rt_scene, frequency_hz, size_m)
    return mine[key]


def _patches(rt_scene, frequency_hz: float, size_m: float) -> Patches:
    corners, shape, eta, thick, rough = [], [], [], [], []
    w = 2 * math.pi * frequency_hz
    for k, (name, v, f, slab) in enumerate(rt_scene._static):  # noqa: SLF001 - the scene's static meshes
        eps, sigma, thickness = (float(x) for x in slab)
        e = complex(eps, -sigma / (w * EPSILON_0_F_M))
        r = rt_scene.roughness(name) if hasattr(rt_scene, "roughness") else WALL_ROUGHNESS_M
        for tri in v[f]:
            edge = max(np.linalg.norm(tri[1] - tri[0]), np.linalg.norm(tri[2] - tri[1]),
                       np.linalg.norm(tri[0] - tri[2]))
            sub = _subdivide(tri[0], tri[1], tri[2], max(1, int(math.ceil(edge / size_m))))
            corners.append(sub)
            shape += [k] * len(sub)
            eta += [e] * len(sub)
            thick += [thickness] * len(sub)
            rough += [r] * len(sub)
    if not corners:
        z = np.zeros((0, 3))
        return Patches(np.zeros((0, 3, 3)), z, z, np.zeros(0), np.zeros(0, int), np.zeros(0, complex), np.zeros(0),
                       np.zeros(0))
    c3 = np.concatenate(corners)
    if len(c3) > MAX_PATCHES:
        raise ValueError(f"the scene's static geometry makes {len(c3)} clutter patches (limit {MAX_PATCHES})")
    cr = np.cross(c3[:, 1] - c3[:, 0], c3[:, 2] - c3[:, 0])
    dbl = np.linalg.norm(cr, axis=1)
    keep = dbl > 1e-12
    c3, cr, dbl = c3[keep], cr[keep], dbl[keep]
    return Patches(c3, c3.mean(axis=1), cr / dbl[:, None], 0.5 * dbl, np.asarray(shape)[keep],
                   np.asarray(eta)[keep], np.asarray(thick)[keep], np.asarray(rough, float)[keep])


def clutter_gains(patches: Patches, tx, rx, wavelength: float, frequency_hz: float, seed: int | None = 0,
                  roughness_m: float | None = None, polarization: str = "V") -> np.ndarray:
    """Complex path gains [K] (synthesiser convention, isotropic antennas) of the patches on tx -> patch -> rx
    (m) for a "V" or "H" polarised link; patches whose front side does not face both antennas get 0
    (two-sided: the normal is turned to the transmitter). Each patch has its wall's material
    (`SurfaceMaterial`: slab, and its rms roughness, or `roughness_m` [m] for all when given)."""
    from rtchannel.backends.surface_scattering import SurfaceMaterial, diffuse_phases, facet_gains

    tx, rx = np.asarray(tx, float), np.asarray(rx, float)
    n = patches.normals * np.sign(np.einsum("ij,ij->i", patches.normals, tx - patches.centroids))[:, None]
    faces_both = np.einsum("ij,ij->i", n, rx - patches.centroids) > 0
    rough = patches.roughness if patches.roughness is not None else np.full(len(patches.areas), WALL_ROUGHNESS_M)
    if roughness_m is not None:
        rough = np.full(len(patches.areas), float(roughness_m))
    phase = diffuse_phases(seed, len(patches.areas))
    out = np.zeros(len(patches.areas), complex)
    for key in {(e, t, r) for e, t, r in zip(patches.eta, patches.thickness, rough)}:
        sel = np.flatnonzero((patches.eta == key[0]) & (patches.thickness == key[1]) & (rough == key[2]) & faces_both)
        if sel.size == 0:
            continue
        mat = SurfaceMaterial(eta=key[0], thickness=key[1] or None, roughness_m=float(key[2]))
        out[sel] = facet_gains(mat, wavelength, patches.centroids[sel], n[sel], patches.areas[sel],
                               patches.corners[sel], tx, rx, True, None if phase is None else phase[sel],
                               polarization)
    return out


def clutter_paths(rt_scene, radar, times: np.ndarray, body_vertices: np.ndarray | None = None,
                  body_faces: np.ndarray | None = None, trace_idx: np.ndarray | None = None,
                  seed: int | None = 0, batch_frames: int = 16) -> dict[str, PathSet]:
    """Persistent clutter path sets, one per link of `radar`, at `times` [F] (s).

    Args:
        rt_scene: the `RTScene` whose static geometry makes the clutter.
        radar: `RadarConfig` (links, carrier, antennas, DSP range resolution).
        times: frame times [F] (s) of the motion the clutter goes with.
        body_vertices, body_faces: the skinned body at `trace_idx` frames [T, V, 3] (m) and its triangles
            [F_b, 3], which shadow the clutter; None: an empty room.
        trace_idx: frame indices [T] the body is given at (default every frame); shadows (knife-edge field
            factors, `knife_edge`) fade linearly between them.
        seed: seed of the patches' fixed diffuse phases.
    """
    from rtchannel.backends.visibility import caster_for

    wf = radar.waveform
    patches = scene_patches(rt_scene, wf.carrier_hz, patch_size_m(wf.range_resolution))
    f_n, k_n = len(times), len(patches.areas)
    trace_idx = np.arange(f_n) if trace_idx is None else np.asarray(trace_idx)
    antennas = np.unique(np.concatenate([[lk.tx_pos for lk in radar.links], [lk.rx_pos for lk in radar.links]]),
                         axis=0)
    # free[a, t, k]: field factor of segment antenna a -> patch k: 0 behind static geometry, else the body's
    # knife-edge factor at traced frame t (1 clear)
    free = np.ones((len(antennas), max(len(trace_idx), 1), k_n))
    if k_n:
        # an empty room: one degenerate (never hit) triangle on the first patch stands in for the body
        verts = (np.broadcast_to(patches.centroids[0], (1, 3, 3)).copy() if body_vertices is None
                 else np.asarray(body_vertices, float))
        faces = np.array([[0, 1, 2]]) if body_faces is None else np.asarray(body_faces)
        caster = caster_for(rt_scene, faces, verts, antennas, batch_frames, purpose="clutter")
        rays = [_patch_rays(pos, patches) for pos in antennas]
        n_slots = 1 if body_vertices is None else min(len(verts), caster.batch)
        open_ = [_static_free(caster, pos, patches, dirs, dists, n_slots) for pos, (dirs, dists) in zip(antennas, rays)]
        if body_vertices is None:  # the degenerate stand-in hides nothing: the static answer of cell 0
            static = np.stack([o[0] for o in open_]).astype(float)
            free = np.broadcast_to(static[:, None], (len(antennas), len(trace_idx), k_n))
        else:
            wavelength = wf.wavelength
            # a segment passing the body's box farther than the clearance of nu = -0.78 (plus a margin far above
            # float32 rounding) is neither blocked nor diffracted by it
            margins = [_BOX_MARGIN + box_margin_m(wavelength, float(d.max(initial=0.0))) for _, d in rays]
            for s0 in range(0, len(verts), batch_frames):  # one BVH build per batch, only rays near the body
                chunk = verts[s0:s0 + batch_frames]
                slots = np.arange(len(chunk))
                free[:, s0:s0 + len(chunk)] = [o[slots] for o in open_]
                lo, hi = chunk.min(axis=1), chunk.max(axis=1)
                near = [_near_box(pos, patches.centroids, o[slots], lo - m, hi + m)
                        for pos, o, m in zip(antennas, open_, margins)]
                if not any(n.any() for n in near):
                    continue
                caster.load(chunk)
                for a, ((dirs, dists), n) in enumerate(zip(rays, near)):
                    b, k = np.nonzero(n)
                    if b.size:
                        hit = caster.occluded_cells(np.broadcast_to(antennas[a], (b.size, 3)), dirs[k], dists[k], b)
                        free[a, s0 + b, k] = segment_amplitudes(antennas[a], patches.centroids[k], chunk, b, hit,
                                                                wavelength, faces)
    index = {tuple(p): i for i, p in enumerate(antennas)}
    # interpolation from traced to all frames: linear fade, as the facets' own gains
    if len(trace_idx) == f_n:
        j = j1 = np.arange(f_n)
        w = np.zeros(f_n)
        fade = False
    else:
        j = np.clip(np.searchsorted(trace_idx, np.arange(f_n), side="right") - 1, 0, max(len(trace_idx) - 2, 0))
        j1 = np.minimum(j + 1, len(trace_idx) - 1)
        span = np.where(j1 > j, trace_idx[j1] - trace_idx[j], 1)
        w = np.clip((np.arange(f_n) - trace_idx[j]) / span, 0.0, 1.0)
        fade = True
    out = {}
    for lk in radar.links:
        keep, inverse, cells, tau_c, w_k = _link_cells(rt_scene, radar, lk, patches, seed)
        vis_t = free[index[tuple(lk.tx_pos)]] * free[index[tuple(lk.rx_pos)]]  # [T, K]: both legs' shadows
        gains = np.zeros((f_n, len(tau_c)), complex)
        _cell_sums(np.ascontiguousarray(vis_t[:, keep]), inverse, w_k, j, j1, w, fade, gains)
        out[lk.name] = PathSet(times=np.asarray(times, float), delays=np.broadcast_to(tau_c, (f_n, len(tau_c))).copy(),
                               gains=gains, ids=CLUTTER_ID_BASE + cells,
                               delay_rates=np.zeros((f_n, len(tau_c))), link=lk.name)
    return out


_BOX_MARGIN = 0.01  # m: Embree's float32 rays and triangles stray ~1e-5 m at room coordinates


def _cell_step(wf) -> float:
    return 1.0 / (CELLS_PER_RANGE_BIN * wf.bandwidth_hz)


def _patch_rays(pos, patches: Patches):
    """Unit directions [K, 3] and lengths [K] (stopping short of the patch) of the rays antenna -> patch."""
    from rtchannel.backends.visibility import _STOP

    d = patches.centroids - pos
    dist = np.linalg.norm(d, axis=1)
    return d / dist[:, None], dist - _STOP


def _static_free(caster, pos, patches: Patches, dirs, dists, n_slots: int) -> np.ndarray:
    """[batch, K] rays antenna -> patch free of the static geometry in each cell of `caster` (cells differ
    in float32 rounding, so each gets its own answer), valid in the first `n_slots` cells; cast once per
    caster, antenna, patch set and cell (walls never move). Where the body is in the scene too, a ray is
    blocked iff static geometry or the body blocks it (any-hit), so the body's rays need casting only where
    this is free."""
    cache = caster.__dict__.setdefault("clutter_static", {})
    key = (np.asarray(pos, float).tobytes(), id(patches))
    got = cache.get(key)
    if got is None or got[0] is not patches:
        if len(cache) >= _STATIC_KEPT:
            cache.pop(next(iter(cache)))
        got = cache[key] = (patches, np.ones((caster.batch, len(dists)), bool), np.zeros(caster.batch, bool))
    _, free, done = got
    todo = np.flatnonzero(~done[:n_slots])
    if todo.size:
        k_n = len(dists)
        cells = np.repeat(todo, k_n)
        caster.clear()
        occ = caster.occluded_cells(np.broadcast_to(pos, (cells.size, 3)), np.tile(dirs, (todo.size, 1)),
                                    np.tile(dists, todo.size), cells)
        free[todo] = ~occ.reshape(todo.size, k_n)
        done[todo] = True
    return free


_STATIC_KEPT = 64  # antenna positions per caster (~0.15 MB each for a room)


@numba.njit(cache=True, nogil=True)
def _near_box(pos, cent, open_, lo, hi):
    """[B, K] open segments pos -> cent[k] that meet the box lo[b]..hi[b] (slab test)."""
    n_b, n_k = open_.shape
    out = np.zeros((n_b, n_k), np.bool_)
    for b in range(n_b):
        for k in range(n_k):
            if not open_[b, k]:
                continue
            t0, t1 = 0.0, 1.0
            for i in range(3):
                d = cent[k, i] - pos[i]
                if d == 0.0:
                    if pos[i] < lo[b, i] or pos[i] > hi[b, i]:
                        t0 = 2.0
                    continue
                a, c = (lo[b, i] - pos[i]) / d, (hi[b, i] - pos[i]) / d
                t0, t1 = max(t0, min(a, c)), min(t1, max(a, c))
            out[b, k] = t0 <= t1
    return out


@numba.njit(parallel=True, cache=True, nogil=True)
def _cell_sums(vis_t, inverse, w_k, j, j1, w, fade, out):
    """out[f, c] = sum over kept patches i of cell c of vis(f, i) w_k[i], vis (field factors) faded linearly
    between traced frames j[f], j1[f] with weight w[f] (the sparse product's order and arithmetic)."""
    for f in numba.prange(out.shape[0]):
        for i in range(w_k.shape[0]):
            if fade:
                v = (1 - w[f]) * vis_t[j[f], i] + w[f] * vis_t[j1[f], i]
            else:
                v = vis_t[f, i]
            if v != 0.0:
                out[f, inverse[i]] += w_k[i] * v


_LINKS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
_LINKS_KEPT = 32  # links per scene: a dataset worker's radars come back sample after sample


def _link_cells(rt_scene, radar, lk, patches: Patches, seed):
    """(kept patches [N], their cell [N], cell indices [C], cell delays [C] (s), weights [N] complex) of one link:
    the static part of its clutter (gains with antennas, delays, cells), cached per scene, radar, link and seed."""
    mine = _LINKS.setdefault(rt_scene, {})
    dump = getattr(radar, "model_dump_json", None)  # every radar setting (antennas, DSP ranges, waveform)
    key = None if dump is None else (dump(), lk.name, seed, id(patches))
    got = mine.get(key)
    if got is not None and got[0] is patches:
        return got[1]
    wf = radar.waveform
    # clutter outside the ranges the DSP processes (plus two bins of range-FFT leakage) cannot reach it
    lo = max(radar.dsp.min_range_m - 2 * wf.range_resolution, 0.0)
    hi = max_range(wf, radar.dsp) + 2 * wf.range_resolution
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    from processing.radar.antenna import link_polarization

    g = clutter_gains(patches, lk.tx_pos, lk.rx_pos, wf.wavelength, wf.carrier_hz, seed,
                      polarization=link_polarization(*radar.antennas(lk)))
    g = g * radar.link_gain(lk, patches.centroids)
    tau_all = bistatic_delay(patches.centroids, lk.tx_pos, lk.rx_pos)
    keep = np.flatnonzero((g != 0) & (np.abs(tau_all * C0 / 2 - mid) <= half))  # within the processed ranges
    tau = tau_all[keep]
    # patches in one delay cell of 1/(16 B) become one path at the cell's delay, each carrying its phase
    # offset at the band centre: exact in slow time (the shadows included), in fast time off by at most
    # pi B / (16 B) / 2 = 0.1 rad at the chirp's ends (1/32 of a range bin of smear)
    step = _cell_step(wf)
    cell = np.round(tau / step).astype(np.int64)
    cells, inverse = np.unique(cell, return_inverse=True)
    tau_c = cells * step
    w_k = g[keep] * np.exp(2j * np.pi * wf.carrier_hz * (tau - tau_c[inverse]))
    value = (keep, inverse.ravel().astype(np.int64), cells, tau_c, w_k)
    if key is not None:
        if len(mine) >= _LINKS_KEPT:
            mine.pop(next(iter(mine)))
        mine[key] = (patches, value)
    return value


def merged(a: PathSet, b: PathSet) -> PathSet:
    """Two persistent path sets of one link at the same frame times as one (paths side by side)."""
    rates = None
    if a.delay_rates is not None or b.delay_rates is not None:
        rates = np.concatenate([np.zeros_like(a.delays) if a.delay_rates is None else a.delay_rates,
                                np.zeros_like(b.delays) if b.delay_rates is None else b.delay_rates], axis=1)
    if a.delays.shape[0] != b.delays.shape[0] or not np.array_equal(a.times, b.times):
        raise ValueError("merged path sets must share their frame times")
    # Both parts passed PathSet's checks, which hold element by element, so their union does too: a copy of
    # `a` takes the joined arrays without checking tens of MB again.
    out = copy.copy(a)
    out.delays, out.gains = np.concatenate([a.delays, b.delays], axis=1), np.concatenate([a.gains, b.gains], axis=1)
    out.ids, out.delay_rates = np.concatenate([a.ids, b.ids]), rates
    return out


__all__ = ["WALL_ROUGHNESS_M", "Patches", "patch_size_m", "scene_patches", "clutter_gains", "clutter_paths",
           "merged", "CLUTTER_ID_BASE"]
