"""The `sionna` backend: Sionna RT's path solver on the skinned body in a room, one solve per frame.

Per traced frame the body's vertices are written in place into the shared `RTScene` and Sionna RT 2.2's
shooting-and-bouncing candidate generator, image method and field calculator run for every link at
once (all transmitters are sources, all receivers targets: two monostatic radars cost one call).

Choices (measured numbers in scenes/README.md):

- Antennas: the radar's patterns (`RadarConfig.antennas`) as Sionna RT arrays with their polarisation ("V"/"H"),
  each transmitter/receiver oriented by its boresight (`rtchannel.backends.sionna_antennas`); Sionna's
  path coefficient a then satisfies |a|^2 = G_tx G_rx P_r / P_t, where P_r / P_t is the unit-gain
  value that includes the lambda / (4 pi) spreading of the Friis/radar equation. Isotropic antennas
  give exactly that unit-gain value, the common gain scale of all backends (points: a = lambda
  sqrt(sigma) / ((4 pi)^1.5 R_tx R_rx)).
- ``los=False`` always: a co-located transmitter/receiver pair would otherwise get a huge direct path,
  and in bistatic links the direct path is static anyway.
- Static paths (no interaction with the body: wall/floor reflections between the antennas) are
  dropped: the DSP removes every range bin's mean, so they would only cost synthesis time. A path
  touching the body at least once (body, wall->body, body->wall, ...) is kept.
- Delays are recomputed in float64 from the interaction vertices (Sionna's are float32), and delay
  rates come from per-vertex velocities of the skinned mesh at the interaction points, barycentric-
  interpolated in the hit triangle (Sionna's own Doppler uses one velocity per object). For a path
  tx = p_0 -> p_1 -> ... -> p_n -> p_{n+1} = rx with unit segment directions u_i = (p_i - p_{i-1}) /
  |p_i - p_{i-1}| and interaction points moving with the material velocity w_i (0 on static objects):
      c d(tau)/dt = sum_{i=1..n} w_i . (u_i - u_{i+1}).
  This holds for diffuse points (material points) and, by Fermat's principle, for specular points too
  (the reflection point slides along the surface without changing the length to first order, so
  only the surface's own motion, i.e. its normal component, counts). Monostatic single bounce:
  2 w . u / c, positive (delay growing) for a body moving away from the radar.
- Kernels: Sionna's own ``PathSolver.__call__`` compacts the path buffer to the number of paths found
  and builds ``Paths`` tensors of that size, which end up in kernels: a count that changes every frame
  recompiles ~12 kernels (~0.1-0.2 s) per frame. The stages are called here directly and invalid
  entries are dropped in numpy, which needs no recompilation at all (Dr.Jit kernel history, see
  tests/test_sionna_backend.py); candidates are additionally padded to a multiple of `pad_bucket`
  with invalid entries as a safety net (no measurable cost).
- Specular: Sionna RT 2.2 finds no monostatic specular path off the body mesh (even with the radar on
  a facet's normal), while specular events take ~3/4 of the diffuse samples; ``specular=False`` is
  the better choice for monostatic body signatures (default True as specified, for bistatic links
  and higher depths).
- The gain a of Sionna RT 2.2 carries no propagation phase (the CIR applies exp(-j 2 pi f tau)
  itself), so it is used as is: it holds the material's reflection/scattering phase.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from processing.pathset import PathSet
from processing.radar.waveform import C0
from rtchannel.backends.sionna_antennas import link_groups, place_antennas
from rtchannel.radar import RadarConfig
from rtchannel.scene.rt_scene import BODY_ID, RTScene, get_scene
from rtchannel.scene.skin import SkinMaterial
from rtchannel.motion.pose import Motion

NONE, SPECULAR, DIFFUSE, REFRACTION, DIFFRACTION = 0, 1, 2, 4, 8  # sionna.rt.constants.InteractionType


class _Tracer:
    """Sionna RT 2.2's solver stages with candidate padding (one per scene and determinism flag)."""

    def __init__(self, deterministic: bool):
        import sionna.rt as rt

        solver = rt.PathSolver(deterministic=deterministic)
        self.candidates = solver._candidate_generator  # noqa: SLF001 - stages of the public solver
        self.image_method = solver._image_method  # noqa: SLF001
        self.fields = solver._field_calculator  # noqa: SLF001

    def __call__(self, scene, samples_per_src: int, max_depth: int, specular: bool, diffuse: bool,
                 refraction: bool, diffraction: bool, seed: int, pad_bucket: int,
                 max_num_paths_per_src: int) -> dict[str, Any]:
        import drjit as dr
        import mitsuba as mi

        src_pos, src_ori, _, _ = scene.sources(True, True)
        tgt_pos, tgt_ori, _, _ = scene.targets(True, True)
        dr.make_opaque(src_pos, tgt_pos, src_ori, tgt_ori)
        buf = self.candidates(mi_scene=scene.mi_scene, src_positions=src_pos, tgt_positions=tgt_pos,
                              samples_per_src=samples_per_src, max_num_paths_per_src=max_num_paths_per_src,
                              max_depth=max_depth, los=False, specular_reflection=specular,
                              diffuse_reflection=diffuse, refraction=refraction, diffraction=diffraction,
                              edge_diffraction=False, seed=seed)
        buf.schedule()
        dr.eval()
        found = int(dr.max(buf.paths_counter)[0])
        if pad_bucket > 0:
            # Pad with the (invalid) tail of the buffer so kernel sizes repeat across frames.
            padded = max(pad_bucket, -(-found // pad_bucket) * pad_bucket)
            buf._paths_counter = mi.UInt(min(padded, buf.buffer_size))  # noqa: SLF001
        buf.shrink()
        buf.detach_geometry()
        buf = self.image_method(scene=scene.mi_scene, paths=buf, src_positions=src_pos, tgt_positions=tgt_pos,
                                diffraction=diffraction, diffraction_lit_region=True)
        buf = self.fields(wavelength=scene.wavelength, paths=buf, samples_per_src=samples_per_src,
                          diffraction=diffraction, src_positions=src_pos, tgt_positions=tgt_pos,
                          src_orientations=src_ori, tgt_orientations=tgt_ori,
                          src_antenna_patterns=scene.tx_array.antenna_pattern.patterns,
                          tgt_antenna_patterns=scene.rx_array.antenna_pattern.patterns)
        buf.schedule()
        dr.eval()
        a = buf.a[0][0]
        out: dict[str, Any]  # arrays, and the path count found
        out = {"valid": np.array(buf.valid, dtype=bool), "src": np.array(buf.source_indices, dtype=np.int64),
               "tgt": np.array(buf.target_indices, dtype=np.int64),
               "a": np.array(dr.real(a), np.float64) + 1j * np.array(dr.imag(a), np.float64),
               "tau": np.array(buf.tau, np.float64), "found": found}
        n = len(out["valid"])
        for key, arr in (("types", buf.interaction_types), ("shapes", buf.shapes), ("prims", buf.primitives)):
            out[key] = np.array(arr, dtype=np.int64).reshape(n, -1)
        out["vertices"] = np.stack([np.array(c, np.float64).reshape(n, -1) for c in
                                    (buf.vertices_x, buf.vertices_y, buf.vertices_z)], axis=-1)
        return out


_TRACERS: dict[tuple[int, bool], _Tracer] = {}


def _tracer(scene: RTScene, deterministic: bool) -> _Tracer:
    key = (id(scene), deterministic)
    if key not in _TRACERS:
        _TRACERS[key] = _Tracer(deterministic)
    return _TRACERS[key]


def _velocity_at(points, prims, types, verts, vels, faces) -> np.ndarray:
    """Material velocity [M, 3] of body interaction points: barycentric blend in the hit triangle
    (diffraction points, whose primitive is an edge, take the nearest vertex's velocity)."""
    out = np.zeros_like(points)
    tri = (types != DIFFRACTION) & (prims >= 0) & (prims < len(faces))
    if tri.any():
        f = faces[prims[tri]]
        a, b, c = verts[f[:, 0]], verts[f[:, 1]], verts[f[:, 2]]
        n = np.cross(b - a, c - a)
        nn = np.einsum("ij,ij->i", n, n)
        p = points[tri]
        with np.errstate(invalid="ignore", divide="ignore"):
            wb = np.einsum("ij,ij->i", np.cross(p - a, c - a), n) / nn
            wc = np.einsum("ij,ij->i", np.cross(b - a, p - a), n) / nn
        bary = np.nan_to_num(np.column_stack([1 - wb - wc, wb, wc]), nan=1 / 3)  # degenerate: centroid
        out[tri] = np.einsum("ij,ijk->ik", bary, vels[f])
    rest = ~tri
    if rest.any():
        d = np.linalg.norm(verts[None, :, :] - points[rest][:, None, :], axis=-1)
        out[rest] = vels[np.argmin(d, axis=1)]
    return out


def path_geometry(tx, rx, vertices, types, body_hit, body_vel) -> tuple[np.ndarray, np.ndarray]:
    """Float64 delays [P] (s) and delay rates [P] (s/s) of paths tx -> vertices -> rx.

    Args:
        tx, rx: antenna positions [3] (m).
        vertices: interaction points [P, D, 3] (m); depths with type NONE are unused.
        types: interaction types [P, D] (0 = none; interactions are contiguous from depth 0).
        body_hit: [P, D] bool, the interaction is on the body.
        body_vel: [P, D, 3] material velocity (m/s) at body interactions (ignored elsewhere).
    """
    p, d = types.shape
    active = types != NONE
    pts = np.empty((p, d + 2, 3))
    pts[:, 0] = tx
    pts[:, 1:-1] = np.where(active[..., None], vertices, rx)  # unused depths collapse onto rx
    pts[:, -1] = rx
    seg = np.diff(pts, axis=1)  # [P, D+1, 3]
    length = np.linalg.norm(seg, axis=-1)
    u = seg / np.where(length > 0, length, 1.0)[..., None]
    w = np.where((active & body_hit)[..., None], body_vel, 0.0)
    rate = np.einsum("pdk,pdk->p", w, u[:, :-1] - u[:, 1:]) / C0
    return length.sum(axis=1) / C0, rate


def sionna_paths(motion: Motion, radar: RadarConfig, scene: str = "room", lod: str = "10k",
                 trace_fps: float | None = None, samples_per_src: int = 1_000_000, max_depth: int = 1,
                 specular: bool = True, diffuse: bool = True, refraction: bool = False,
                 diffraction: bool = False, skin: SkinMaterial | None = None, seed: int = 0,
                 deterministic: bool = False, pad_bucket: int = 512, joint_links: bool = True,
                 max_num_paths_per_src: int = 1_000_000, progress=None, stats: dict | None = None
                 ) -> dict[str, PathSet]:
    """Frame-local path sets (one per link) from Sionna RT on the skinned body in `scene`.

    Args:
        motion: pose sequence; the avatar (`lod`) is scaled to its rig height.
        radar: links; every antenna must be >= 1 cm from all geometry in every frame
            (`rtchannel.scene.rt_scene.RadarPlacementError` otherwise).
        scene: "room", "free_space" or a Mitsuba XML path (see `rtchannel.scene.rt_scene`).
        lod: avatar level of detail ("full", "10k", "5k", "2k"), or "auto" (`scene_model.resolve_lod`).
        trace_fps: trace at this frame rate (motion resampled); default every motion frame.
        samples_per_src: rays shot per transmitter per frame.
        max_depth: maximum number of interactions per path.
        specular, diffuse, refraction, diffraction: Sionna RT interaction types to enable.
        skin: body radio material (default dry skin at the carrier, Gabriel 1996).
        seed: ray-sampling seed, the same every frame (the sampling pattern moves coherently).
        deterministic: Sionna's deterministic candidate generator (reproducible bit for bit).
        pad_bucket: candidate counts are padded to a multiple of this (0 disables padding).
        joint_links: trace all links in one solver call per antenna-shape group (one call for the seed kit;
            False: one call per link, for benchmarks).
        max_num_paths_per_src: Sionna's candidate buffer size per source.
        progress: optional callable receiving 1 after each traced frame.
        stats: optional dict filled with per-call candidate counts ("found").

    Returns:
        {link name: PathSet} with ids None, delays [s], gains (|a|^2 = P_r/P_t with the links' antenna
        patterns, `RadarConfig.antennas`), and
        delay_rates from per-vertex body velocities. Frames without body paths have gain 0 everywhere.
    """
    from rtchannel.backends.scene_model import resolve_lod
    from rtchannel.body.avatar import load_avatar
    from rtchannel.body.skinning import skin_vertices, skin_velocities

    if trace_fps is not None:
        motion = motion.resampled(trace_fps)
    lod = resolve_lod(lod, scene, radar.waveform.wavelength)
    rt_scene = get_scene(scene, lod, motion.rig.height, radar.waveform.carrier_hz, skin)
    av = load_avatar(lod, motion.rig.height)
    return trace_frames(rt_scene, radar, motion.times, skin_vertices(av, motion), skin_velocities(av, motion),
                        samples_per_src=samples_per_src, max_depth=max_depth, specular=specular,
                        diffuse=diffuse, refraction=refraction, diffraction=diffraction, seed=seed,
                        deterministic=deterministic, pad_bucket=pad_bucket, joint_links=joint_links,
                        max_num_paths_per_src=max_num_paths_per_src, progress=progress, stats=stats)


def trace_frames(rt_scene: RTScene, radar: RadarConfig, times: np.ndarray, vertices: np.ndarray,
                 velocities: np.ndarray, samples_per_src: int = 1_000_000, max_depth: int = 1,
                 specular: bool = True, diffuse: bool = True, refraction: bool = False,
                 diffraction: bool = False, seed: int = 0, deterministic: bool = False, pad_bucket: int = 512,
                 joint_links: bool = True, max_num_paths_per_src: int = 1_000_000, progress=None,
                 stats: dict | None = None) -> dict[str, PathSet]:
    """`sionna_paths` for any body mesh: `vertices`/`velocities` [F, V, 3] (m, m/s) of
    ``rt_scene``'s body at `times` [F] (s); other arguments as in `sionna_paths`."""
    if abs(float(rt_scene.sionna_scene.frequency[0]) - radar.waveform.carrier_hz) > 1.0:
        rt_scene.sionna_scene.frequency = radar.waveform.carrier_hz  # a user scene for another carrier
    faces = rt_scene.body_faces
    body_id = rt_scene.body_object_id
    links = list(radar.links)
    # One call per antenna-shape group (Sionna RT has one tx and one rx array per scene), else per link.
    groups = link_groups(radar, links) if joint_links else [[lk] for lk in links]
    tracer = _tracer(rt_scene, deterministic)
    per_link: dict[str, list] = {lk.name: [] for lk in links}
    stats = {} if stats is None else stats
    stats.setdefault("found", [])
    placed = place_antennas(rt_scene, groups[0], radar) if len(groups) == 1 else None
    for k in range(len(times)):
        rt_scene.set_body(vertices[k])
        for group in groups:
            index, antennas = placed if placed is not None else place_antennas(rt_scene, group, radar)
            rt_scene.check_clearance(antennas)
            res = tracer(rt_scene.sionna_scene, samples_per_src, max_depth, specular, diffuse, refraction,
                         diffraction, seed, pad_bucket, max_num_paths_per_src)
            stats["found"].append(res["found"])
            on_body = (res["shapes"] == body_id) & (res["types"] != NONE)
            keep_all = res["valid"] & on_body.any(axis=1) & (np.abs(res["a"]) > 0)
            for lk in group:
                src, tgt = index[lk.name]
                sel = np.flatnonzero(keep_all & (res["src"] == src) & (res["tgt"] == tgt))
                verts_sel = res["vertices"][sel]
                hit = on_body[sel]
                vel = np.zeros_like(verts_sel)
                if hit.any():
                    vel[hit] = _velocity_at(verts_sel[hit], res["prims"][sel][hit], res["types"][sel][hit],
                                            vertices[k], velocities[k], faces)
                tau, rate = path_geometry(lk.tx_pos, lk.rx_pos, verts_sel, res["types"][sel], hit, vel)
                # the synthesiser multiplies by exp(+j 2 pi f tau) (beat = tx x conj(rx)): conj of Sionna's a
                per_link[lk.name].append((tau, np.conj(res["a"][sel]), rate))
        if progress is not None:
            progress(1)
    out = {}
    for name, frames in per_link.items():
        width = max(1, max(len(f[0]) for f in frames))
        kk = len(frames)
        delays, gains, rates = np.full((kk, width), np.nan), np.zeros((kk, width), complex), np.zeros((kk, width))
        for i, (tau, a, rate) in enumerate(frames):
            delays[i, :len(tau)], gains[i, :len(tau)], rates[i, :len(tau)] = tau, a, rate
        out[name] = PathSet(times=times, delays=delays, gains=gains, ids=None, delay_rates=rates, link=name)
    return out


__all__ = ["sionna_paths", "trace_frames", "path_geometry", "place_antennas", "BODY_ID"]
