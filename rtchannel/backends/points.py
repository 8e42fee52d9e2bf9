"""The `points` backend: the seed's 21 point scatterers with time-invariant gains (free space).

Delay of scatterer l on link (tx, rx): tau_l(t) = (|C_l(t) - tx| + |C_l(t) - rx|) / c0, i.e. the
bistatic radial distance is half the total path (seed Sect. IV-A); monostatic links reduce to 2 d / c0.

Gain scales (`scale`):
- "radar" (default): the common scale of all backends, the path coefficient of the radar equation,
  |a_l|^2 = P_r / P_t = G_tx G_rx lambda^2 sigma_l / ((4 pi)^3 R_tx^2 R_rx^2), with sigma_l = g_l^2
  sigma_body (the seed's area-fraction gains g_l, sum of squares 1, share the body RCS) and the antenna
  gains G toward the scatterer (`RadarConfig.link_gain`; 1 for isotropic antennas).
- "seed": a_l = g_l, time-invariant and dimensionless, exactly the seed's model (no range loss, no
  antenna patterns).
"""
from __future__ import annotations

import numpy as np

from processing.pathset import PathSet
from processing.radar.propagation import bistatic_delay, path_amplitude
from rtchannel.radar import RadarConfig
from rtchannel.body.scatterers import PointScatterers, seed_scatterers
from rtchannel.motion.pose import Motion
from rtchannel.errors import MOVE_THE_PERSON, RadarPlacementError
from processing.errors import InputError


def link_delays(points: np.ndarray, tx: np.ndarray, rx: np.ndarray) -> np.ndarray:
    """Delays [F, M] in seconds of point trajectories [F, M, 3] (m) for one tx/rx pair (m)."""
    return bistatic_delay(points, tx, rx)


def scatterer_trajectories(motion: Motion, scatterers: PointScatterers | None = None) -> np.ndarray:
    """Trajectories [F, M, 3] in metres of the scatterers (default: the seed's 21) moving with `motion`."""
    sc = seed_scatterers(motion.rig) if scatterers is None else scatterers
    return motion.attached_points(sc.joints, sc.rest_points)


# Whole-body monostatic RCS [m^2] shared by the 21 points on the "radar" scale, calibrated to the `facets`
# default (not fitted to any recording): the mean coherent RCS of the 10k body (S = 0.5 Lambertian skin
# with the physical-optics term on, random diffuse phases seed 0, gains traced at 10 fps) over a 3 s
# procedural walk at 1 m/s seen by monostatic radars 3 m away at 8 azimuths, 1.1 m up, free space:
# -3.10 dBsm = 0.49 m^2 (`python -m rtchannel.backends.rcs`, see `rcs.walk_body_rcs`; 2k/5k LODs -3.64/-3.02
# dBsm, walk seeds 1/2 -3.16/-3.25 dBsm, power sum -4.27 dBsm). It lies within measured human RCS at K
# band, about -5..0 dBsm (e.g. Yamada et al., IEEE VTC 2005, 76 GHz: -8..-3 dBsm).
BODY_RCS_M2 = 0.49

# The 21 scatterers sit on the skeleton, inside the body: the skin lies up to ~0.12 m from them (half the
# chest's depth; limbs 0.04-0.07 m). An antenna nearer than this to any of them is inside or touching the
# body, where the point model (and its 1/r^2 amplitude) means nothing.
MIN_SCATTERER_CLEARANCE_M = 0.15


def _check_clearance(traj: np.ndarray, times: np.ndarray, link) -> None:
    """RadarPlacementError when an antenna of `link` comes within MIN_SCATTERER_CLEARANCE_M of a scatterer."""
    for which, pos in (("transmitter", link.tx_pos), ("receiver", link.rx_pos)):
        d = np.linalg.norm(traj - pos, axis=-1)
        k, m = np.unravel_index(int(np.argmin(d)), d.shape)
        if d[k, m] < MIN_SCATTERER_CLEARANCE_M:
            raise RadarPlacementError(
                f"link '{link.name}': the {which} at ({pos[0]:.3f}, {pos[1]:.3f}, {pos[2]:.3f}) m is "
                f"{d[k, m] * 100:.1f} cm from body scatterer {m} at t = {times[k]:.2f} s: inside or touching the "
                f"body (minimum {MIN_SCATTERER_CLEARANCE_M * 100:g} cm){MOVE_THE_PERSON}")


def point_paths(motion: Motion, radar: RadarConfig, gains: np.ndarray | None = None,
                trajectories: np.ndarray | None = None, scale: str = "radar",
                body_rcs_m2: float = BODY_RCS_M2) -> dict[str, PathSet]:
    """Persistent path sets (one per link) of the point scatterers.

    Args:
        motion: the pose sequence.
        radar: links whose tx/rx positions are used.
        gains: amplitude gain per scatterer [M] (time-invariant, the seed's a_l); default: area-scaled.
        trajectories: scatterer positions [F, M, 3] (m); default: the skeleton-attached seed scatterers
            (the avatar's skin markers can be passed here instead).
        scale: "radar" (gains^2 * body_rcs_m2 as RCS through the radar equation, range loss included)
            or "seed" (gains as they are); see the module docstring.
        body_rcs_m2: whole-body RCS [m^2] on the "radar" scale.

    Returns:
        {link name: PathSet} with path ids 0..M-1.
    """
    sc = seed_scatterers(motion.rig)
    traj = scatterer_trajectories(motion, sc) if trajectories is None else trajectories
    g = sc.gains if gains is None else np.asarray(gains, dtype=np.complex128)
    if g.shape != (traj.shape[1],):
        raise InputError(f"gains must have one value per scatterer ({traj.shape[1]}), got shape {g.shape}")
    if scale not in ("radar", "seed"):
        raise InputError(f"points gain scale must be 'radar' or 'seed', got {scale!r}")
    out = {}
    for link in radar.links:
        _check_clearance(traj, motion.times, link)
        r_tx = np.linalg.norm(traj - link.tx_pos, axis=-1)
        r_rx = np.linalg.norm(traj - link.rx_pos, axis=-1)
        tau = link_delays(traj, link.tx_pos, link.rx_pos)
        gain = np.broadcast_to(g, tau.shape).copy()
        if scale == "radar":
            gain = gain * path_amplitude(body_rcs_m2, r_tx, r_rx, radar.waveform.wavelength)
            gain = gain * radar.link_gain(link, traj)
        out[link.name] = PathSet(times=motion.times, delays=tau, gains=gain, ids=np.arange(traj.shape[1]),
                                 link=link.name)
    return out
