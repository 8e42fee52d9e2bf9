"""The `facets` backend: scattering from every triangle of the skinned body mesh.

Each body triangle f is a scatterer with a persistent identity. Per link (tx, rx) and frame, with F the
number of facets and W the number of planar walls (the floor is one), a path has id f + F kind:

- kind 0, direct tx -> f -> rx: delay (|c - tx| + |c - rx|) / c0 from the centroid c (float64), delay
  rate v_c . (u_tx + u_rx) / c0 with v_c the centroid velocity (mean of the skinned vertex velocities,
  exact for linear blend skinning) and u the unit vectors antenna -> centroid;
- first-order body-wall paths through image antennas mirrored in wall w (``walls=True``): kind 1 + 2w,
  tx' -> f -> rx, and kind 2 + 2w, tx -> f -> rx'; for a monostatic link (tx == rx) the two have the same
  delay and visibility and are merged into one path (kind 1 + 2w) whose gain is the sum of both (they
  differ only because the diffuse model evaluates Gamma for the incident direction, not reciprocal);
- double bounce, both antennas mirrored (``double_bounce``): kind 1 + 2W + w, tx' -> f -> rx' with both
  images in wall w (tx -> w -> f -> w -> rx; monostatically one path per facet and wall), and, with
  ``double_bounce="pairs"``, kind 1 + 3W + W w1 + w2 for tx mirrored in w1 and rx in w2 != w1 (merged
  monostatically into w1 < w2 like the single-bounce twins). Each reflection point must lie on its wall
  and both legs must be free (`visibility`); the gain carries both walls' reflection coefficients.

Gain (common scale, `surface_scattering`): a = lambda sqrt(sigma_f) / ((4 pi)^1.5 r_tx r_rx) on the
(image) geometry, with sigma_f from Sionna RT's diffuse model for the skin material (scattering
coefficient S, pattern, Fresnel Gamma of skin) times a fixed random phase per facet, plus (``po=True``,
the default) sqrt(1 - S^2) times the exact physical-optics integral over the triangle, the coherent,
specular part that Sionna's model scales by sqrt(1 - S^2): with S = 0.5 it carries 75 % of the reflected
power, so leaving it out underestimates the body (mean walk RCS about -8 instead of -3.1 dBsm, see
`rcs.walk_body_rcs`). Image paths are multiplied by the wall's co-polar slab reflection coefficient at
each reflection point, for the link's polarisation ("V" or "H", `LinkSpec.polarization`: both antennas'), and
by the wall's Kirchhoff specular factor exp(-(4 pi sigma_h cos(theta) / lambda)^2 / 2) (`Wall.roughness_m`,
the roughness its clutter scatters with, `rtchannel.scene.material`).

Antennas (`LinkSpec.tx_antenna`, `rx_antenna`; `facet_paths` takes the radar's, `RadarConfig.antennas`):
every path is multiplied by sqrt(G_tx(u_tx)) sqrt(G_rx(u_rx)) (`processing.radar.antenna.gain`), u the direction
from the antenna towards the facet centroid, or, for an antenna mirrored in wall w, towards the centroid's
mirror image in w (the reflection point lies on that line); the merged monostatic twins get their own
factors. Like the rest of the gain it is evaluated at the traced frames and interpolated in between (the
trunk at 2 m moving 1 m/s turns 3 deg per 0.1 s: the linear interpolation error of a 30-deg Gaussian beam's
amplitude exp(-2 ln2 psi^2 / HPBW^2) is at most (3 deg)^2 / 8 x 4 ln2 / (30 deg)^2 = 0.35 % per antenna;
fast limbs err more, like the rest of the interpolated gain; ``trace_fps=None`` evaluates every frame).
Both antennas isotropic: no factor at all (gains bit-identical to the unit-gain scale).

Diffuse phase (``seed``, default 0; None: none): a rough surface's diffuse field has a random phase per
resolution cell, fixed while the cell moves with the skin. Each facet gets one uniform phase
(`surface_scattering.diffuse_phases`, seeded by (seed, F)), the same in every frame (Doppler stays
coherent) and on every path of the facet (direct, via walls, double bounce: the same surface cell).
The expected coherent power of the diffuse sum is then its power sum, which is area-weighted, so the body's
diffuse return no longer grows with the mesh resolution (with equal phases a flat patch of N facets gave
N times its power). The PO term keeps its deterministic phase: it is the coherent part.

A facet absent in a frame (back-facing, occluded, reflection point off the wall, degenerate) has gain 0
and delay NaN, and the synthesiser fades it. Visibility (Mitsuba shadow rays on the shared scene, see
`visibility`) and gains are evaluated at `trace_fps` (default 10 Hz; None: every frame) and linearly
interpolated in between; delays and delay rates are exact at every frame. Gains follow the synthesiser's
phase convention exp(+j 2 pi f tau), i.e. they are the complex conjugates of Sionna-convention channel
coefficients.

With ``image_lod`` (default "2k") all image paths (single and double bounce) are traced on a coarser mesh
of the same skinned body (its own BVH and its own diffuse phases; ids f_c + F kind with f_c a coarse
facet): diffuse power is area-weighted and the PO term is the same surface integral, so the image power
is kept (coherent image power of a 2 s walk within 0.4 dB of the 5k image mesh) while the image path
count drops ~5x.

Cost drivers (see benchmarks/bench_facets.py): one BVH build per traced frame (batched, straight through
Mitsuba's Embree with its low-quality builder, ~1 ms CPU per 10k triangles), the Python/numpy work around ~10^4
shadow rays per antenna and traced frame (x 2 per wall and image facet; the casts themselves are cheap), the compiled
gains and antenna patterns (~0.2 us per facet path with PO, `facet_kernels`, reading the facets in place), and the
[frames, paths] output arrays, which also set the synthesiser's cost; the knobs are `trace_fps`, the LOD,
`image_lod`, `walls`, `double_bounce` and `min_relative_gain_db`.
"""
from __future__ import annotations

import os
import time
import weakref
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from processing.pathset import PathSet
from rtchannel.backends.facet_assemble import assemble, link_gains, merge_batches
from rtchannel.backends.surface_scattering import SurfaceMaterial, diffuse_phases
from rtchannel.backends.visibility import batch_visibility, caster_for, check_body_clearance
from processing.errors import InputError


@dataclass(frozen=True)
class LinkSpec:
    """A radar link by name, antenna positions [3] (m) and antenna patterns (`processing.radar.antenna` specs;
    None: isotropic, the backends' native unit-gain scale)."""

    name: str
    tx: np.ndarray
    rx: np.ndarray
    tx_antenna: object = None
    rx_antenna: object = None

    def antennas(self):
        """(tx, rx) patterns, or None when both are isotropic (no factor at all: bit-identical gains)."""
        kinds = {getattr(a, "kind", "isotropic") for a in (self.tx_antenna, self.rx_antenna)}
        return None if kinds == {"isotropic"} else (self.tx_antenna, self.rx_antenna)

    @property
    def polarization(self) -> str:
        """The link's polarisation, "V" or "H" (its antennas', which must agree; None antennas are "V")."""
        from processing.radar.antenna import link_polarization

        return link_polarization(self.tx_antenna, self.rx_antenna)


# Fast defaults (benchmarks/bench_facets.py; error cost in `rtchannel.analysis.speed_error`): visibility and gains
# at 10 Hz (gains interpolated, delays exact every frame), wall images on the 2k mesh (~5x fewer image
# paths, power kept), paths whose peak is 50 dB below the link's strongest dropped (bench walk: 0.06 % /
# 0.02 % of the power, 31 % / 22 % of the paths of radar 1 / 2; the PO glints are ~15 dB above a diffuse
# facet, so -40 dB would drop 1 % of the power). -40 dB keeps 36 % fewer paths than -50 dB (~20 % less
# synthesis time), but its p(v,t) EMD against the quick converged reference (full LOD, full accuracy, 4 seeds)
# is 0.0926 against 0.0920 m/s on the 5 s bench walk (0.0983 against 0.0985 on 2 s; -45 dB 0.0932, -35 dB
# 0.0943 on 5 s): the difference is 2 % of that reference's own error (0.033 m/s), but not an improvement,
# so -50 dB stays. (Tracing at 7.5 Hz instead of 10: 0.0959 m/s.) Double bounce via the floor only: on the
# 5 s bench walk (two radars, 10k body, room) the chain's CPU time is +15 % with every wall (True) and +34 % with every
# pair of walls ("pairs") against ~0 for the floor, while those paths carry 0.3-0.5 % (True) and 0.9-1.8 %
# ("pairs") of the received power there, the floor alone 0.01-0.02 % (vertical polarisation meets the
# floor near its Brewster angle; the walls behind the radars give most of it). The floor is kept on: it is
# in every room and under a fallen body. It is not free: re-measured once the rest got faster, the bench
# walk's chain takes 0.543 s with it and 0.513 s without (same process, alternating), and after the -50 dB
# cut it keeps 6 paths on radar 1 (peak 42 dB below the strongest) and none on radar 2 or on the seed-0 fall
# and sit (peaks 54-68 dB below). Dropping it is a model change the calibration would have to clear.
DEFAULT_TRACE_FPS = 10.0
DEFAULT_IMAGE_LOD = "2k"
DEFAULT_MIN_RELATIVE_GAIN_DB = -50.0
DEFAULT_DOUBLE_BOUNCE = "floor"
DEFAULT_WALL_CUT_DB = -30.0  # walls="auto": see `scene_model.DEFAULT_WALL_CUT_DB`


def trace_frame_indices(n_frames: int, fps: float, trace_fps: float | None) -> np.ndarray:
    """Frames at which visibility and gains are evaluated: every frame, or about `trace_fps` per second
    (always including the first and last frame)."""
    if trace_fps is None or trace_fps >= fps:
        return np.arange(n_frames)
    if not trace_fps > 0:
        raise InputError(f"trace_fps must be positive, got {trace_fps}")
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
               walls=(), po: bool = True, min_relative_gain_db: float | None = None,
               progress=None, timing: dict | None = None, batch_frames: int = 16,
               image_mesh: tuple | None = None, seed: int | None = 0,
               double_bounce: bool | str = DEFAULT_DOUBLE_BOUNCE, extra=None) -> dict[str, PathSet]:
    """Facet path sets of any deforming triangle mesh (the engine behind `facet_paths`).

    Args:
        scene: `rtchannel.scene.rt_scene.RTScene` holding this mesh as its body (``set_body``, ray casts).
        times: frame times [K] (s). vertices: [K, V, 3] (m). faces: [F, 3].
        velocities: vertex velocities [K, V, 3] (m/s) for analytic delay rates, or None.
        links: radar links (`LinkSpec`: positions and antenna patterns). wavelength: carrier wavelength [m].
            material: the mesh's surface material.
        trace_idx: frames at which visibility and gains are evaluated (default all).
        walls: planar walls for image paths (empty: no body-wall multipath).
        po: add the physical-optics term. min_relative_gain_db: drop paths whose peak |gain| is more
            than this many dB below the link's strongest path (e.g. -40); None keeps every path.
        progress: optional callable receiving the number of traced frames done after each BVH batch.
        batch_frames: traced frames whose bodies share one BVH build (`visibility.FrameBatchCaster`).
        timing: optional dict; wall time [s] is added under "clearance", "bvh", "rays", "gains", "assemble"
            (with an image mesh the two meshes are traced in two threads and their stage times add up).
        image_mesh: optional (vertices [K, Vc, 3], faces [Fc, 3], velocities or None) of a coarser mesh of
            the same body (Fc <= F) on which the wall-image paths are traced instead (ids f_c + F kind).
        seed: seed of the fixed random diffuse phase per facet (`diffuse_phases`); None: no random phase.
        double_bounce: double-bounce image paths (see `double_bounce_pairs`): False, True (= "same": both
            antennas mirrored in the same wall, every wall), "pairs" (any two walls), "floor" or a wall name.
        extra: optional callable (link name -> PathSet at `times` or None) whose paths are appended to the
            link's (the static clutter; called once tracing is done, so it may wait for a thread).

    Returns:
        {link name: persistent PathSet}; ids as in the module doc (F = number of faces).

    Raises:
        RadarPlacementError: an antenna within 1 cm of the static geometry, or within 1 cm of (or inside)
            the body at any frame.
        ValueError: a positive `min_relative_gain_db`, or an image mesh with more faces than the mesh.
    """
    if min_relative_gain_db is not None and not min_relative_gain_db <= 0:
        raise InputError(f"min_relative_gain_db must be <= 0 dB (relative to the strongest path), got "
                         f"{min_relative_gain_db}")
    vertices = np.asarray(vertices, float)
    faces = np.asarray(faces, np.int64)
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
    meshes = [(vertices, faces, velocities, True, not walls or image_mesh is None)]
    if walls and image_mesh is not None:
        v_c, f_c, vel_c = image_mesh
        if len(f_c) > len(faces):
            raise ValueError(f"the image mesh has more faces ({len(f_c)}) than the mesh ({len(faces)})")
        meshes.append((np.asarray(v_c, float), np.asarray(f_c, np.int64), vel_c, False, True))
    double = double_bounce_pairs(double_bounce, walls)
    antennas = [link.antennas() for link in links]
    pols = [link.polarization for link in links]

    def trace_mesh(mesh, mesh_clock):
        verts, fcs, vels, direct_paths, image_paths = mesh
        found = _trace(scene, verts, fcs, trace_idx, sources, pairs, walls if image_paths else [], material,
                       wavelength, po, batch_frames, direct_paths, mesh_clock, progress,
                       diffuse_phases(seed, len(fcs)), double if image_paths else [], antennas, pols)
        return found, verts, vels, fcs

    if len(meshes) == 1 or not _side_by_side():
        parts = [trace_mesh(m, clock) for m in meshes]
    else:
        # The direct paths (fine mesh) and the wall images (coarse mesh) are independent and cost about the
        # same; their kernels and Embree calls drop the GIL, so the two meshes are traced side by side
        # (each keeps its own caster and stage clock; the stage times of the two threads add up).
        clocks = [_Clock({}) for _ in meshes]
        with ThreadPoolExecutor(len(meshes)) as pool:
            parts = list(pool.map(trace_mesh, meshes, clocks))
        for c in clocks:
            for k, v in c.timing.items():
                timing[k] = timing.get(k, 0.0) + v
        clock.t = time.perf_counter()

    def assemble_link(li):
        link = links[li]
        return assemble([(p[0][li],) + p[1:] for p in parts], link.name, sources[pairs[li][0]], sources[pairs[li][1]],
                        walls, times, trace_idx, len(faces), min_relative_gain_db,
                        None if extra is None else extra(link.name))

    if len(links) == 1 or not _side_by_side():
        sets = [assemble_link(li) for li in range(len(links))]
    else:
        # a link's assembly is half numpy glue on one core; two links side by side keep both cores busy
        # (bench walk: the stage uses 1.7 cores instead of 1.4); outputs do not depend on the order
        with ThreadPoolExecutor(len(links)) as pool:
            sets = list(pool.map(assemble_link, range(len(links))))
    clock("assemble")
    return {link.name: ps for link, ps in zip(links, sets)}


def double_bounce_pairs(double_bounce: bool | str | None, walls) -> list[tuple[int, int]]:
    """(tx wall, rx wall) index pairs of the double-bounce paths: False/None/"off" none; True/"same" each
    wall with itself (tx -> wall -> facet -> same wall -> rx); "pairs" every ordered pair of walls; "floor"
    the lowest upward-facing plane(s) (normal within 8 deg of +z, within 1 cm of the lowest; none in a
    scene without one) with itself; any other string: the wall of that name with itself."""
    n = len(walls)
    if double_bounce in (False, None, "off"):
        return []
    if double_bounce in (True, "same"):
        return [(w, w) for w in range(n)]
    if double_bounce == "pairs":
        return [(a, b) for a in range(n) for b in range(n)]
    if double_bounce == "floor":
        up = [w for w, wall in enumerate(walls) if float(np.asarray(wall.normal, float)[2]) > 0.99]
        low = min((float(walls[w].point[2]) for w in up), default=0.0)
        return [(w, w) for w in up if float(walls[w].point[2]) < low + 0.01]
    names = [getattr(w, "name", None) for w in walls]
    if isinstance(double_bounce, str) and double_bounce in names:
        w = names.index(double_bounce)
        return [(w, w)]
    raise InputError(f"double_bounce must be true, false, 'same', 'pairs', 'floor' or a wall name {names}, "
                     f"got {double_bounce!r}")


def _trace(scene, vertices, faces, trace_idx, sources, pairs, walls, material, wavelength, po, batch_frames,
           direct_paths, clock, progress, phases, double, antennas, pols=None) -> list[dict]:
    """Visibility and gains at the traced frames of one mesh, batch by batch (one BVH build each)."""
    from rtchannel.body.skinning import face_frames

    caster = caster_for(scene, faces, vertices, sources, min(batch_frames, len(trace_idx)))
    batches = []
    for start in range(0, len(trace_idx), caster.batch):
        frames = trace_idx[start:start + caster.batch]
        caster.load(vertices[frames])
        clock("bvh")
        v = vertices[frames]
        normals, areas, degenerate, cent = face_frames(v, faces)  # centroids ((a + b) + c) / 3, one pass
        vis = batch_visibility(caster, cent, normals, ~degenerate, sources, walls, pairs,
                               {w for pair in double for w in pair})
        clock("rays")
        batches.append(link_gains(vis, pairs, sources, walls, start, cent, normals, areas,
                                  (v, faces), material, wavelength, po, phases,
                                  direct_paths, double=double, antennas=antennas, polarizations=pols))
        clock("gains")
        if progress is not None:
            progress(start + len(frames))
    return merge_batches(batches, len(pairs))


_STATIC_CHECKED: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


class _Clock:
    """Adds the wall time since the previous call to timing[name]."""

    def __init__(self, timing: dict):
        self.timing, self.t = timing, time.perf_counter()

    def __call__(self, name: str) -> None:
        now = time.perf_counter()
        self.timing[name] = self.timing.get(name, 0.0) + now - self.t
        self.t = now


def facet_paths(motion, radar, scene="room", lod: str = "10k", trace_fps: float | None = DEFAULT_TRACE_FPS,
                walls: bool | str = True, po: bool = True, skin=None,
                min_relative_gain_db: float | None = DEFAULT_MIN_RELATIVE_GAIN_DB,
                progress=None, velocity_method: str = "spline", timing: dict | None = None,
                batch_frames: int = 16, image_lod: str | None = DEFAULT_IMAGE_LOD, seed: int | None = 0,
                double_bounce: bool | str = DEFAULT_DOUBLE_BOUNCE, clutter: bool = True,
                trace_step_m: float | None = None, trace_step_deg: float | None = None,
                trace_max_gap_s: float = 1.0, wall_cut_db: float | None = DEFAULT_WALL_CUT_DB,
                stats: dict | None = None) -> dict[str, PathSet]:
    """Persistent facet path sets (one per link) of the skinned avatar moving with `motion`.

    The defaults are the fast setting (see `DEFAULT_TRACE_FPS`); ``trace_fps=None, image_lod=None,
    min_relative_gain_db=None`` is the full-accuracy one (every frame traced, every path kept).

    Args:
        motion: the pose sequence (`rtchannel.motion.pose.Motion`); the avatar is scaled to its rig height.
        radar: `rtchannel.radar.RadarConfig` (links and carrier).
        scene: "room", "free_space", a Mitsuba XML path, or an `RTScene` whose body is this LOD.
        lod: avatar level of detail ("full", "10k", "5k", "2k"), or "auto": the coarsest whose facets scatter
            like the smooth body at the carrier (`scene_model.resolve_lod`).
        trace_fps: rate [Hz] of visibility/gain evaluation (None: every motion frame); a speed knob.
            Coarser than the motion only when below its frame rate.
        trace_step_m: instead of `trace_fps`, trace where the body's fastest vertex has moved this far [m]
            since the last traced frame (`scene_model.adaptive_trace_indices`; at least every `trace_max_gap_s`).
        trace_step_deg: instead of `trace_fps`, trace where the angle between the facets' normals and their
            lines of sight to the antennas has turned this far [deg] (`scene_model.aspect_rate_deg_s` on the
            image mesh, or the mesh; at least every `trace_max_gap_s`): far from the radar and in still phases
            coarser.
        trace_max_gap_s: with `trace_step_m` or `trace_step_deg`, the longest time between traced frames [s].
        clutter: add the static clutter of the scene's walls, floor and furniture, shadowed by the body
            (`rtchannel.backends.clutter`); nothing to add in free space.
        walls: include first-order body-wall image paths: True (every wall), False, "auto" (the walls
            whose paths can reach the range window through the antennas' patterns, `scene_model.walls_in_view`)
            or comma-separated wall names.
        wall_cut_db: with ``walls="auto"``, cull a wall every antenna sees this many dB below its peak.
        stats: optional dict receiving what the scene-dependent options chose ("lod", "walls", "culled_walls",
            "traced_frames").
        po: add the physical-optics term to the diffuse gain (default on; off leaves only the diffuse part).
        skin: `rtchannel.scene.rt_scene.SkinMaterial` (default dry skin at the carrier).
        min_relative_gain_db: drop paths weaker than this (dB, negative) relative to the strongest.
        progress: callable receiving the number of traced frames done.
        velocity_method: "spline" or "central" (see `rtchannel.body.skinning`).
        batch_frames: traced frames sharing one BVH build (speed only; grazing facets may flip
            visibility with float32 ray rounding, ~1e-3 of the paths and ~1e-11 of the power).
        timing: optional dict receiving the wall time [s] of "skinning", "clearance", "bvh", "rays", "gains"
            and "assemble".
        image_lod: LOD on which the wall-image paths are traced (None: `lod`); a coarser one (e.g. "2k")
            gives ~5x fewer image paths with the same power (diffuse gains are area-weighted), while the
            direct paths keep `lod`. Image ids are then f_c + F kind, f_c a coarse facet.
        seed: seed of the fixed random phase of each facet's diffuse field (None: no random phase).
        double_bounce: double-bounce wall paths (tx and rx both mirrored): "floor" (default: the lowest
            upward-facing plane with itself), True (each wall with itself), "pairs" (every pair of walls),
            False, or one wall's name; see `double_bounce_pairs`.

    Returns:
        {link name: PathSet} with ids f + F kind, kind as in the module doc (0 direct, 1.. wall images).

    Raises:
        rtchannel.scene.rt_scene.RadarPlacementError: an antenna closer than 1 cm to the geometry.
    """
    from rtchannel.backends.scene_model import resolve_lod
    from rtchannel.body.avatar import load_avatar
    from rtchannel.scene.rt_scene import RTScene, get_scene
    from rtchannel.body.skinning import blend_points, matrix_derivatives, rest_for_motion

    wf = radar.waveform
    stats = {} if stats is None else stats
    lod = resolve_lod(lod, scene, wf.wavelength)
    rt = scene if isinstance(scene, RTScene) else get_scene(scene, lod, motion.rig.height, wf.carrier_hz, skin,
                                                            sionna=False)
    avatar = load_avatar(lod)
    if len(rt.body_faces) != avatar.n_faces:
        raise ValueError(f"scene body has {len(rt.body_faces)} triangles but LOD {lod!r} has {avatar.n_faces}")
    coarse = load_avatar(image_lod) if walls is not False and image_lod not in (None, lod) else None
    if coarse is not None and coarse.n_faces > avatar.n_faces:
        raise InputError(f"image_lod {image_lod!r} ({coarse.n_faces} triangles) is finer than lod {lod!r}")
    timing = {} if timing is None else timing
    t0 = time.perf_counter()
    # Positions and velocities in one blend: skinning is linear in the joint matrices.
    mats = np.concatenate([motion.skinning_matrices(), matrix_derivatives(motion, velocity_method)])

    def skinned(av):
        both = blend_points(av.weights, rest_for_motion(av, motion), mats)
        return both[:motion.n_frames], both[motion.n_frames:]

    verts, vels = skinned(avatar)
    image_mesh = None
    if coarse is not None:
        v_c, vel_c = skinned(coarse)
        image_mesh = (v_c, coarse.faces, vel_c)
    timing["skinning"] = timing.get("skinning", 0.0) + time.perf_counter() - t0
    links = [LinkSpec(lk.name, lk.tx_pos, lk.rx_pos, *radar.antennas(lk)) for lk in radar.links]
    material = SurfaceMaterial.from_skin(rt.skin, wf.carrier_hz)
    probe = (image_mesh[0], image_mesh[1]) if image_mesh is not None else (verts, avatar.faces)
    if trace_step_m is None and trace_step_deg is None:
        trace_idx = trace_frame_indices(motion.n_frames, motion.fps, trace_fps)
    else:
        from rtchannel.backends.scene_model import adaptive_frames

        sources = np.unique(np.concatenate([[lk.tx for lk in links], [lk.rx for lk in links]]), axis=0)
        trace_idx = adaptive_frames(motion.times, vels, probe, sources, trace_step_m, trace_step_deg,
                                    trace_max_gap_s)
    used_walls = _used_walls(rt.walls, walls, links, radar, wall_cut_db, stats)
    stats.update(lod=lod, walls=[getattr(w, "name", "?") for w in used_walls], traced_frames=len(trace_idx))
    with ThreadPoolExecutor(1) as pool:
        static = None
        if clutter and rt.static_meshes:
            # shadows need no more than the image LOD's body (2k by default; its BVH is 5x cheaper); the clutter
            # is independent of the body's paths, so it runs beside them (its own caster, GIL-free kernels)
            job = (rt, radar, motion.times, probe[0][trace_idx], probe[1], trace_idx, seed, batch_frames)
            static = pool.submit(_timed_clutter, *job) if _side_by_side() else _done(_timed_clutter(*job))
        # the clutter's columns are written into each link's arrays as they are assembled (no second copy)
        extra = None if static is None else (lambda name: static.result()[0][name])
        paths = mesh_paths(rt, motion.times, verts, avatar.faces, vels, links, wf.wavelength, material, trace_idx,
                           used_walls, po, min_relative_gain_db, progress, timing, batch_frames,
                           image_mesh if used_walls else None, seed, _culled_double(double_bounce, stats), extra)
        if static is not None:
            timing["clutter"] = timing.get("clutter", 0.0) + static.result()[1]
    return paths


def _side_by_side() -> bool:
    """Whether independent parts (the two meshes, the clutter) run in threads: with two or more cores for this
    process (a dataset worker pinned to one numba thread, one worker per core, keeps to its one core)."""
    import numba

    return (os.cpu_count() or 1) >= 2 and numba.get_num_threads() >= 2


def _done(value) -> Future:
    """A finished future holding `value` (the same interface as a submitted job's)."""
    f: Future = Future()
    f.set_result(value)
    return f


def _timed_clutter(*args) -> tuple[dict, float]:
    """(`clutter.clutter_paths`(*args), its wall time [s])."""
    from rtchannel.backends.clutter import clutter_paths

    t0 = time.perf_counter()
    return clutter_paths(*args), time.perf_counter() - t0


def _culled_double(double_bounce, stats: dict):
    """A double bounce named after a wall that ``walls="auto"`` culled is dropped with it."""
    if isinstance(double_bounce, str) and double_bounce in stats.get("culled_walls", {}):
        return False
    return double_bounce


def _used_walls(walls, choice: bool | str, links, radar, wall_cut_db, stats: dict) -> list:
    """The walls `choice` (True, False, "auto" or comma-separated names) selects; culled ones go to stats."""
    walls = list(walls)
    if choice is True:
        return walls
    if choice is False or not walls:
        return []
    if choice == "auto":
        from processing.fast_time import max_range
        from rtchannel.backends.scene_model import walls_in_view

        kept, culled = walls_in_view(walls, links, max_range(radar.waveform, radar.dsp),
                                     radar.waveform.range_resolution, wall_cut_db)
        stats["culled_walls"] = culled
        return kept
    names = [n.strip() for n in str(choice).split(",") if n.strip()]
    known = [getattr(w, "name", None) for w in walls]
    bad = [n for n in names if n not in known]
    if bad:
        raise InputError(f"walls: no wall named {bad[0]!r} in the scene (its walls: {', '.join(map(str, known))}; "
                         "or true, false, auto)")
    return [w for w in walls if getattr(w, "name", None) in names]
