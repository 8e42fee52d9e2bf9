"""The floor image of a foot against its direct path, for vertical and horizontal polarisation (issue 37).

A point-like scatterer (a foot) at height h_f seen by a monostatic radar at height h_r and range d over a concrete
floor (ITU-R P.2040): the image path is |Gamma| r / r' of the direct one (tests/test_surfaces.py pins the facets
backend to this), with Gamma = r_TE for horizontal and r_TM for vertical polarisation at the grazing angle, and the
floor's Kirchhoff factor for a 1 mm rms roughness. Usage: python scripts/floor_image_db.py
"""
import numpy as np

from rtchannel.backends.surface_scattering import fresnel
from rtchannel.scene.material import WALL_ROUGHNESS_M, kirchhoff_specular
from rtchannel.scene.mitsuba_scene import ITU_MATERIALS_PROPERTIES


def concrete(f_hz: float) -> complex:
    (a, b, c, d), = [v for (lo, hi), v in ITU_MATERIALS_PROPERTIES["concrete"].items() if lo <= f_hz / 1e9 <= hi]
    f = f_hz / 1e9
    return complex(a * f ** b, -c * f ** d / (2 * np.pi * f_hz * 8.8541878128e-12))


def main() -> None:
    for f_hz, h_r in ((24.125e9, 1.1), (5.8e9, 1.0)):
        lam = 299792458.0 / f_hz
        for h_f in (0.05, 0.10):
            print(f"{f_hz / 1e9:g} GHz, radar {h_r} m high, foot {h_f} m high: image / direct [dB]")
            for d in (1.0, 2.0, 3.0, 4.0, 5.0):
                r, r_img = np.hypot(d, h_r - h_f), np.hypot(d, h_r + h_f)
                sin_g = (h_r + h_f) / r_img
                r_te, r_tm = fresnel(sin_g, concrete(f_hz))
                rough = 20 * np.log10(kirchhoff_specular(2 * sin_g, WALL_ROUGHNESS_M, lam))
                print(f"  {d:.0f} m, grazing {np.degrees(np.arcsin(sin_g)):4.1f} deg: "
                      f"H {20 * np.log10(abs(r_te) * r / r_img):6.1f}  V {20 * np.log10(abs(r_tm) * r / r_img):6.1f}"
                      f"  (roughness {rough:5.2f} more)")


if __name__ == "__main__":
    main()
