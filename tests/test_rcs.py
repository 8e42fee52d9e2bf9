"""Radar cross-sections through the `sionna` backend against closed forms (amplitude calibration).

Measured (24.125 GHz, radar 3 m away; see rtchannel/backends/rcs.py for the closed forms):
- flat PEC plate, specular: sigma = pi R^2 (the image of the radar in an infinite mirror), not the
  physical-optics 4 pi A^2 / lambda^2: Sionna RT's specular reflection has no aperture.
- flat plate, Lambertian S = 1: 4 S^2 A (0.998 of it).
- sphere, Lambertian S = 1: 0.853 of (8 pi / 3) a^2 at 1e5..1e6 rays (stable to 0.2 %: the ray
  lattice is a quadrature, not random sampling); the co-polar V/V receive power is all of it (cross-pol
  is 1e-19 of co-pol), so the -0.69 dB is inside Sionna's diffuse field evaluation over oblique facets.
- sphere, specular: no path at all (a tessellated sphere is a set of flat mirrors, none exactly normal
  to the radar), so the geometric-optics pi a^2 is reproduced by no Sionna model.
"""
import numpy as np
import pytest

from processing.radar.propagation import lambertian_sphere_rcs, plate_po_rcs
from processing.radar.waveform import C0
from rtchannel.backends.rcs import PEC, monostatic_rcs, plate_mesh, sionna_backend, sphere_mesh
from rtchannel.scene.skin import SkinMaterial

LAMBERT_PEC = SkinMaterial(relative_permittivity=1.0, conductivity=1e8, scattering_coefficient=1.0)
R = 3.0


def test_plate_specular_is_a_mirror_image():
    for side in (0.2, 0.4):
        v, f = plate_mesh(side, side, 2)
        r = monostatic_rcs(sionna_backend(PEC, samples_per_src=100_000, specular=True, diffuse=False), v, f,
                           distance=R)
        # One exact image-method path with |Gamma| = 1: float32 geometry, 0.1 % covers rounding only;
        # the same for both sizes, unlike physical optics (a factor 16 between them).
        assert r["n_paths"] == 1
        assert r["sigma"] == pytest.approx(np.pi * R ** 2, rel=1e-3)
        assert abs(np.log10(r["sigma"] / plate_po_rcs(side ** 2, C0 / 24.125e9))) > 0.5


def test_plate_lambertian_broadside():
    v, f = plate_mesh(0.2, 0.2, 4)
    r = monostatic_rcs(sionna_backend(LAMBERT_PEC, samples_per_src=1_000_000, specular=False, diffuse=True),
                       v, f, distance=R)
    # ~350 ray hits on the plate: the ray-lattice quadrature of a flat patch is good to ~1 %; 3 % margin.
    assert r["sigma"] == pytest.approx(4 * 0.04, rel=0.03)


def test_sphere_lambertian():
    a = 0.3
    v, f = sphere_mesh(a, 4)
    r = monostatic_rcs(sionna_backend(LAMBERT_PEC, samples_per_src=300_000, specular=False, diffuse=True),
                       v, f, distance=R)
    ratio = r["sigma"] / lambertian_sphere_rcs(a)
    # Closed form (8 pi/3) a^2; measured 0.853 at 1e5, 3e5 and 1e6 rays (module doc). The band
    # [0.80, 0.90] holds that measured value with ~5 % room and fails on any factor-level error
    # (a missing cos: 0.75 or 1.5; |Gamma|^2 of skin instead of PEC: 0.4).
    assert 0.80 < ratio < 0.90
    r2 = monostatic_rcs(sionna_backend(LAMBERT_PEC, samples_per_src=300_000, specular=True, diffuse=False),
                        v, f, distance=R)
    assert r2["n_paths"] == 0 and r2["sigma"] == 0.0
