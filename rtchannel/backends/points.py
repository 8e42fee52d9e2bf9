"""The `points` backend: the seed's 21 point scatterers with time-invariant gains (free space).

Delay of scatterer l on link (tx, rx): tau_l(t) = (|C_l(t) - tx| + |C_l(t) - rx|) / c0, i.e. the
bistatic radial distance is half the total path (seed Sect. IV-A); monostatic links reduce to 2 d / c0.
"""
from __future__ import annotations

import numpy as np

from processing.pathset import PathSet
from processing.waveform import C0
from rtchannel.radar import RadarConfig
from rtchannel.scatterers import PointScatterers, seed_scatterers
from rtchannel.skeleton import Motion


def link_delays(points: np.ndarray, tx: np.ndarray, rx: np.ndarray) -> np.ndarray:
    """Delays [F, M] in seconds of point trajectories [F, M, 3] (m) for one tx/rx pair (m)."""
    return (np.linalg.norm(points - tx, axis=-1) + np.linalg.norm(points - rx, axis=-1)) / C0


def scatterer_trajectories(motion: Motion, scatterers: PointScatterers | None = None) -> np.ndarray:
    """Trajectories [F, M, 3] in metres of the scatterers (default: the seed's 21) moving with `motion`."""
    sc = seed_scatterers(motion.rig) if scatterers is None else scatterers
    return motion.attached_points(sc.joints, sc.rest_points)


def point_paths(motion: Motion, radar: RadarConfig, gains: np.ndarray | None = None,
                trajectories: np.ndarray | None = None) -> dict[str, PathSet]:
    """Persistent path sets (one per link) of the point scatterers.

    Args:
        motion: the pose sequence.
        radar: links whose tx/rx positions are used.
        gains: amplitude gain per scatterer [M] (time-invariant, the seed's a_l); default: area-scaled.
        trajectories: scatterer positions [F, M, 3] (m); default: the skeleton-attached seed scatterers
            (the avatar's skin markers can be passed here instead).

    Returns:
        {link name: PathSet} with path ids 0..M-1.
    """
    sc = seed_scatterers(motion.rig)
    traj = scatterer_trajectories(motion, sc) if trajectories is None else trajectories
    g = sc.gains if gains is None else np.asarray(gains, dtype=np.complex128)
    if g.shape != (traj.shape[1],):
        raise ValueError(f"gains must have one value per scatterer ({traj.shape[1]}), got shape {g.shape}")
    out = {}
    for link in radar.links:
        tau = link_delays(traj, link.tx_pos, link.rx_pos)
        out[link.name] = PathSet(times=motion.times, delays=tau, gains=np.broadcast_to(g, tau.shape).copy(),
                                 ids=np.arange(traj.shape[1]), link=link.name)
    return out
