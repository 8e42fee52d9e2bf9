"""The `facets` backend: deterministic scattering from every triangle of the skinned body mesh.

Each body triangle f is a scatterer with a persistent identity. Per link (tx, rx) and frame:

- direct path tx -> f -> rx (id f): delay (|c - tx| + |c - rx|) / c0 from the centroid c (float64), delay
  rate v_c . (u_tx + u_rx) / c0 with v_c the centroid velocity (mean of the skinned vertex velocities,
  exact for linear blend skinning) and u the unit vectors antenna -> centroid;
- first-order body-wall paths through image antennas mirrored in each planar wall (``walls=True``):
  tx' -> f -> rx (id f + F (1 + 2w)) and tx -> f -> rx' (id f + F (2 + 2w)); for a monostatic link
  (tx == rx) the two have the same delay and visibility and are merged into one path whose gain is the
  sum of both (id f + F (1 + 2w)); they differ in gain only because Sionna's diffuse model evaluates the
  Fresnel Gamma for the incident direction, which is not reciprocal.

Gain (common scale, `surface_scattering`): a = lambda sqrt(sigma_f) / ((4 pi)^1.5 r_tx r_rx) with
sigma_f from Sionna RT's diffuse model for the skin material (scattering coefficient S, pattern,
Fresnel Gamma of skin), plus, with ``po=True``, sqrt(1 - S^2) times the exact physical-optics integral
over the triangle (the coherent, specular-like part Sionna reduces by R = sqrt(1 - S^2)). Image paths
are multiplied by the wall's co-polar slab reflection coefficient at the reflection point.

A facet absent in a frame (back-facing, occluded, reflection point off the wall, degenerate) has gain 0
and delay NaN, and the synthesiser fades it. Visibility (Mitsuba shadow rays on the shared scene, see
`visibility`) and gains are evaluated at `trace_fps` (default: every frame) and linearly interpolated in
between; delays and delay rates are exact at every frame. Gains follow the synthesiser's phase convention
exp(+j 2 pi f tau), i.e. they are the complex conjugates of Sionna-convention channel coefficients.

Cost drivers (see benchmarks/bench_facets.py): one BVH refit per traced frame (batched), ~10^4 shadow rays
per antenna and traced frame (x 3 per wall with images), and the [frames, paths] output arrays; the knobs
are `trace_fps`, the LOD, `walls` and `min_relative_gain_db`.
"""
from __future__ import annotations

import time
import weakref
from dataclasses import dataclass

import numba
import numpy as np

from processing.pathset import PathSet
from processing.waveform import C0
from rtchannel.backends.surface_scattering import SurfaceMaterial, facet_gains, wall_factor
from rtchannel.backends.visibility import caster_for, check_body_clearance, direct_visibility, image_visibility
from rtchannel.backends.wall_images import mirror
from rtchannel.skinning import face_normals_and_areas


@dataclass(frozen=True)
class LinkSpec:
    """A radar link by name and antenna positions [3] (m)."""

    name: str
    tx: np.ndarray
    rx: np.ndarray


def trace_frame_indices(n_frames: int, fps: float, trace_fps: float | None) -> np.ndarray:
    """Frames at which visibility and gains are evaluated: every frame, or about `trace_fps` per second
    (always including the first and last frame)."""
    if trace_fps is None or trace_fps >= fps:
        return np.arange(n_frames)
    if not trace_fps > 0:
        raise ValueError(f"trace_fps must be positive, got {trace_fps}")
    step = fps / trace_fps
    idx = np.round(np.arange(0.0, n_frames - 1, step)).astype(int)
    return np.unique(np.concatenate([idx, [n_frames - 1]]))


def _unique_sources(links: list[LinkSpec]) -> tuple[np.ndarray, list[tuple[int, int]]]:
    pts: list[np.ndarray] = []
    pairs = []

    def index(p):
        for i, q in enumerate(pts):
            if np.array_equal(p, q):
                return i
        pts.append(np.asarray(p, float))
        return len(pts) - 1

    for link in links:
        pairs.append((index(link.tx), index(link.rx)))
    return np.array(pts), pairs


def mesh_paths(scene, times: np.ndarray, vertices: np.ndarray, faces: np.ndarray, velocities: np.ndarray | None,
               links: list[LinkSpec], wavelength: float, material: SurfaceMaterial, trace_idx=None,
               walls=(), po: bool = False, min_relative_gain_db: float | None = None,
               progress=None, timing: dict | None = None, batch_frames: int = 16) -> dict[str, PathSet]:
    """Facet path sets of any deforming triangle mesh (the engine behind `facet_paths`).

    Args:
        scene: `rtchannel.rt_scene.RTScene` holding this mesh as its body (``set_body``, ray casts).
        times: frame times [K] (s). vertices: [K, V, 3] (m). faces: [F, 3].
        velocities: vertex velocities [K, V, 3] (m/s) for analytic delay rates, or None.
        links: radar links. wavelength: carrier wavelength [m]. material: the mesh's surface material.
        trace_idx: frames at which visibility and gains are evaluated (default all).
        walls: planar walls for image paths (empty: no body-wall multipath).
        po: add the physical-optics term. min_relative_gain_db: drop paths whose peak |gain| is more
            than this many dB below the link's strongest path (e.g. -40); None keeps every path.
        progress: optional callable receiving the number of traced frames done after each one.
        batch_frames: traced frames whose bodies share one BVH build (`visibility.FrameBatchCaster`).
        timing: optional dict; wall time [s] is added under "clearance", "bvh", "rays", "gains", "assemble".

    Returns:
        {link name: persistent PathSet}; ids as in the module doc (F = number of faces).

    Raises:
        RadarPlacementError: an antenna within 1 cm of the static geometry, or within 1 cm of (or inside)
            the body at any frame.
        ValueError: a positive `min_relative_gain_db`.
    """
    if min_relative_gain_db is not None and not min_relative_gain_db <= 0:
        raise ValueError(f"min_relative_gain_db must be <= 0 dB (relative to the strongest path), got "
                         f"{min_relative_gain_db}")
    vertices = np.asarray(vertices, float)
    faces = np.asarray(faces, np.int64)
    n_faces = len(faces)
    trace_idx = np.arange(len(times)) if trace_idx is None else np.asarray(trace_idx)
    walls = list(walls)
    sources, pairs = _unique_sources(links)
    timing = {} if timing is None else timing
    clock = _Clock(timing)
    checked = _STATIC_CHECKED.setdefault(scene, set())
    if sources.tobytes() not in checked:  # static geometry never moves: check each antenna set once
        scene.set_body(vertices[trace_idx[0]])
        scene.check_clearance(sources)
        checked.add(sources.tobytes())
    check_body_clearance(times, vertices, faces, sources)  # the body at every frame
    clock("clearance")
    jobs = []  # (link, kind, slot, facet idx, point a, point b, wall index or -1, cos_w, antenna, merged)
    geo_c, geo_n, geo_a = [], [], []
    caster = caster_for(scene, faces, vertices, sources, min(batch_frames, len(trace_idx)))
    for slot, k in enumerate(trace_idx):
        cell = slot % caster.batch
        if cell == 0:
            caster.load(vertices[trace_idx[slot:slot + caster.batch]])
            clock("bvh")
        view = caster.view(cell)
        normals, areas, degenerate = face_normals_and_areas(vertices[k], faces)
        c = vertices[k][faces].mean(axis=1)
        geo_c.append(c)
        geo_n.append(normals)
        geo_a.append(areas)
        direct = direct_visibility(view, c, normals, ~degenerate, sources)
        images = None
        if walls:
            needed = [np.zeros(n_faces, bool) for _ in sources]
            for si_tx, si_rx in pairs:
                needed[si_tx] |= direct[si_rx]
                needed[si_rx] |= direct[si_tx]
            images = image_visibility(view, c, normals, needed, sources, walls)
        for li, (si_tx, si_rx) in enumerate(pairs):
            for kind, mask, p_a, p_b, via in _path_kinds(sources, si_tx, si_rx, direct, images, walls):
                idx = np.flatnonzero(mask)
                if idx.size:
                    w, cos_w, ant, merged = via if via is not None else (-1, None, None, False)
                    jobs.append((li, kind, slot, idx, p_a, p_b, w, None if cos_w is None else cos_w[idx], ant, merged))
        clock("rays")
        if progress is not None:
            progress(slot + 1)
    found = _job_gains(jobs, len(links), np.array(geo_c), np.array(geo_n), np.array(geo_a), vertices, faces,
                       trace_idx, walls, material, wavelength, po)
    clock("gains")
    out = {link.name: _assemble(found[li], link, sources[pairs[li][0]], sources[pairs[li][1]], walls, times,
                                trace_idx, vertices, faces, velocities, min_relative_gain_db)
           for li, link in enumerate(links)}
    clock("assemble")
    return out


_STATIC_CHECKED: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


class _Clock:
    """Adds the wall time since the previous call to timing[name]."""

    def __init__(self, timing: dict):
        self.timing, self.t = timing, time.perf_counter()

    def __call__(self, name: str) -> None:
        now = time.perf_counter()
        self.timing[name] = self.timing.get(name, 0.0) + now - self.t
        self.t = now


def _job_gains(jobs, n_links, cent, norm, area, vertices, faces, trace_idx, walls, material, wavelength, po,
               chunk: int = 250_000):
    """Gains of every (link, kind, traced frame, facet) job in a few large vectorised batches.

    Returns per link {kind: [(slot, facet idx, gains)]}."""
    found = [dict() for _ in range(n_links)]
    start = 0
    while start < len(jobs):
        stop, n = start, 0
        while stop < len(jobs) and (n == 0 or n + jobs[stop][3].size <= chunk):
            n += jobs[stop][3].size
            stop += 1
        batch = jobs[start:stop]
        start = stop
        sizes = [j[3].size for j in batch]
        slot = np.repeat([j[2] for j in batch], sizes)
        fidx = np.concatenate([j[3] for j in batch])
        p_a = np.repeat(np.array([j[4] for j in batch]), sizes, axis=0)
        p_b = np.repeat(np.array([j[5] for j in batch]), sizes, axis=0)
        c, n_, a = cent[slot, fidx], norm[slot, fidx], area[slot, fidx]
        corners = vertices[trace_idx[slot][:, None], faces[fidx]] if po else None
        g = facet_gains(material, wavelength, c, n_, a, corners, p_a, p_b, po)
        merged = np.repeat([j[9] for j in batch], sizes)
        if merged.any():  # monostatic: add the twin tx -> f -> rx' (same delay and visibility)
            m = merged
            g[m] += facet_gains(material, wavelength, c[m], n_[m], a[m], None if corners is None else corners[m],
                                 p_b[m], p_a[m], po)
        wall_of = np.repeat([j[6] for j in batch], sizes)
        for w in np.unique(wall_of[wall_of >= 0]):
            m = wall_of == w
            cos_w = np.concatenate([j[7] for j in batch if j[6] == w])
            ant = np.repeat(np.array([j[8] for j in batch if j[6] == w]), [j[3].size for j in batch if j[6] == w],
                            axis=0)
            q_dir = mirror(c[m], walls[w]) - ant  # antenna -> mirrored centroid: the first leg
            q_dir /= np.linalg.norm(q_dir, axis=1, keepdims=True)
            g[m] *= wall_factor(walls[w], cos_w, q_dir, wavelength)
        for j, part in zip(batch, np.split(g, np.cumsum(sizes)[:-1])):
            found[j[0]].setdefault(j[1], []).append((j[2], j[3], part))
    return found


def _path_kinds(sources, si_tx, si_rx, direct, images, walls):
    """(kind, mask [F], point a, point b, wall info or None) of every path family of one link."""
    tx, rx = sources[si_tx], sources[si_rx]
    mono = si_tx == si_rx
    out = [(0, direct[si_tx] & direct[si_rx], tx, rx, None)]
    if images is None:
        return out
    for w, wall in enumerate(walls):
        vt = images[si_tx][w]
        if vt is not None:
            out.append((1 + 2 * w, vt.mask & direct[si_rx], vt.image, rx, (w, vt.cos_w, tx, mono)))
        vr = images[si_rx][w]
        if vr is not None and not mono:
            out.append((2 + 2 * w, direct[si_tx] & vr.mask, tx, vr.image, (w, vr.cos_w, rx, False)))
    return out


def _assemble(found, link, tx, rx, walls, times, trace_idx, vertices, faces, velocities, min_db):
    """Dense PathSet of one link from the sparse per-trace-frame gains."""
    n_faces = len(faces)
    n_slots = len(trace_idx)
    ids_all, gains_all = [], []
    for kind, entries in sorted(found.items()):
        ids = np.unique(np.concatenate([idx for _, idx, _ in entries]))
        col = np.searchsorted(ids, np.arange(n_faces))
        g = np.zeros((n_slots, ids.size), complex)
        for slot, idx, gk in entries:
            g[slot, col[idx]] = gk
        ids_all.append(ids + n_faces * kind)
        gains_all.append(g)
    k = len(times)
    if not ids_all:  # nothing ever visible: one absent path keeps the output well-defined
        return PathSet(times=times, delays=np.full((k, 1), np.nan), gains=np.zeros((k, 1), complex),
                       ids=np.array([0]), delay_rates=np.zeros((k, 1)), link=link.name)
    ids = np.concatenate(ids_all)
    g_trace = np.concatenate(gains_all, axis=1)
    peak = np.abs(g_trace).max(axis=0)
    keep = peak > 0
    if min_db is not None:
        keep &= peak >= peak.max() * 10 ** (min_db / 20)
    ids, g_trace = ids[keep], np.ascontiguousarray(g_trace[:, keep])
    # Path end points: antenna or its wall image.
    kinds = ids // n_faces
    pa = np.broadcast_to(tx, (ids.size, 3)).copy()
    pb = np.broadcast_to(rx, (ids.size, 3)).copy()
    for kind in np.unique(kinds[kinds > 0]):
        wall = walls[(kind - 1) // 2]
        if kind % 2 == 1:
            pa[kinds == kind] = mirror(tx, wall)
        else:
            pb[kinds == kind] = mirror(rx, wall)
    t_tr = times[trace_idx]
    slot = np.clip(np.searchsorted(t_tr, times, side="right") - 1, 0, max(len(t_tr) - 2, 0))
    nxt = np.minimum(slot + 1, len(t_tr) - 1)
    span = np.where(nxt > slot, t_tr[nxt] - t_tr[slot], 1.0)
    w = np.where(nxt > slot, (times - t_tr[slot]) / span, 0.0)
    gains = np.empty((k, ids.size), complex)
    delays = np.empty((k, ids.size))
    rates = np.empty((k, ids.size))
    vel = velocities if velocities is not None else np.zeros((1, 1, 3))
    _fill_paths(vertices, np.asarray(vel, float), faces, ids % n_faces, pa, pb, g_trace, slot, nxt, w,
                velocities is not None, gains, delays, rates)
    return PathSet(times=times, delays=delays, gains=gains, ids=ids,
                   delay_rates=rates if velocities is not None else None, link=link.name)


@numba.njit(parallel=True, cache=True)
def _fill_paths(verts, vels, faces, fidx, pa, pb, g_trace, slot, nxt, w, has_vel, gains, delays, rates):
    """Per frame k and path p: gain interpolated between traced frames; centroid delay and its rate
    (NaN / 0 where the gain is 0). Fused so the [K, P] arrays are written once."""
    n_k, n_p = gains.shape
    for k in numba.prange(n_k):
        j0, j1, wk = slot[k], nxt[k], w[k]
        for p in range(n_p):
            g = (1.0 - wk) * g_trace[j0, p] + wk * g_trace[j1, p]
            gains[k, p] = g
            if g == 0:
                delays[k, p] = np.nan
                rates[k, p] = 0.0
                continue
            f = fidx[p]
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            ra2 = 0.0
            rb2 = 0.0
            dot_a = 0.0
            dot_b = 0.0
            for i in range(3):
                ci = (verts[k, a, i] + verts[k, b, i] + verts[k, c, i]) / 3.0
                da = ci - pa[p, i]
                db = ci - pb[p, i]
                ra2 += da * da
                rb2 += db * db
                if has_vel:
                    vi = (vels[k, a, i] + vels[k, b, i] + vels[k, c, i]) / 3.0
                    dot_a += vi * da
                    dot_b += vi * db
            ra = np.sqrt(ra2)
            rb = np.sqrt(rb2)
            delays[k, p] = (ra + rb) / C0
            rates[k, p] = (dot_a / ra + dot_b / rb) / C0 if has_vel else 0.0


def facet_paths(motion, radar, scene="room", lod: str = "10k", trace_fps: float | None = None,
                walls: bool = True, po: bool = False, skin=None, min_relative_gain_db: float | None = None,
                progress=None, velocity_method: str = "spline", timing: dict | None = None,
                batch_frames: int = 16) -> dict[str, PathSet]:
    """Persistent facet path sets (one per link) of the skinned avatar moving with `motion`.

    Args:
        motion: the pose sequence (`rtchannel.skeleton.Motion`); the avatar is scaled to its rig height.
        radar: `rtchannel.radar.RadarConfig` (links and carrier).
        scene: "room", "free_space", a Mitsuba XML path, or an `RTScene` whose body is this LOD.
        lod: avatar level of detail ("full", "10k", "5k", "2k").
        trace_fps: rate [Hz] of visibility/gain evaluation (None: every motion frame); a speed knob.
        walls: include first-order body-wall image paths.
        po: add the physical-optics term to the diffuse gain.
        skin: `rtchannel.rt_scene.SkinMaterial` (default dry skin at the carrier).
        min_relative_gain_db: drop paths weaker than this (dB, negative) relative to the strongest.
        progress: callable receiving the number of traced frames done.
        velocity_method: "spline" or "central" (see `rtchannel.skinning`).
        batch_frames: traced frames sharing one BVH build (speed only; grazing facets may flip
            visibility with float32 ray rounding, ~1e-3 of the paths and ~1e-11 of the power).
        timing: optional dict receiving the wall time [s] of "skinning", "clearance", "bvh", "rays", "gains"
            and "assemble".

    Returns:
        {link name: PathSet} with ids f (direct) and f + F (1 + image index) (wall images).

    Raises:
        rtchannel.rt_scene.RadarPlacementError: an antenna closer than 1 cm to the geometry.
    """
    from rtchannel.avatar import load_avatar
    from rtchannel.rt_scene import RTScene, get_scene
    from rtchannel.skinning import blend_points, matrix_derivatives, rest_for_motion

    wf = radar.waveform
    rt = scene if isinstance(scene, RTScene) else get_scene(scene, lod, motion.rig.height, wf.carrier_hz, skin)
    avatar = load_avatar(lod)
    if len(rt.body_faces) != avatar.n_faces:
        raise ValueError(f"scene body has {len(rt.body_faces)} triangles but LOD {lod!r} has {avatar.n_faces}")
    timing = {} if timing is None else timing
    t0 = time.perf_counter()
    # Positions and velocities in one blend: skinning is linear in the joint matrices.
    mats = np.concatenate([motion.skinning_matrices(), matrix_derivatives(motion, velocity_method)])
    both = blend_points(avatar.weights, rest_for_motion(avatar, motion), mats)
    verts, vels = both[:motion.n_frames], both[motion.n_frames:]
    timing["skinning"] = timing.get("skinning", 0.0) + time.perf_counter() - t0
    links = [LinkSpec(lk.name, lk.tx_pos, lk.rx_pos) for lk in radar.links]
    material = SurfaceMaterial.from_skin(rt.skin, wf.carrier_hz)
    return mesh_paths(rt, motion.times, verts, avatar.faces, vels, links, wf.wavelength, material,
                      trace_frame_indices(motion.n_frames, motion.fps, trace_fps),
                      rt.walls if walls else (), po, min_relative_gain_db, progress, timing, batch_frames)


def rcs_backend(skin=None, po: bool = True):
    """A `rtchannel.backends.rcs.BackendFn` for static calibration targets in free space: facets of the
    mesh with `skin` (an `rtchannel.rt_scene.SkinMaterial`, e.g. `rcs.PEC`; default dry skin) as
    material, diffuse plus (if `po`) physical optics. Gains are in the synthesiser's convention, so
    coherent sums must use exp(+j 2 pi f tau)."""
    from rtchannel.rt_scene import RTScene

    def run(vertices, faces, radar):
        wf = radar.waveform
        scene = RTScene("free_space", faces, vertices, wf.carrier_hz, skin)
        links = [LinkSpec(lk.name, lk.tx_pos, lk.rx_pos) for lk in radar.links]
        v = np.stack([vertices, vertices])
        return mesh_paths(scene, np.array([0.0, 0.1]), v, faces, None, links, wf.wavelength,
                          SurfaceMaterial.from_skin(scene.skin, wf.carrier_hz), po=po)

    return run
