"""The one home of the propagation formulas every backend shares: bistatic delay, the radar equation's path
coefficient and its read-back into an RCS, and the closed-form RCS of the calibration targets.

All backends hand the synthesiser path coefficients on one scale, |a|^2 = P_r / P_t with isotropic
unit-gain antennas, so a target of RCS sigma [m^2] at r_tx, r_rx [m] from transmitter and receiver has

    |a| = lambda sqrt(sigma) / ((4 pi)^1.5 r_tx r_rx)            (bistatic radar equation)

Compiled (numba) kernels inline the same expressions; tests pin them to these functions.
"""
from __future__ import annotations

import numpy as np

from processing.radar.waveform import C0

FOUR_PI_1_5 = (4 * np.pi) ** 1.5


def bistatic_delay(points, tx, rx) -> np.ndarray:
    """Delays [s], shape of `points` without its last axis, of points [..., 3] (m) for a transmitter and a
    receiver at `tx`, `rx` [3] (m): (|x - tx| + |x - rx|) / c."""
    points = np.asarray(points, dtype=float)
    return (np.linalg.norm(points - np.asarray(tx, float), axis=-1)
            + np.linalg.norm(points - np.asarray(rx, float), axis=-1)) / C0


def path_amplitude(sigma, r_tx, r_rx, wavelength: float):
    """Path coefficient |a| (|a|^2 = P_r/P_t, isotropic unit-gain antennas) of a target of RCS `sigma`
    [m^2] at distances `r_tx`, `r_rx` [m]: lambda sqrt(sigma) / ((4 pi)^1.5 r_tx r_rx). Broadcasts."""
    return wavelength * np.sqrt(sigma) / (FOUR_PI_1_5 * np.asarray(r_tx) * np.asarray(r_rx))


def rcs_from_amplitude(a, r_tx, r_rx, wavelength: float):
    """The RCS [m^2] that `path_amplitude` turns into the coefficient `a` (complex or real): the read-back
    used to measure a backend's RCS from its path sets."""
    return (np.abs(a) * FOUR_PI_1_5 * np.asarray(r_tx) * np.asarray(r_rx) / wavelength) ** 2


def received_power_ratio(sigma, r_tx, r_rx, wavelength: float, gain_tx: float = 1.0, gain_rx: float = 1.0):
    """P_r / P_t of the bistatic radar equation, G_tx G_rx lambda^2 sigma / ((4 pi)^3 r_tx^2 r_rx^2), with
    linear antenna gains `gain_tx`, `gain_rx` (= |a|^2 G_tx G_rx)."""
    return gain_tx * gain_rx * path_amplitude(sigma, r_tx, r_rx, wavelength) ** 2


# ---- closed-form RCS of the calibration targets (monostatic) -------------------------------------------
def plate_po_rcs(area: float, wavelength: float) -> float:
    """Broadside RCS [m^2] of a perfectly conducting flat plate of `area` [m^2] (physical optics):
    4 pi A^2 / lambda^2."""
    return 4 * np.pi * area ** 2 / wavelength ** 2


def optical_sphere_rcs(radius: float) -> float:
    """Optical-region RCS [m^2] of a perfectly conducting sphere of `radius` [m]: pi a^2."""
    return np.pi * radius ** 2


def lambertian_sphere_rcs(radius: float, scattering_coefficient: float = 1.0, gamma: float = 1.0) -> float:
    """RCS [m^2] of a sphere under the Lambertian diffuse model, summed in power: the integral of
    4 S^2 Gamma^2 cos^2(theta) dA over the lit hemisphere = (8 pi / 3) S^2 Gamma^2 a^2."""
    return 8 * np.pi / 3 * scattering_coefficient ** 2 * gamma ** 2 * radius ** 2


def lambertian_plate_rcs(area: float, scattering_coefficient: float = 1.0, gamma: float = 1.0,
                         cos_theta: float = 1.0) -> float:
    """RCS [m^2] of a flat plate of `area` [m^2] under the Lambertian diffuse model, summed in power, seen at
    incidence cosine `cos_theta`: 4 S^2 Gamma^2 cos^2(theta) A."""
    return 4 * scattering_coefficient ** 2 * gamma ** 2 * cos_theta ** 2 * area


__all__ = ["FOUR_PI_1_5", "bistatic_delay", "path_amplitude", "rcs_from_amplitude", "received_power_ratio",
           "plate_po_rcs", "optical_sphere_rcs", "lambertian_sphere_rcs", "lambertian_plate_rcs"]
