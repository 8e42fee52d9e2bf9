"""What a scene needs modelled: the mesh backend's settings derived from the radar, the room and the motion.

Four rules, each a switchable `facets` option (``lod="auto"``, ``walls="auto"``, ``trace_step_m``,
``trace_step_deg``), each measured (`rtchannel bench --calibrate`, `benchmarks/bench_trace_rules.py`;
docs/results.md, issue 26):

- **Body LOD from the wavelength.** A faceted convex surface of curvature radius rho scatters like the smooth
  one when each facet's specular lobe (width ~ lambda / (2 L) for a facet of size L) is wider than the angle
  between neighbouring facets' normals (~ L / rho), i.e. when L <= sqrt(lambda rho / 2): the facet is no
  larger than the first Fresnel zone of the curved surface (for R >> rho the Fresnel zone of a convex body
  is sqrt(lambda rho / 2), not sqrt(lambda R)). With rho = 5 cm, the radius of a forearm or a calf (the
  body's tightest large surfaces; the trunk's is ~15 cm), that is 1.8 cm at 24.125 GHz and 3.6 cm at
  5.8 GHz. ``lod="auto"`` takes the coarsest avatar whose median edge length meets it: 10k at 24 GHz
  (median edge 1.6 cm), 2k at 5.8 GHz (3.6 cm). The range resolution never decides here: the avatar's
  largest facets (18 cm at 2k) are far below any room radar's range bin.
- **Walls that can reach the processed range window through the antennas' patterns.** A wall's image
  paths are at least |tx' - rx| long (triangle inequality through the image antenna tx'), so a wall whose
  image of every link's antennas lies beyond the largest used range plus `RANGE_MARGIN_BINS` bins cannot put
  more than the range window's far sidelobes (boxcar: < -20 dB three bins out) into the signature. A wall
  every antenna sees only `wall_cut_db` or more below its pattern's peak (the best point of the wall
  polygon, sampled on a grid) carries image paths at least that much below the direct body paths (|Gamma| <= 1
  and the image leg is the longer one). ``walls="auto"`` keeps the others; double bounces follow.
- **Trace rate from the fastest limb.** Visibility and gains are interpolated between traced frames (delays
  are exact at every frame), so the interpolation error grows with how far the body moves between them.
  ``trace_step_m`` places traced frames where the fastest vertex of the body (99th percentile of the
  vertex speeds, so one badly skinned vertex does not decide) has travelled `trace_step_m` metres since
  the last one: a fall's impact is traced densely, the still seconds before a sit-down sparsely.
- **Trace rate from the aspect the radar sees.** What interpolation between traced frames misses is how a
  facet's physical-optics lobe (width ~ lambda / (2 L)) sweeps past the antenna, i.e. how fast the angle
  between a facet's normal and its line of sight turns, not how far the facet travels: a trunk pitching
  forward in a sit-down turns its glints quickly while moving little (the distance rule measured badly
  there), and the line of sight turns by v_perp / R, so the same motion far from the radar needs fewer
  traced frames than near it. ``trace_step_deg`` places traced frames where that angle (the `ASPECT_QUANTILE`
  of the facets facing an antenna, the coarser mesh's facets) has turned `trace_step_deg` degrees since the
  last one.
"""
from __future__ import annotations

from functools import cache

import numpy as np

from processing.errors import InputError

LIMB_CURVATURE_M = 0.05  # radius of a forearm / calf: the body's tightest large surfaces (see module doc)
RANGE_MARGIN_BINS = 3  # a boxcar range window's sidelobes are below -20 dB three bins from the peak
ASPECT_QUANTILE = 0.9  # of the facets' aspect rates: the limbs' glints, not the few fastest facets of a hand
DEFAULT_WALL_CUT_DB = -30.0  # a wall seen this far below every antenna's peak contributes below the display


@cache
def median_edge_m(lod: str) -> float:
    """Median triangle edge length [m] of the avatar at `lod` (its rig height, 1.75 m scale)."""
    from rtchannel.body.avatar import load_avatar

    av = load_avatar(lod)
    v, f = av.vertices, av.faces
    edges = np.concatenate([np.linalg.norm(v[f[:, i]] - v[f[:, (i + 1) % 3]], axis=1) for i in range(3)])
    return float(np.median(edges))


def fresnel_facet_m(wavelength_m: float, curvature_m: float = LIMB_CURVATURE_M) -> float:
    """Largest facet size [m] that scatters like the smooth surface: sqrt(lambda rho / 2) (module doc)."""
    return float(np.sqrt(wavelength_m * curvature_m / 2.0))


def lod_for_wavelength(wavelength_m: float, curvature_m: float = LIMB_CURVATURE_M) -> str:
    """The coarsest avatar LOD whose median edge is at most `fresnel_facet_m` (the full mesh if none is)."""
    from rtchannel.body.avatar import LODS

    limit = fresnel_facet_m(wavelength_m, curvature_m)
    by_size = sorted((lod for lod in LODS), key=median_edge_m, reverse=True)  # coarsest first
    for lod in by_size:
        if median_edge_m(lod) <= limit:
            return lod
    return by_size[-1]


def resolve_lod(lod: str, scene, wavelength_m: float) -> str:
    """The one resolution of a backend's ``lod`` option (facets and sionna): a level of detail as given, or for
    "auto" the body LOD of a given `RTScene`, else `lod_for_wavelength` of the carrier.

    Args:
        lod: "full", "10k", "5k", "2k" or "auto".
        scene: what the backend traces (an `RTScene` carries its own body; names and paths do not).
        wavelength_m: the carrier's wavelength [m].
    """
    if lod != "auto":
        return lod
    from rtchannel.scene.rt_scene import RTScene

    if isinstance(scene, RTScene):
        from rtchannel.body.avatar import LODS, load_avatar

        n = len(scene.body_faces)
        return next(name for name in LODS if load_avatar(name).n_faces == n)
    return lod_for_wavelength(wavelength_m)


def _wall_grid(wall, n: int = 24) -> np.ndarray:
    """Points [M, 3] covering the wall polygon: an n x n grid in its plane kept inside, plus its corners."""
    from rtchannel.backends.wall_images import in_convex_polygon

    poly = np.asarray(wall.polygon, float)
    normal = np.asarray(wall.normal, float)
    e1 = poly[1] - poly[0]
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    uv = (poly - poly.mean(axis=0)) @ np.stack([e1, e2]).T
    u = np.linspace(uv[:, 0].min(), uv[:, 0].max(), n)
    w = np.linspace(uv[:, 1].min(), uv[:, 1].max(), n)
    uu, ww = np.meshgrid(u, w)
    pts = poly.mean(axis=0) + uu.reshape(-1, 1) * e1 + ww.reshape(-1, 1) * e2
    return np.concatenate([pts[in_convex_polygon(pts, wall, tol=1e-6)], poly])


def wall_pattern_db(wall, position, antenna) -> float:
    """Best power gain [dB] of `antenna` at `position` toward any point of the wall, relative to its peak
    (0 for an isotropic antenna or None)."""
    from processing.radar import antenna as ant

    if antenna is None or getattr(antenna, "kind", "isotropic") == "isotropic":
        return 0.0
    amp = ant.gain(antenna, np.asarray(position, float), _wall_grid(wall))
    peak = 10.0 ** (ant.peak_gain_dbi(antenna) / 20.0)
    return float(20.0 * np.log10(max(float(amp.max()), 1e-30) / peak))


def walls_in_view(walls, links, max_range_m: float, range_resolution_m: float,
                  wall_cut_db: float | None = DEFAULT_WALL_CUT_DB) -> tuple[list, dict[str, str]]:
    """The walls whose image paths can reach the signature, and why each other wall was culled.

    Args:
        walls: the scene's planar walls (`rtchannel.scene.rt_scene.Wall`).
        links: `rtchannel.backends.facets.LinkSpec`s (positions [m] and antenna patterns).
        max_range_m: largest range the DSP uses [m] (bistatic: half the path).
        range_resolution_m: the range bin [m].
        wall_cut_db: cull a wall that every antenna sees this many dB or more below its peak (None: never).

    Returns:
        (kept walls in scene order, {culled wall name: reason}).
    """
    from rtchannel.backends.wall_images import mirror, signed_distance

    limit = max_range_m + RANGE_MARGIN_BINS * range_resolution_m
    kept, culled = [], {}
    for wall in walls:
        reach, seen = False, False
        for lk in links:
            tx, rx = np.asarray(lk.tx, float), np.asarray(lk.rx, float)
            if signed_distance(tx, wall) <= 0 or signed_distance(rx, wall) <= 0:
                continue  # an antenna behind the wall: no image path through it on this link
            shortest = 0.5 * min(np.linalg.norm(mirror(tx, wall) - rx), np.linalg.norm(mirror(rx, wall) - tx))
            if shortest <= limit:
                reach = True
                best = max(wall_pattern_db(wall, tx, lk.tx_antenna), wall_pattern_db(wall, rx, lk.rx_antenna))
                seen = seen or wall_cut_db is None or best > wall_cut_db
        name = getattr(wall, "name", "?")
        if not reach:
            culled[name] = f"image paths beyond the range window ({limit:.2f} m)"
        elif not seen:
            culled[name] = f"every antenna sees it below {wall_cut_db:g} dB of its peak"
        else:
            kept.append(wall)
    return kept, culled


def fastest_speed(velocities: np.ndarray, quantile: float = 0.99) -> np.ndarray:
    """Per frame, the `quantile` of the vertex speeds [K] (m/s) of velocities [K, V, 3] (m/s)."""
    speed = np.linalg.norm(np.asarray(velocities, float), axis=-1)
    return np.quantile(speed, quantile, axis=1)


def aspect_rate_deg_s(times: np.ndarray, vertices: np.ndarray, faces: np.ndarray, sources: np.ndarray,
                      quantile: float = ASPECT_QUANTILE) -> np.ndarray:
    """Per frame, the `quantile` over facets of how fast [deg/s] the angle between a facet's normal and its
    line of sight to an antenna turns (the largest over `sources` [S, 3] m), for a mesh vertices [K, V, 3] (m)
    with triangles `faces` at `times` [K] (s). Facets facing away from an antenna in both frames of a step
    do not count (they carry no path from it)."""
    from rtchannel.body.skinning import face_frames

    times = np.asarray(times, float)
    k = len(times)
    if k < 2:
        return np.zeros(k)
    normals, _, degenerate, cent = face_frames(np.asarray(vertices, float), np.asarray(faces, np.int64))
    dt = np.diff(times)
    step_rate = np.zeros(k - 1)
    for p in np.asarray(sources, float).reshape(-1, 3):
        los = p - cent
        cos = np.einsum("kfi,kfi->kf", normals, los) / np.maximum(np.linalg.norm(los, axis=-1), 1e-12)
        angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
        facing = (cos[1:] > 0) | (cos[:-1] > 0)
        facing &= ~(degenerate[1:] | degenerate[:-1])
        turn = np.where(facing, np.abs(np.diff(angle, axis=0)), np.nan)
        q = np.nan_to_num(np.nanquantile(np.where(facing.any(axis=1)[:, None], turn, 0.0), quantile, axis=1))
        step_rate = np.maximum(step_rate, q / dt)
    # per frame: the mean of its two neighbouring steps' rates (the ends take their one step)
    return np.concatenate([[step_rate[0]], 0.5 * (step_rate[1:] + step_rate[:-1]), [step_rate[-1]]])


def adaptive_frames(times: np.ndarray, velocities: np.ndarray, probe: tuple, sources: np.ndarray,
                    step_m: float | None, step_deg: float | None, max_gap_s: float = 1.0) -> np.ndarray:
    """Traced frames of the facets backend's adaptive rules: `step_m` (fastest vertex of velocities [K, V, 3]
    m/s) or `step_deg` (`aspect_rate_deg_s` of probe = (vertices [K, V', 3] m, faces) seen from sources [S, 3]
    m); exactly one of the two."""
    if (step_m is None) == (step_deg is None):
        raise InputError("trace_step_m and trace_step_deg are two rules for the same trace rate: give one")
    if not max_gap_s > 0:
        raise InputError(f"trace_max_gap_s must be positive, got {max_gap_s}")
    if step_m is not None:
        return adaptive_trace_indices(times, fastest_speed(velocities), step_m, max_gap_s)
    assert step_deg is not None  # exactly one of the two (checked above)
    rate = aspect_rate_deg_s(times, probe[0], probe[1], sources)
    return adaptive_trace_indices(times, rate, step_deg, max_gap_s, name="trace_step_deg")


def adaptive_trace_indices(times: np.ndarray, speed: np.ndarray, step_m: float,
                           max_gap_s: float = 1.0, name: str = "trace_step_m") -> np.ndarray:
    """Frames to trace: the first, the last, and each frame where the fastest vertex has moved `step_m`
    metres since the last traced one (its speed [K] m/s integrated over `times` [K] s), with at most
    `max_gap_s` between traced frames so that a body at rest still has its gains refreshed (visibility of
    a still body changes when nothing moves, but the idle sway of a standing person does not stop). Any
    other rate works the same way (an aspect rate [deg/s] with a step in degrees; `name` is the option
    named in the error)."""
    if not step_m > 0:
        raise InputError(f"{name} must be positive, got {step_m}")
    times = np.asarray(times, float)
    k = len(times)
    if k <= 2:
        return np.arange(k)
    dt = np.diff(times)
    travelled = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * dt)])
    idx, last_s, last_t = [0], 0.0, times[0]
    for i in range(1, k - 1):
        if travelled[i] - last_s >= step_m or times[i] - last_t >= max_gap_s:
            idx.append(i)
            last_s, last_t = travelled[i], times[i]
    idx.append(k - 1)
    return np.asarray(idx, dtype=int)
