"""The body's radio material: dry skin's dielectric properties at the carrier (Gabriel et al. 1996) and the
scattering settings of Sionna RT's radio material, as the ray-tracing scene and the facets backend use them.

Gabriel et al.'s 4-Cole-Cole model of dry skin (S. Gabriel, R. W. Lau, C. Gabriel, "The dielectric
properties of biological tissues: III. Parametric models for the dielectric spectrum of tissues", Phys.
Med. Biol. 41 (1996) 2271-2293, Table 1 "Skin (Dry)"; the same model the IFAC/Andreuccetti online database
evaluates), evaluated at the carrier: 24.125 GHz gives eps_r' = 18.9 and sigma = 22.9 S/m.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from processing.constants import C0, DEFAULT_CARRIER_HZ, EPSILON_0_F_M as epsilon_0
from processing.errors import InputError

_SKIN_MATERIAL_ID = "rtchannel-skin"


# Gabriel et al. 1996, Table 1, "Skin (Dry)": eps_inf, sigma_ionic [S/m], then (delta_eps, tau [s], alpha).
_GABRIEL_DRY_SKIN = (4.0, 0.0002, ((32.0, 7.234e-12, 0.0), (1100.0, 32.481e-9, 0.20),
                                    (0.0, 159.155e-6, 0.20), (0.0, 15.915e-3, 0.20)))


def gabriel_dry_skin(frequency_hz: float) -> tuple[float, float]:
    """(relative permittivity eps_r', conductivity sigma [S/m]) of dry skin at `frequency_hz` (Gabriel 1996).

    The complex permittivity is eps_r' - j sigma / (omega eps0), the convention Sionna RT uses.
    """
    w = 2 * np.pi * frequency_hz
    eps_inf, sig, poles = _GABRIEL_DRY_SKIN
    eps = complex(eps_inf) + sig / (1j * w * epsilon_0)
    for de, tau, alpha in poles:
        eps += de / (1 + (1j * w * tau) ** (1 - alpha))
    return float(eps.real), float(-eps.imag * w * epsilon_0)


_SKIN_24G = gabriel_dry_skin(DEFAULT_CARRIER_HZ)


# Skin roughness: the scattering coefficient S depends on the roughness in wavelengths. Kirchhoff's
# (Rayleigh) roughness factor gives the specular power fraction exp(-g), g = (4 pi sigma_h cos(theta) /
# lambda)^2, of a surface with rms height sigma_h (Beckmann & Spizzichino 1963; Ulaby, Moore & Fung vol. 2),
# so S^2 = 1 - exp(-g) of the reflected power goes to the diffuse lobe. Sionna's S is one number per
# material: it is taken at normal incidence. The one parameter sigma_h is chosen so that S = 0.5 at
# 24.125 GHz, the value the project has used at the seed's carrier (0.53 mm: within the 0.1-1 mm range of
# skin-surface profilometry, wrinkles and clothing folds excluded); it gives S = 0.13 at 5.8 GHz.
SKIN_REFERENCE_S = (DEFAULT_CARRIER_HZ, 0.5)


def roughness_rms_m() -> float:
    """The rms surface height sigma_h [m] that gives S = 0.5 at 24.125 GHz under the Kirchhoff model."""
    f, s_ref = SKIN_REFERENCE_S
    return math.sqrt(-math.log(1.0 - s_ref ** 2)) * (C0 / f) / (4 * math.pi)


def scattering_coefficient(frequency_hz: float, rms_height_m: float | None = None) -> float:
    """S = sqrt(1 - exp(-(4 pi sigma_h / lambda)^2)) of skin of rms height `rms_height_m` [m] (default
    `roughness_rms_m`) at `frequency_hz` [Hz], normal incidence (see the comment above)."""
    f_ref, s_ref = SKIN_REFERENCE_S
    if rms_height_m is None and frequency_hz == f_ref:
        return s_ref  # the reference point itself, exactly (the round trip through sigma_h is off by 1 ulp)
    sigma_h = roughness_rms_m() if rms_height_m is None else rms_height_m
    g = (4 * math.pi * sigma_h * frequency_hz / C0) ** 2
    return math.sqrt(-math.expm1(-g))


@dataclass(frozen=True)
class SkinMaterial:
    """Radio material of the body (Sionna RT ``RadioMaterial``).

    Attributes:
        relative_permittivity: real relative permittivity eps_r' at the carrier.
        conductivity: conductivity sigma [S/m] at the carrier (dielectric loss included).
        scattering_coefficient: S in [0, 1]; fraction of the reflected field amplitude scattered
            diffusely (Sionna: specular amplitude scaled by sqrt(1 - S^2)).
        scattering_pattern: "lambertian", "backscattering" or "directive" (Degli-Esposti 2007).
        alpha_r, alpha_i, lambda_: lobe parameters of the backscattering/directive patterns.
        xpd_coefficient: cross-polarisation discrimination of the diffuse part, in [0, 1].
        thickness: slab thickness [m]; skin absorbs within ~1 mm at 24 GHz, so any thickness of a few
            cm makes Sionna's slab reflection equal the half-space one.
        source: where the dielectric values come from.
    """

    relative_permittivity: float = _SKIN_24G[0]
    conductivity: float = _SKIN_24G[1]
    scattering_coefficient: float = 0.5
    scattering_pattern: str = "lambertian"
    alpha_r: int = 4
    alpha_i: int = 4
    lambda_: float = 0.75
    xpd_coefficient: float = 0.0
    thickness: float = 0.05
    source: str = "Gabriel et al., Phys. Med. Biol. 41:2271 (1996), dry skin, 4-Cole-Cole at 24.125 GHz"

    @classmethod
    def at(cls, frequency_hz: float, **overrides) -> "SkinMaterial":
        """Dry skin (Gabriel 1996) at `frequency_hz` [Hz] with the roughness's scattering coefficient
        (`scattering_coefficient`: 0.5 at 24.125 GHz, 0.13 at 5.8 GHz); any field can be overridden."""
        eps, sig = gabriel_dry_skin(frequency_hz)
        src = (f"Gabriel et al., Phys. Med. Biol. 41:2271 (1996), dry skin, 4-Cole-Cole at {frequency_hz / 1e9:g} GHz;"
               f" S from {roughness_rms_m() * 1e3:.2f} mm rms roughness (Kirchhoff)")
        return cls(**{"relative_permittivity": eps, "conductivity": sig, "source": src,
                      "scattering_coefficient": scattering_coefficient(frequency_hz), **overrides})

    def __post_init__(self):
        if self.scattering_pattern not in ("lambertian", "backscattering", "directive"):
            raise InputError(f"unknown scattering pattern {self.scattering_pattern!r}; "
                             "choose lambertian, backscattering or directive")
        if not 0.0 <= self.scattering_coefficient <= 1.0:
            raise InputError(f"scattering_coefficient must be in [0, 1], got {self.scattering_coefficient}")


def skin_xml(skin: SkinMaterial) -> str:
    vals = dict(relative_permittivity=skin.relative_permittivity, conductivity=skin.conductivity,
                scattering_coefficient=skin.scattering_coefficient, xpd_coefficient=skin.xpd_coefficient,
                thickness=skin.thickness)
    floats = "".join(f'<float name="{k}" value="{float(v)!r}"/>' for k, v in vals.items())
    return f'<bsdf type="radio-material" id="{_SKIN_MATERIAL_ID}">{floats}</bsdf>'
