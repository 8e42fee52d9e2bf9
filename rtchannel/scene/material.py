"""One radio-material model for the scene and every backend: a surface's complex permittivity at the carrier,
slab thickness, roughness (-> scattering coefficient S), diffuse pattern and cross-polar fraction.

The body (`rtchannel.scene.skin.SkinMaterial`, `SurfaceMaterial.from_skin`), the scene's walls and floor
(`rtchannel.scene.rt_scene.Wall.material`), the clutter's patches and the facets backend all evaluate a
`SurfaceMaterial`; the Sionna backend writes the same numbers into Sionna RT's ``RadioMaterial``.

Roughness (Kirchhoff / Beckmann-Spizzichino, Ament's specular factor). A surface of rms height sigma_h
(Gaussian heights) reflects coherently only the fraction

    rho_s = exp(-(k sigma_h q)^2 / 2),   q = n . (u_in + u_out)  (= 2 cos(theta_i) at specular incidence)

of the smooth surface's field (the mean of exp(j k h q) over the heights h), and the rest of the power,
S^2 = 1 - rho_s^2, is scattered diffusely: the diffuse and the specular fractions add up to the reflected
power exactly (S^2 + rho_s^2 = 1), which is Sionna RT's energy split (specular field scaled by
sqrt(1 - S^2), diffuse power S^2) with S evaluated at the local incidence instead of one number per
material. A wall (default rms height `WALL_ROUGHNESS_M`) therefore uses one roughness for the clutter's diffuse
return (S at the patch's incidence), for the clutter's specular (PO) return, and for the body's wall and floor
bounces (image paths scaled by rho_s at each reflection point). The body keeps Sionna's fixed S (the skin's
roughness is folded into `SkinMaterial.scattering_coefficient`): ``roughness_m=None``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from processing.constants import EPSILON_0_F_M as epsilon_0

# rms height of a plastered or concrete wall finish (honest range 0.3-3 mm: float-finished concrete to rough
# plaster): with the Kirchhoff model it gives walls S = 0.80 at 24 GHz and 0.24 at 5.8 GHz at normal incidence
WALL_ROUGHNESS_M = 1e-3


def kirchhoff_specular(q, rms_height_m: float, wavelength: float):
    """Coherent (specular) field factor rho_s = exp(-(2 pi sigma_h q / lambda)^2 / 2) [same shape as q] of a
    surface of rms height `rms_height_m` [m] at wavelength [m]; q = n . (u_in + u_out), 2 cos(theta_i) at
    specular incidence (so rho_s = exp(-(4 pi sigma_h cos(theta_i) / lambda)^2 / 2), Ament's factor)."""
    x = 2 * np.pi / wavelength * rms_height_m * np.asarray(q, float)
    return np.exp(-0.5 * x * x)


def kirchhoff_scattering(cos_i, rms_height_m: float, wavelength: float):
    """Scattering coefficient S = sqrt(1 - rho_s^2) at incidence cosine(s) cos_i of a surface of rms height
    `rms_height_m` [m]: the diffuse share of the reflected field (S^2 + rho_s^2 = 1)."""
    x = 4 * np.pi / wavelength * rms_height_m * np.clip(np.asarray(cos_i, float), 0.0, 1.0)
    return np.sqrt(-np.expm1(-x * x))


@dataclass(frozen=True)
class SurfaceMaterial:
    """Electromagnetic surface properties at one frequency.

    Attributes:
        eta: complex relative permittivity eps_r' - j sigma / (omega eps0); None = perfect conductor.
        scattering_coefficient: S in [0, 1] (diffuse fraction of the reflected field amplitude), used as is
            when `roughness_m` is None (Sionna's one number per material, e.g. the skin).
        pattern: "lambertian", "directive" or "backscattering".
        alpha_r, alpha_i, lambda_: lobe parameters of the directive/backscattering patterns.
        xpd_coefficient: K_x; the co-polar diffuse power is scaled by (1 - K_x).
        thickness: slab thickness [m] (ITU-R P.2040 single-layer slab); None = half-space.
        roughness_m: rms surface height [m]; when set, S and the specular factor follow the Kirchhoff model at
            each element's own angles (module doc; 0: smooth, S = 0) and `scattering_coefficient` is ignored.
    """

    eta: complex | None = None
    scattering_coefficient: float = 1.0
    pattern: str = "lambertian"
    alpha_r: int = 4
    alpha_i: int = 4
    lambda_: float = 0.75
    xpd_coefficient: float = 0.0
    thickness: float | None = None
    roughness_m: float | None = None

    @classmethod
    def from_skin(cls, skin, frequency_hz: float) -> "SurfaceMaterial":
        """From an `rtchannel.scene.rt_scene.SkinMaterial` (permittivity, conductivity [S/m], S, pattern)."""
        eta = complex(skin.relative_permittivity, -skin.conductivity / (2 * np.pi * frequency_hz * epsilon_0))
        return cls(eta=eta, scattering_coefficient=float(skin.scattering_coefficient),
                   pattern=skin.scattering_pattern, alpha_r=int(skin.alpha_r), alpha_i=int(skin.alpha_i),
                   lambda_=float(skin.lambda_), xpd_coefficient=float(skin.xpd_coefficient),
                   thickness=float(skin.thickness) if skin.thickness else None)

    @classmethod
    def from_slab(cls, relative_permittivity: float, conductivity: float, thickness: float | None,
                  frequency_hz: float, roughness_m: float = WALL_ROUGHNESS_M) -> "SurfaceMaterial":
        """A wall's material: eps_r', sigma [S/m] at `frequency_hz` [Hz], slab thickness [m] (None or 0:
        half-space), rms roughness [m] (Lambertian diffuse part, as the scene's ITU materials in Sionna)."""
        eta = complex(relative_permittivity, -conductivity / (2 * math.pi * frequency_hz * epsilon_0))
        return cls(eta=eta, thickness=thickness or None, roughness_m=float(roughness_m))

    def scattering_at(self, cos_i, wavelength: float):
        """S at incidence cosine(s) cos_i: the fixed `scattering_coefficient`, or Kirchhoff's with roughness."""
        if self.roughness_m is None:
            return np.full(np.shape(cos_i), float(self.scattering_coefficient))
        return kirchhoff_scattering(cos_i, self.roughness_m, wavelength)

    def specular_at(self, q, wavelength: float):
        """Specular field factor for q = n . (u_in + u_out): sqrt(1 - S^2) of the fixed S, or `kirchhoff_specular`."""
        if self.roughness_m is None:
            return np.full(np.shape(q), math.sqrt(1.0 - self.scattering_coefficient ** 2))
        return kirchhoff_specular(q, self.roughness_m, wavelength)

    def kernel_surface(self) -> tuple[float, float]:
        """(fixed S, rms height [m] or 0) as the compiled kernels take them (`facet_kernels`): a rough surface
        passes its height, a smooth one (roughness 0) S = 0, a fixed-S material its S and 0."""
        if self.roughness_m is None:
            return float(self.scattering_coefficient), 0.0
        return (0.0, 0.0) if self.roughness_m == 0 else (0.0, float(self.roughness_m))

    def normal_scattering_coefficient(self, wavelength: float) -> float:
        """S at normal incidence (the one number Sionna RT's RadioMaterial holds)."""
        return float(self.scattering_at(1.0, wavelength))


__all__ = ["SurfaceMaterial", "WALL_ROUGHNESS_M", "kirchhoff_specular", "kirchhoff_scattering"]
