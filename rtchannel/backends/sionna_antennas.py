"""The radar's antenna patterns as Sionna RT 2.2 antenna arrays, and the transmitters/receivers that use them.

Sionna RT evaluates an antenna pattern inside its field calculator: a registered pattern factory returns
callables ``(theta, phi) -> (C_theta, C_phi)`` in the device's local frame (x' boresight, z' up), and each
Transmitter/Receiver turns that frame by its own (yaw, pitch, roll). `processing.radar.antenna` uses the same
local frame, so a project pattern becomes a Sionna pattern by evaluating `local_power_gain` with Dr.Jit
operations: the antenna's polarisation (`polarization`, Sionna's spelling: "V", slant angle 0, C_theta =
sqrt(G) and C_phi = 0 exactly; "H", slant angle pi/2, C_phi = sqrt(G) and C_theta = 0) on the array
(`PlanarArray(polarization=...)`, which hands it to the pattern factory). Then |a|^2 carries G_tx(u_tx) G_rx(u_rx)
on top of the unit-gain scale, with u_tx the direction in which each path leaves the transmitter and u_rx the one
from which it reaches the receiver (Sionna's first and last path segments: exact for every depth and for wall-bounce
paths).

Limits of Sionna RT 2.2: the scene holds ONE transmit and ONE receive array for all devices (orientations
are per device). Links whose antennas differ in shape or polarisation (not only in orientation) are therefore
traced in separate solver calls, one per distinct (tx shape, rx shape, polarisation); the seed's kit (one horn
everywhere) and the isotropic case need one call. Isotropic antennas keep Sionna's own "iso" pattern with
orientation (0, 0, 0): bit for bit the unit-gain behaviour of the backend.
"""
from __future__ import annotations

import hashlib
import json
from types import SimpleNamespace

import numpy as np

from processing.radar.antenna import link_polarization, local_power_gain, sionna_orientation
from processing.errors import InputError

_REGISTERED: set[str] = set()


def shape_key(spec) -> str:
    """Sionna pattern name of `spec`: "iso" for isotropic antennas, else a name derived from the pattern's
    shape (kind, beamwidths, gain, floor...; orientation excluded, it belongs to each device)."""
    if spec.kind == "isotropic":
        return "iso"
    # the polarisation is the array's (`place_antennas`), not the pattern's: one registered pattern serves both
    shape = json.dumps(spec.model_dump(exclude={"boresight", "look_at", "up", "downtilt_deg", "polarization"}),
                       sort_keys=True)
    return f"rtchannel_{spec.kind}_{hashlib.sha1(shape.encode()).hexdigest()[:12]}"


def _drjit_ops():
    import drjit as dr

    return SimpleNamespace(sin=dr.sin, cos=dr.cos, exp=dr.exp, sqrt=dr.sqrt, arctan2=dr.atan2, maximum=dr.maximum,
                           power=dr.power, where=dr.select)


def register_pattern(spec) -> str:
    """Register `spec`'s shape with Sionna RT (once per shape) and return the pattern name for
    ``PlanarArray(pattern=...)``; isotropic antennas use Sionna's own "iso"."""
    name = shape_key(spec)
    if name in _REGISTERED or name == "iso":
        return name
    import drjit as dr
    import mitsuba as mi
    from sionna.rt import register_antenna_pattern
    from sionna.rt.antenna_pattern import PolarizedAntennaPattern

    ops = _drjit_ops()

    def v_pattern(theta, phi):
        # sqrt(G): the amplitude pattern; the power gain is finite and > 0 everywhere (floor), no NaN.
        # (Mitsuba's stubs type the variant classes, Complex2f among them, as object: the variant is chosen at
        # run time.)
        return mi.Complex2f(dr.sqrt(local_power_gain(spec, theta, phi, ops)), 0.0)  # type: ignore[operator]

    def factory(*, polarization="V", polarization_model="tr38901_2"):
        return PolarizedAntennaPattern(v_pattern=v_pattern, polarization=polarization,
                                       polarization_model=polarization_model)

    register_antenna_pattern(name, factory)
    _REGISTERED.add(name)
    return name


def link_groups(radar, links) -> list[list]:
    """`links` grouped so that each group needs one transmit and one receive pattern shape and one
    polarisation (one Sionna solver call per group), in first-seen order."""
    groups: dict[tuple[str, str, str], list] = {}
    for link in links:
        tx, rx = radar.antennas(link) if radar is not None else (None, None)
        key = (shape_key(tx) if tx is not None else "iso", shape_key(rx) if rx is not None else "iso",
               link_polarization(tx, rx))
        groups.setdefault(key, []).append(link)
    return list(groups.values())


def _orientation(spec, position) -> tuple[float, float, float]:
    if spec is None or spec.kind == "isotropic":
        return (0.0, 0.0, 0.0)  # today's unit-gain devices: no rotation, bit-identical fields
    yaw, pitch, roll = (float(a) for a in sionna_orientation(spec, position))
    return (yaw, pitch, roll)


def place_antennas(scene, links, radar=None) -> tuple[dict[str, tuple[int, int]], np.ndarray]:
    """Put one transmitter per distinct (tx position, orientation) and one receiver per distinct (rx
    position, orientation) of `links` into ``scene`` (an `RTScene`), with the scene's arrays set to the links'
    antenna patterns and polarisation (`radar.antennas(link)`; isotropic "V" when `radar` is None).

    All `links` must share one tx and one rx pattern shape and one polarisation (`link_groups`).

    Returns ({link name: (source index, target index)}, all antenna positions [N, 3] (m)).
    """
    import mitsuba as mi
    import sionna.rt as rt

    specs = [radar.antennas(lk) if radar is not None else (None, None) for lk in links]
    names = {(shape_key(t) if t is not None else "iso", shape_key(r) if r is not None else "iso",
              link_polarization(t, r)) for t, r in specs}
    if len(names) != 1:
        raise InputError(f"place_antennas: links need one tx and one rx pattern shape and one polarization per call, "
                         f"got {sorted(names)}")
    s = scene.sionna_scene
    for name in list(s.transmitters) + list(s.receivers):
        s.remove(name)
    tx0, rx0 = specs[0]
    pol = link_polarization(tx0, rx0)
    s.tx_array = rt.PlanarArray(num_rows=1, num_cols=1, polarization=pol,
                                pattern=register_pattern(tx0) if tx0 is not None else "iso")
    s.rx_array = rt.PlanarArray(num_rows=1, num_cols=1, polarization=pol,
                                pattern=register_pattern(rx0) if rx0 is not None else "iso")
    txs: list[tuple] = []
    rxs: list[tuple] = []
    index = {}
    for link, (t_spec, r_spec) in zip(links, specs):
        t = (tuple(map(float, link.tx_pos)), _orientation(t_spec, link.tx_pos))
        r = (tuple(map(float, link.rx_pos)), _orientation(r_spec, link.rx_pos))
        if t not in txs:
            txs.append(t)
            s.add(rt.Transmitter(name=f"tx{len(txs) - 1}", position=mi.Point3f(*t[0]), orientation=mi.Point3f(*t[1])))
        if r not in rxs:
            rxs.append(r)
            s.add(rt.Receiver(name=f"rx{len(rxs) - 1}", position=mi.Point3f(*r[0]), orientation=mi.Point3f(*r[1])))
        index[link.name] = (txs.index(t), rxs.index(r))
    return index, np.array([p for p, _ in txs + rxs], dtype=float)


__all__ = ["place_antennas", "register_pattern", "link_groups", "shape_key"]
