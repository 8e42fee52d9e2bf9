"""Antenna patterns: closed forms, orientation (look-at, rotation about z), local/Sionna frames, validation."""
import math
from types import SimpleNamespace

import numpy as np
import pytest
from pydantic import ValidationError

from processing.radar.antenna import (GaussianBeam, Isotropic, YagiBeam, directivity_dbi, gain, kraus_gain_dbi,
                                link_gain, local_directions, local_power_gain, parse_antenna, peak_gain_dbi,
                                sionna_orientation)
from processing.dsp.signatures import signatures
from processing.pathset import PathSet
from processing.synthesis.exact import synthesise
from processing.radar.waveform import C0, Waveform

POS = np.array([3.0, 0.0, 1.1])
CENTRE = (0.0, 0.0, 1.1)
HORN = GaussianBeam(hpbw_az_deg=30.0, hpbw_el_deg=20.0, floor_db=40.0, look_at=CENTRE)


def _towards(az_deg, el_deg, r=2.0, pos=POS):
    """Point at range r from the radar at (3, 0, 1.1) looking along -x: az about z (left = +), el up."""
    az, el = np.radians(az_deg), np.radians(el_deg)
    d = np.array([-np.cos(el) * np.cos(az), -np.cos(el) * np.sin(az), np.sin(el)])
    return pos + r * d


def _rz(deg):
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1.0]])


def test_gaussian_principal_cuts_match_closed_form():
    # On the azimuth cut (el = 0) and the elevation cut the pattern is exactly G0 exp(-4 ln2 (angle/HPBW)^2).
    g0 = 10 ** (peak_gain_dbi(HORN) / 10)
    for az in (0.0, 10.0, 15.0, 40.0, -25.0):
        g = gain(HORN, POS, _towards(az, 0.0)) ** 2
        assert g == pytest.approx(g0 * math.exp(-4 * math.log(2) * (az / 30.0) ** 2), rel=1e-12)
    for el in (10.0, -10.0, 25.0):
        g = gain(HORN, POS, _towards(0.0, el)) ** 2
        assert g == pytest.approx(g0 * math.exp(-4 * math.log(2) * (el / 20.0) ** 2), rel=1e-12)
    # far off axis the floor holds, 40 dB below the peak, never 0
    assert gain(HORN, POS, _towards(180.0, 0.0)) ** 2 == pytest.approx(g0 * 1e-4, rel=1e-12)


def test_yagi_half_power_points_and_front_to_back():
    y = YagiBeam(hpbw_az_deg=24.0, hpbw_el_deg=40.0, front_to_back_db=20.0, floor_db=30.0, peak_gain_dbi=17.0,
                 look_at=CENTRE)
    g0 = 10 ** 1.7
    assert gain(y, POS, _towards(12.0, 0.0)) ** 2 == pytest.approx(g0 / 2, rel=1e-12)
    assert gain(y, POS, _towards(0.0, -20.0)) ** 2 == pytest.approx(g0 / 2, rel=1e-12)
    assert gain(y, POS, _towards(180.0, 0.0)) ** 2 == pytest.approx(g0 / 100, rel=1e-12)


def _moving_point(direction_az_deg, antenna, wf, r0=2.5, v=1.0, sigma=0.5):
    """Point target receding radially at v along azimuth `direction_az_deg`, on the radar equation scale,
    with the antenna factors of a monostatic link (same pattern on transmit and receive)."""
    times = np.arange(0.0, 0.4, 1 / 60)
    r = r0 + v * times
    pts = np.stack([_towards(direction_az_deg, 0.0, ri) for ri in r])[:, None, :]
    amp = wf.wavelength * math.sqrt(sigma) / ((4 * math.pi) ** 1.5 * r ** 2)  # |a|^2 = Pr/Pt, isotropic
    g = amp[:, None] * link_gain(antenna, POS, antenna, POS, pts)
    return PathSet(times=times, delays=(2 * r / C0)[:, None], gains=g.astype(complex), ids=np.array([0]))


def test_40_degrees_off_boresight_through_synthesis_and_dsp():
    # 30 deg HPBW horn, monostatic: the power ratio of a target 40 deg off in azimuth to one on boresight is
    # G(40)^2 / G(0)^2, i.e. 2 x 10 log10(exp(-4 ln2 (40/30)^2)) = -42.81 dB. The synthesiser and the DSP are
    # linear in the path gain and both targets share range history and velocity, so the measured ratio is
    # exact up to complex64 rounding (1e-6 dB); 0.1 dB catches any amplitude/power (factor 2 in dB) slip.
    wf = Waveform()
    horn = GaussianBeam(hpbw_az_deg=30.0, hpbw_el_deg=30.0, floor_db=60.0, look_at=CENTRE)
    expected_db = 2 * 10 * math.log10(math.exp(-4 * math.log(2) * (40 / 30) ** 2))
    assert expected_db == pytest.approx(-42.813, abs=0.001)
    powers = []
    for az in (0.0, 40.0):
        t, iq = synthesise(_moving_point(az, horn, wf), wf, method="exact")
        sig = signatures(iq, wf, t0=t[0])
        assert sig.valid.all()
        powers.append(sig.power.sum())
    assert 10 * math.log10(powers[1] / powers[0]) == pytest.approx(expected_db, abs=0.1)


def test_look_at_gives_the_maximum():
    rng = np.random.default_rng(7)
    dirs = rng.normal(size=(20000, 3))
    targets = POS + dirs / np.linalg.norm(dirs, axis=1, keepdims=True) * rng.uniform(0.5, 5.0, (20000, 1))
    g = gain(HORN, POS, targets)
    g_look = gain(HORN, POS, np.array(CENTRE))
    assert g_look == pytest.approx(10 ** (peak_gain_dbi(HORN) / 20), rel=1e-14)
    assert g.max() <= g_look
    np.testing.assert_allclose(HORN.boresight_unit(POS), [-1.0, 0.0, 0.0], atol=1e-15)


@pytest.mark.parametrize("k", [2, 5, 11, 18])
def test_rotating_antenna_and_look_at_about_z_keeps_gain_to_co_rotated_targets(k):
    angle = 20.0 * (k - 1)  # the seed's direction k
    rng = np.random.default_rng(k)
    targets = rng.uniform([-2, -2, 0], [2, 2, 2], (500, 3))
    rz = _rz(angle)
    for spec in (GaussianBeam(hpbw_az_deg=30, hpbw_el_deg=20, look_at=(0.4, -0.3, 1.0)),  # off the z axis
                 YagiBeam(hpbw_az_deg=24, hpbw_el_deg=30, boresight=(-1.0, 0.2, -0.1)),
                 Isotropic()):
        g = gain(spec, POS, targets)
        g_rot = gain(spec.rotated_about_z(angle), rz @ POS, targets @ rz.T)
        np.testing.assert_allclose(g_rot, g, rtol=1e-12, atol=0)
    # an off-axis look-at point left behind would aim the antenna elsewhere
    spec = GaussianBeam(hpbw_az_deg=30, hpbw_el_deg=20, look_at=(0.4, -0.3, 1.0))
    assert not np.allclose(gain(spec, rz @ POS, targets @ rz.T), gain(spec, POS, targets), rtol=1e-3)


def test_target_at_antenna_position_is_finite_boresight():
    g = gain(HORN, POS, np.stack([POS, POS + [1e-300, 0, 0], _towards(0, 0)]))
    assert np.all(np.isfinite(g))
    assert g[0] == pytest.approx(10 ** (peak_gain_dbi(HORN) / 20), rel=1e-14)


def _sionna_rotation_matrix(yaw, pitch, roll):
    # Sionna RT's rotation_matrix (TR 38.901 eq. 7.1-4): Rz(yaw) Ry(pitch) Rx(roll)
    ca, sa, cb, sb, cc, sc = (math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch), math.cos(roll),
                              math.sin(roll))
    return np.array([[ca * cb, ca * sb * sc - sa * cc, ca * sb * cc + sa * sc],
                     [sa * cb, sa * sb * sc + ca * cc, sa * sb * cc - ca * sc],
                     [-sb, cb * sc, cb * cc]])


@pytest.mark.parametrize("spec", [HORN, YagiBeam(hpbw_az_deg=24, hpbw_el_deg=36, boresight=(-1, 0.3, -0.2),
                                                 up=(0.1, 0.0, 1.0)), Isotropic()])
def test_local_spherical_evaluation_and_sionna_orientation(spec):
    rng = np.random.default_rng(3)
    targets = rng.uniform([-2, -2, 0], [2, 2, 2], (300, 3))
    u = local_directions(spec, POS, targets)
    theta, phi = np.arccos(np.clip(u[:, 2], -1, 1)), np.arctan2(u[:, 1], u[:, 0])  # Sionna's angles
    np.testing.assert_allclose(local_power_gain(spec, theta, phi), gain(spec, POS, targets) ** 2, rtol=1e-10)
    np.testing.assert_allclose(_sionna_rotation_matrix(*sionna_orientation(spec, POS)), spec.frame(POS), atol=1e-12)


def test_local_pattern_runs_with_drjit_operations():
    dr = pytest.importorskip("drjit")
    llvm = pytest.importorskip("drjit.llvm")
    ops = SimpleNamespace(sin=dr.sin, cos=dr.cos, exp=dr.exp, sqrt=dr.sqrt, arctan2=dr.atan2, maximum=dr.maximum,
                          power=dr.power, where=dr.select)
    theta = np.linspace(0.0, np.pi, 61)
    phi = np.linspace(-np.pi, np.pi, 61, endpoint=False)
    th, ph = (a.ravel() for a in np.meshgrid(theta, phi))
    for spec in (HORN, YagiBeam(hpbw_az_deg=24, hpbw_el_deg=36, boresight=(1, 0, 0))):
        g_dr = local_power_gain(spec, llvm.Float(th), llvm.Float(ph), ops)
        np.testing.assert_allclose(np.array(g_dr), local_power_gain(spec, th, ph), rtol=2e-5)


def test_directivity_normalises_the_pattern_and_matches_closed_forms():
    # Narrow Gaussian beam without floor: D = 16 ln2 / (HPBW_az HPBW_el) [rad]; small-angle error < 0.01 dB.
    narrow = GaussianBeam(hpbw_az_deg=10, hpbw_el_deg=8, floor_db=80, boresight=(1, 0, 0))
    d_closed = 10 * math.log10(16 * math.log(2) / np.radians(10) / np.radians(8))
    assert directivity_dbi(narrow) == pytest.approx(d_closed, abs=0.01)
    # Kraus (41253 / HPBW^2) is 0.54 dB above the Gaussian beam's directivity (41253 / 36410 = 1.133).
    kraus_excess = 10 * math.log10(math.pi / 4 / math.log(2))
    assert kraus_gain_dbi(10, 8) - directivity_dbi(narrow) == pytest.approx(kraus_excess, abs=0.01)
    # Independent check of the normalisation: the mean gain over a Fibonacci sphere is 1 (energy conserved).
    n = 400_000
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    a = np.pi * (1 + 5 ** 0.5) * k
    pts = np.stack([np.sqrt(1 - z * z) * np.cos(a), np.sqrt(1 - z * z) * np.sin(a), z], axis=1)
    for spec in (HORN, YagiBeam(hpbw_az_deg=24, hpbw_el_deg=24, floor_db=25, boresight=(1, 0, 0))):
        assert np.mean(gain(spec, POS, POS + pts) ** 2) == pytest.approx(1.0, rel=2e-3)
    assert directivity_dbi(Isotropic()) == 0.0


@pytest.mark.parametrize("data, field", [
    ({"kind": "gaussian", "hpbw_az_deg": 30, "hpbw_el_deg": 30, "look_at": [0, float("nan"), 1]}, "look_at"),
    ({"kind": "gaussian", "hpbw_az_deg": 0.0, "hpbw_el_deg": 30, "look_at": [0, 0, 1]}, "hpbw_az_deg"),
    ({"kind": "gaussian", "hpbw_az_deg": 30, "hpbw_el_deg": float("inf"), "look_at": [0, 0, 1]}, "hpbw_el_deg"),
    ({"kind": "gaussian", "hpbw_az_deg": 30, "hpbw_el_deg": 30, "look_at": [0, 0, 1], "floor_db": 1}, "floor_db"),
    ({"kind": "gaussian", "hpbw_az_deg": 30, "hpbw_el_deg": 30, "look_at": [0, 0, 1], "peak_gain_dbi": 70},
     "peak_gain_dbi"),
    ({"kind": "yagi", "hpbw_az_deg": 180, "hpbw_el_deg": 30, "boresight": [1, 0, 0]}, "hpbw_az_deg"),
    ({"kind": "yagi", "hpbw_az_deg": 24, "hpbw_el_deg": 24, "boresight": [1, 0, 0], "front_to_back_db": 35},
     "front_to_back_db"),
    ({"kind": "gaussian", "hpbw_az_deg": 30, "hpbw_el_deg": 30}, "boresight or look_at"),
    ({"kind": "gaussian", "hpbw_az_deg": 30, "hpbw_el_deg": 30, "boresight": [1, 0, 0], "look_at": [0, 0, 1]},
     "not both"),
    ({"kind": "gaussian", "hpbw_az_deg": 30, "hpbw_el_deg": 30, "boresight": [0, 0, -2]}, "parallel to up"),
    ({"kind": "isotropic", "gain_dbi": 3}, "gain_dbi"),
    ({"kind": "horn"}, "kind"),
])
def test_invalid_antennas_are_rejected_naming_the_field(data, field):
    with pytest.raises(ValidationError, match=field):
        parse_antenna(data)


def test_parse_and_undefined_look_at():
    spec = parse_antenna({"kind": "yagi", "hpbw_az_deg": 24, "hpbw_el_deg": 30, "look_at": [0, 0, 1.1]})
    assert isinstance(spec, YagiBeam) and spec.rotated_about_z(90).look_at == (0.0, 0.0, 1.1)
    with pytest.raises(ValueError, match="coincides with the antenna position"):
        gain(spec, (0, 0, 1.1), [[1, 1, 1]])


def test_tabulated_directivities_are_the_computed_ones():
    # The table only saves start-up time: each entry must be what the integral gives. 1e-12 relative allows
    # the last-bit differences of numpy's vectorised exp/arctan2 between CPUs summed over the grid (each
    # term ~1e-16 relative, 2e6 terms in pairwise sums: error growth ~log2(2e6) ulp), nothing more.
    from processing.radar import antenna
    from processing.radar.receiver import ANCORTEK_2400T2R4

    assert antenna._directivity_params(ANCORTEK_2400T2R4.antenna) in antenna._TABULATED
    for (kind, params), tabulated in antenna._TABULATED.items():
        assert antenna._directivity.__wrapped__(kind, params) == pytest.approx(tabulated, rel=1e-12)
        spec = {"gaussian": GaussianBeam, "yagi": YagiBeam}[kind].model_validate(dict(params, boresight=(0, 1, 0)))
        assert directivity_dbi(spec) == 10 * math.log10(tabulated)


@pytest.mark.parametrize("tilt", [-10.0, 0.0, 8.0, 20.0])
def test_downtilt_moves_the_peak_and_keeps_the_elevation_beamwidth(tilt):
    """The gain peaks at the tilted boresight, and its half-power points lie +-HPBW_el / 2 about it in the
    vertical plane (the pattern is only turned): checked on the 580AD-like Yagi, 24 deg in elevation."""
    from processing.radar.antenna import YagiBeam, gain, peak_gain_dbi

    pos = np.array([3.0, 0.0, 1.0])  # gain() is the amplitude factor sqrt(G): 20 log10 of it is G in dBi
    ant = YagiBeam(hpbw_az_deg=24.0, hpbw_el_deg=24.0, peak_gain_dbi=17.0, front_to_back_db=20.0, floor_db=25.0,
                   look_at=(0.0, 0.0, 1.0), downtilt_deg=tilt)
    el = np.radians(np.linspace(-60, 60, 24001))  # elevation of the direction, seen from the antenna
    dirs = np.stack([-np.cos(el), 0 * el, np.sin(el)], axis=-1)  # toward -x (the look-at point), up and down
    g = gain(ant, pos, pos + dirs)  # amplitude factor sqrt(G)
    g_db = 20 * np.log10(g)
    peak = np.degrees(el[np.argmax(g_db)])
    assert peak == pytest.approx(-tilt, abs=0.01)
    assert g_db.max() == pytest.approx(peak_gain_dbi(ant), abs=1e-6) and peak_gain_dbi(ant) == 17.0
    half = np.degrees(el[g_db >= g_db.max() - 3.0103])
    assert half.min() == pytest.approx(-tilt - 12.0, abs=0.05) and half.max() == pytest.approx(-tilt + 12.0, abs=0.05)
