"""Monostatic radar cross-section of a test mesh through a backend, for amplitude calibration.

All backends report the complex path gain a with unit-gain isotropic antennas, |a|^2 = P_r / P_t. The
monostatic radar equation P_r/P_t = lambda^2 sigma / ((4 pi)^3 R^4) turns it into an RCS:
sigma = (4 pi)^3 R^4 |a|^2 / lambda^2. Each path is converted with its own range (R = c tau / 2, exact for
single-bounce monostatic paths), and the paths' powers are summed incoherently: diffuse paths are Monte-
Carlo samples of a rough surface whose phases carry no meaning, so the expected (mean) RCS is the
power sum; the coherent sum is also returned.

Closed forms used by the tests (optical region, target size >> lambda):
- sphere, geometric optics (specular): pi a^2;
- flat plate of area A at broadside, physical optics: 4 pi A^2 / lambda^2;
- Lambertian surface with scattering coefficient S and reflection-coefficient magnitude |G| (Sionna RT's
  diffuse model, Degli-Esposti 2007): a patch dA seen at incidence angle theta backscatters
  sigma = 4 S^2 |G|^2 cos^2(theta) dA, so a sphere gives (8 pi / 3) S^2 |G|^2 a^2 and a broadside plate
  4 S^2 |G|^2 A;
- a specular mirror reflection in an image-method tracer (Sionna RT) is the image of the radar in an
  infinite plane: |a| = lambda / (4 pi 2R), i.e. sigma = pi R^2 whatever the plate's size.

Body RCS over a walk (`walk_body_rcs`, the calibration of the `points` backend's whole-body RCS against
the `facets` default): monostatic radars at a fixed distance around a short procedural walk in free space;
per frame, every path is scaled by its own range, sigma_p = (4 pi)^3 R_p^4 |a_p|^2 / lambda^2 with R_p =
c0 tau_p / 2, and the paths are summed coherently with the synthesiser's phase exp(+j 2 pi f tau) (the RCS
the radar sees in that frame) and in power (incoherent); both are averaged in power over the frames.
Run ``python -m rtchannel.backends.rcs`` for the table behind `rtchannel.backends.points.BODY_RCS_M2`.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from processing.constants import DEFAULT_CARRIER_HZ
from processing.radar.antenna import Isotropic
from processing.pathset import PathSet
from processing.radar.propagation import FOUR_PI_1_5
from processing.radar.waveform import C0
from rtchannel.radar import Link, RadarConfig
from rtchannel.scene.rt_scene import RTScene
from rtchannel.scene.skin import SkinMaterial
from processing.errors import InputError

# A backend function maps (vertices [V, 3], faces [T, 3], radar) to {link name: PathSet} of one frame.
BackendFn = Callable[[np.ndarray, np.ndarray, RadarConfig], dict[str, PathSet]]

PEC = SkinMaterial(relative_permittivity=1.0, conductivity=1e8, scattering_coefficient=0.0,
                   source="perfect conductor (sigma = 1e8 S/m)")


def sphere_mesh(radius: float, subdivisions: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Icosphere (trimesh) centred on the origin: vertices [V, 3] (m), outward faces [T, 3]."""
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)


def plate_mesh(width: float, height: float, n: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Flat plate in the y-z plane centred on the origin, normal +x, split into 2 n^2 triangles."""
    y, z = np.meshgrid(np.linspace(-width / 2, width / 2, n + 1), np.linspace(-height / 2, height / 2, n + 1))
    v = np.column_stack([np.zeros(y.size), y.ravel(), z.ravel()])
    idx = np.arange(y.size).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    return v, np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])


def monostatic_rcs(backend: BackendFn, vertices: np.ndarray, faces: np.ndarray, distance: float = 5.0,
                   centre=(0.0, 0.0, 1.5), azimuth_deg: float = 0.0, frequency_hz: float = DEFAULT_CARRIER_HZ) -> dict:
    """RCS [m^2] of a mesh (given about the origin, placed at `centre`) seen by a monostatic radar.

    The radar sits `distance` m from `centre` in the horizontal direction `azimuth_deg` (0 = +x, so a
    `plate_mesh` is seen at broadside). Returns {"sigma": incoherent power sum (m^2), "coherent": |sum|
    based RCS (m^2), "n_paths": paths used}.
    """
    az = np.deg2rad(azimuth_deg)
    c = np.asarray(centre, float)
    tx = c + distance * np.array([np.cos(az), np.sin(az), 0.0])
    radar = RadarConfig(links=[Link(name="rcs", tx=tuple(map(float, tx)))], antenna=Isotropic())  # RCS: unit gain
    radar = radar.model_copy(update={"waveform": radar.waveform.model_copy(update={"carrier_hz": frequency_hz})})
    ps = backend(np.asarray(vertices, float) + c, np.asarray(faces), radar)["rcs"]
    lam = C0 / frequency_hz
    present = ps.gains[0] != 0
    a, tau = ps.gains[0][present], ps.delays[0][present]
    r = C0 * tau / 2
    k = (4 * np.pi) ** 3 / lam ** 2
    coherent = np.sum(a * (r / distance) ** 2 * np.exp(2j * np.pi * frequency_hz * tau))  # synthesiser's convention
    return {"sigma": float(k * np.sum(np.abs(a) ** 2 * r ** 4)),
            "coherent": float(k * distance ** 4 * np.abs(coherent) ** 2), "n_paths": int(present.sum())}


def frame_rcs(ps: PathSet, frequency_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """(coherent, incoherent) RCS [m^2] per frame [K] of a monostatic, single-bounce path set (free space).

    Each path is scaled to its own range R = c0 tau / 2 before the sum (see the module doc); absent
    paths (gain 0) are skipped."""
    lam = C0 / frequency_hz
    on = ps.gains != 0
    tau = np.where(on, ps.delays, 0.0)
    root_sigma = ps.gains * (C0 * tau / 2) ** 2 * FOUR_PI_1_5 / lam  # sqrt(sigma_p) up to phase
    s = np.where(on, root_sigma * np.exp(2j * np.pi * frequency_hz * tau), 0)
    return np.abs(s.sum(axis=1)) ** 2, np.sum(np.abs(s) ** 2, axis=1)


WALK_AZIMUTHS_DEG = (0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0)


def walk_body_rcs(backend: str = "facets", duration: float = 3.0, distance: float = 3.0,
                  azimuths_deg=WALK_AZIMUTHS_DEG, antenna_height: float = 1.1, walk_seed: int = 0,
                  **options) -> dict:
    """Mean monostatic body RCS [m^2] of a procedural walk seen from several directions (free space).

    The body walks `duration` s at 1 m/s along +x, its hips passing the origin at mid-walk; one monostatic
    radar sits `distance` m from the origin at each azimuth (0 deg: ahead of the walker, 90 deg: on its
    left side), `antenna_height` m up. `backend` is "facets" (`facet_paths` in free space without walls,
    other `options` passed on) or "points" (`point_paths`, options passed on).

    Returns:
        {"coherent": mean over radars and frames of the per-frame coherent RCS, "incoherent": the same
        for the power sum, "per_azimuth": {azimuth: (coherent, incoherent)}}, all in m^2.
    """
    from rtchannel.motion.procedural import generate

    motion = generate("walk", duration=duration, speed=1.0, start=(-duration / 2, 0.0), pad_before=0.0,
                      pad_after=0.0, seed=walk_seed)
    az = np.deg2rad(np.asarray(azimuths_deg, float))
    links = [Link(name=f"az{a:g}", tx=(distance * np.cos(r), distance * np.sin(r), antenna_height))
             for a, r in zip(azimuths_deg, az)]
    radar = RadarConfig(links=links, antenna=Isotropic(), receiver=None)  # RCS: unit-gain antennas
    if backend == "facets":
        from rtchannel.backends.facets import facet_paths

        paths = facet_paths(motion, radar, scene="free_space", walls=False, **options)
    elif backend == "points":
        from rtchannel.backends.points import point_paths

        paths = point_paths(motion, radar, **options)
    else:
        raise InputError(f"walk_body_rcs supports the facets and points backends, got {backend!r}")
    per = {}
    for a, link in zip(azimuths_deg, links):
        coh, inc = frame_rcs(paths[link.name], radar.waveform.carrier_hz)
        per[a] = (float(coh.mean()), float(inc.mean()))
    return {"coherent": float(np.mean([v[0] for v in per.values()])),
            "incoherent": float(np.mean([v[1] for v in per.values()])), "per_azimuth": per}


def sionna_backend(material: SkinMaterial = PEC, **options) -> BackendFn:
    """A `BackendFn` tracing one static frame with the `sionna` backend in free space.

    `options` go to `rtchannel.backends.sionna_rt.trace_frames` (samples_per_src, specular, diffuse, ...).
    """
    from rtchannel.backends.sionna_rt import trace_frames

    def run(vertices, faces, radar):
        scene = RTScene("free_space", faces, vertices, radar.waveform.carrier_hz, material)
        v = vertices[None]
        return trace_frames(scene, radar, np.zeros(1), v, np.zeros_like(v), **options)

    return run


__all__ = ["monostatic_rcs", "sionna_backend", "sphere_mesh", "plate_mesh", "PEC", "BackendFn", "frame_rcs",
           "walk_body_rcs"]


def _db(x: float) -> str:
    return f"{10 * np.log10(x):6.2f}"


if __name__ == "__main__":  # the body-RCS table behind points.BODY_RCS_M2 (see the module doc)
    import argparse

    ap = argparse.ArgumentParser(description="mean monostatic body RCS over a procedural walk (dBsm)")
    ap.add_argument("--duration", type=float, default=3.0)
    ap.add_argument("--lods", nargs="+", default=["2k", "5k", "10k"])
    ap.add_argument("--po", choices=["on", "off", "both"], default="on")
    args = ap.parse_args()
    rows: list[tuple[str, dict]] = [("points", {})]
    for po in {"on": [True], "off": [False], "both": [True, False]}[args.po]:
        rows += [("facets", {"lod": lod, "po": po}) for lod in args.lods]
    print(f"walk {args.duration:g} s at 1 m/s, radars 3 m away at azimuths {WALK_AZIMUTHS_DEG} deg, 1.1 m up")
    print("backend options | coherent | incoherent | per azimuth coherent (dBsm)")
    for backend, opts in rows:
        r = walk_body_rcs(backend, args.duration, **opts)
        per = " ".join(_db(v[0]) for v in r["per_azimuth"].values())
        print(f"{backend} {opts} | {_db(r['coherent'])} | {_db(r['incoherent'])} | {per}", flush=True)
