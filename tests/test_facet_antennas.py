"""Antenna patterns on the `facets` backend's paths: direct, wall-image and double-bounce paths get
sqrt(G_tx(u_tx)) sqrt(G_rx(u_rx)), with u towards the facet or, through a wall, towards its mirror image.

Patterns are checked against hand formulas (symmetric Gaussian beam G = G0 exp(-4 ln2 (psi / HPBW)^2) with
an explicit peak gain and a floor far below the angles used), not against `processing.radar.antenna`."""
import math

import numpy as np
import pytest

from processing.radar.antenna import GaussianBeam, Isotropic
from processing.radar.waveform import C0
from rtchannel.backends.facets import LinkSpec, facet_paths, mesh_paths
from rtchannel.backends.points import point_paths
from rtchannel.backends.rcs import plate_mesh
from rtchannel.backends.surface_scattering import SurfaceMaterial
from rtchannel.backends.wall_images import PlanarWall
from rtchannel.motion.pose import Motion
from rtchannel.motion.procedural import generate
from rtchannel.radar import Link, RadarConfig
from rtchannel.scene.rt_scene import RTScene, get_scene

F0 = 24.125e9
LAM = C0 / F0
PEC_PO = SurfaceMaterial(eta=None, scattering_coefficient=0.0)  # pure physical optics: one coherent glint
SKIN = SurfaceMaterial(eta=18.9 - 17.1j, scattering_coefficient=0.5)
LN2 = math.log(2.0)


def _beam(boresight, hpbw_az=30.0, hpbw_el=None, peak_dbi=15.0):
    return GaussianBeam(boresight=tuple(boresight), hpbw_az_deg=hpbw_az, hpbw_el_deg=hpbw_el or hpbw_az,
                        peak_gain_dbi=peak_dbi, floor_db=80.0)


def _amp(position, boresight, hpbw_deg, peak_dbi, target):
    """Hand formula: sqrt(G) of a symmetric Gaussian beam at `position` towards `target` [3]."""
    d = np.asarray(target, float) - np.asarray(position, float)
    b = np.asarray(boresight, float)
    psi = math.acos(np.clip(d @ b / (np.linalg.norm(d) * np.linalg.norm(b)), -1.0, 1.0))
    return math.sqrt(10 ** (peak_dbi / 10) * math.exp(-4 * LN2 * (psi / math.radians(hpbw_deg)) ** 2))


def _mirror(p, wall_point, wall_normal):
    n = np.asarray(wall_normal, float)
    return p - 2 * ((p - wall_point) @ n) * n


# ---- (1) a plate seen at boresight and off axis --------------------------------------------------------------

R = 100.0  # far field of the 0.2 m plate (2 D^2 / lambda = 6.5 m)


def _plate_power(tx_antenna):
    v, f = plate_mesh(0.2, 0.2, 8)  # normal +x, centred on the origin
    scene = RTScene("free_space", f, v, F0)
    tx = np.array([R, 0.0, 0.0])
    link = LinkSpec("l", tx, tx, tx_antenna, tx_antenna)
    ps = mesh_paths(scene, np.array([0.0, 0.1]), np.stack([v, v]), f, None, [link], LAM, PEC_PO, po=True)["l"]
    g, tau = ps.gains[0], ps.delays[0]
    on = g != 0
    assert on.sum() == len(f)
    return abs(np.sum(g[on] * np.exp(2j * np.pi * F0 * tau[on]))) ** 2


def test_plate_off_boresight_power_follows_the_two_way_pattern():
    # The antenna at (R, 0, 0) turns its boresight away from the plate by psi (in the azimuth plane, or the
    # elevation plane with its own beamwidth): the scattering is untouched, so the coherent power changes by
    # the monostatic two-way pattern (G(psi)/G0)^2 = exp(-4 ln2 (psi/HPBW)^2)^2, and at boresight the
    # isotropic power is multiplied by G0^2.
    # Tolerance: the 128 facet centroids spread +-1 mrad about the axis. The PO glint is the plain sum of
    # the facets (equal phases at broadside), so the ratio is the mean of the factors over the facets: its
    # first-order term cancels (the centroids average to the plate centre) and the second-order terms are
    # (d ln G^2/dpsi)^2 d^2 / 2 + (d^2 ln G^2/dpsi^2) d^2 / 2 <= (4.3^2 + 2 * 8 ln2 / 0.35^2) * 1e-6 / 2 = 5e-5
    # (psi = 12 deg, HPBW 20-30 deg): 2e-4 relative.
    iso = _plate_power(None)
    peak_dbi = 15.0
    on_axis = _plate_power(_beam((-1.0, 0.0, 0.0), 30.0, 20.0, peak_dbi))
    assert on_axis / iso == pytest.approx(10 ** (2 * peak_dbi / 10), rel=2e-4)
    psi = math.radians(12.0)
    for bore, hpbw in (((-math.cos(psi), math.sin(psi), 0.0), 30.0), ((-math.cos(psi), 0.0, math.sin(psi)), 20.0)):
        off = _plate_power(_beam(bore, 30.0, 20.0, peak_dbi))
        expected = math.exp(-4 * LN2 * (psi / math.radians(hpbw)) ** 2) ** 2  # 0.48 (azimuth), 0.19 (elevation)
        assert off / on_axis == pytest.approx(expected, rel=2e-4)


# ---- (2) paths via a wall: the factor looks at the mirror image ------------------------------------------------

WALL = PlanarWall("w", point=np.array([1.0, 2.0, 0.0]), normal=np.array([0.0, -1.0, 0.0]),
                  polygon=np.array([[-5, 2, -3], [6, 2, -3], [6, 2, 3], [-5, 2, 3]], float),
                  relative_permittivity=5.24 - 0.4j, thickness=0.2)


def _wall_scene_paths(links):
    v, f = plate_mesh(0.3, 0.3, 2)  # 8 facets at different angles from the antennas
    scene = RTScene("free_space", f, v, F0)
    out = mesh_paths(scene, np.array([0.0, 0.1]), np.stack([v, v]), f, None, links, LAM, SKIN, walls=[WALL],
                     po=True, double_bounce="same")
    return out, v[f].mean(axis=1), len(f)


def test_wall_image_factors_match_the_pattern_towards_the_mirror_image():
    tx, rx = np.array([3.0, 0.6, 0.2]), np.array([2.5, -0.8, -0.1])
    tb, rb = (-1.0, 0.3, 0.05), (-1.0, 0.1, -0.2)  # neither antenna looks straight at the plate or its image
    hp_tx, hp_rx, dbi_tx, dbi_rx = 40.0, 60.0, 15.0, 10.0
    horn = LinkSpec("h", tx, rx, _beam(tb, hp_tx, peak_dbi=dbi_tx), _beam(rb, hp_rx, peak_dbi=dbi_rx))
    (out, cent, n_f) = _wall_scene_paths([horn, LinkSpec("i", tx, rx)])
    h, i = out["h"], out["i"]
    assert np.array_equal(h.ids, i.ids)
    kinds = h.ids // n_f
    # kind 0 direct, 1 tx image, 2 rx image, 3 both images (double bounce via the same wall); one wall
    assert set(kinds.tolist()) == {0, 1, 2, 3}
    checked = 0
    for col in np.flatnonzero(i.gains[0] != 0):
        kind, c = kinds[col], cent[h.ids[col] % n_f]
        c_img = _mirror(c, WALL.point, WALL.normal)
        to_tx = c_img if kind in (1, 3) else c
        to_rx = c_img if kind in (2, 3) else c
        factor = _amp(tx, tb, hp_tx, dbi_tx, to_tx) * _amp(rx, rb, hp_rx, dbi_rx, to_rx)
        # Both frames are traced: the factor is applied exactly (float64 rounding only).
        assert h.gains[0, col] / i.gains[0, col] == pytest.approx(factor, rel=1e-9)
        # A wrong direction (the facet instead of its image) would differ by more than 10 %.
        if kind:
            wrong = _amp(tx, tb, hp_tx, dbi_tx, c) * _amp(rx, rb, hp_rx, dbi_rx, c)
            assert abs(wrong / factor - 1) > 0.1
        checked += 1
    assert checked == 4 * n_f


def test_monostatic_merged_image_twins_get_their_own_factors():
    # Monostatically tx' -> f -> rx and tx -> f -> rx' are merged into one path (kind 1); with different
    # transmit and receive antennas each twin needs its own factor: A_tx(c') A_rx(c) and A_tx(c) A_rx(c').
    # The twins' isotropic gains come from a bistatic link whose receiver is 0.1 um away (kinds 1 and 2):
    # that geometry change moves the gains by ~1e-7 relative (test_wall_images uses 1e-5 likewise).
    tx = np.array([3.0, 0.6, 0.2])
    rx_near = tx + np.array([0.0, 0.0, 1e-7])
    tb, rb = (-1.0, 0.4, 0.0), (-1.0, -0.3, 0.1)
    a_tx, a_rx = _beam(tb, 40.0, peak_dbi=15.0), _beam(rb, 60.0, peak_dbi=10.0)
    out, cent, n_f = _wall_scene_paths([LinkSpec("mono", tx, tx, a_tx, a_rx), LinkSpec("bi", tx, rx_near)])
    mono, bi = out["mono"], out["bi"]
    g_bi = dict(zip(bi.ids, bi.gains[0]))
    cols = np.flatnonzero((mono.ids // n_f == 1) & (mono.gains[0] != 0))
    assert cols.size == n_f
    for col in cols:
        f = mono.ids[col] % n_f
        c = cent[f]
        c_img = _mirror(c, WALL.point, WALL.normal)
        fwd = _amp(tx, tb, 40.0, 15.0, c_img) * _amp(tx, rb, 60.0, 10.0, c)
        rev = _amp(tx, tb, 40.0, 15.0, c) * _amp(tx, rb, 60.0, 10.0, c_img)
        assert abs(fwd / rev - 1) > 0.1  # the two twins' factors really differ here
        expected = g_bi[f + n_f] * fwd + g_bi[f + 2 * n_f] * rev
        assert mono.gains[0, col] == pytest.approx(expected, rel=1e-5)


# ---- (3) a walking body with the default horn kit: facets and points agree ------------------------------------

def test_walk_horn_over_isotropic_power_change_agrees_with_points():
    # Both backends multiply each path by the same horns' sqrt(G_tx G_rx); their relative change (horn over
    # isotropic, total power over the walk) is 2 G0 (the common +32 dB of the seed's 30-deg horns) plus the
    # power-weighted mean of the pattern loss over each backend's scatterers, so a missing or doubled factor
    # is off by ~30 dB. The two differ only in where the body's power sits: the points give 0.21 of the
    # body RCS to the shins, feet and toes (z < 0.3 m, the seed's area fractions), which the walk sees 13-27
    # deg below boresight (two-way loss 24.1 (el / 30 deg)^2 dB = 4.5-19 dB, i.e. a factor < 0.35), while
    # the facets' power is mostly the trunk's PO glints near antenna height. Moving 0.21 of the power from
    # a factor ~1 to < 0.35 lowers the mean by 10 log10(1 - 0.21 (0.65..1)) = 0.6-1.0 dB; the head and
    # thighs at the close end add a few tenths: 1.5 dB (measured 0.99 dB radar 1, 0.17 dB radar 2). Per
    # frame, the whole lower body (thighs down, 0.40 of the points' RCS) lost entirely would give
    # 10 log10(1 / 0.6) = 2.2 dB: 2.5 dB (measured 1.43 / 1.18 dB).
    m = generate("walk", duration=2.0, start=(-1.0, 0.0))  # x from -1 to 1.6 m: radar 2 sees it cross its beam
    horn, iso = RadarConfig(), RadarConfig(antenna=Isotropic())
    fh, fi = (facet_paths(m, r, scene="free_space", lod="2k", walls=False) for r in (horn, iso))
    ph, pi = point_paths(m, horn), point_paths(m, iso)

    def power(ps):
        return np.sum(np.abs(ps.gains) ** 2, axis=1)

    for name in fh:
        d_f = 10 * np.log10(power(fh[name]) / power(fi[name]))
        d_p = 10 * np.log10(power(ph[name]) / power(pi[name]))
        walk_f = 10 * np.log10(power(fh[name]).sum() / power(fi[name]).sum())
        walk_p = 10 * np.log10(power(ph[name]).sum() / power(pi[name]).sum())
        assert abs(walk_f - walk_p) < 1.5, (name, walk_f, walk_p)
        assert np.max(np.abs(d_f - d_p)) < 2.5, name
        assert walk_f > 20.0  # the horns' gain is really there (2 G0 = 32 dB on boresight)
    # Radar 2 sees the walk cross its beam: the change follows the crossing (over 15 dB of swing).
    d2 = 10 * np.log10(power(fh["radar2"]) / power(fi["radar2"]))
    assert d2.max() - d2.min() > 15.0


# ---- (4) isotropic antennas: the gains of before, bit for bit --------------------------------------------------

def test_isotropic_antennas_leave_every_path_bit_identical():
    m = generate("walk", duration=1.0, start=(-1.0, 0.3))
    m = Motion(m.rig, m.fps, m.rotations[40:44], m.positions[40:44])
    links = [Link(name="mono", tx=(3.0, 0.0, 1.1)), Link(name="bi", tx=(3.0, 0.0, 1.1), rx=(0.0, -3.0, 1.1))]
    scene = get_scene("room", "2k", m.rig.height, F0)
    opts = dict(scene=scene, lod="2k", walls=True, trace_fps=None, min_relative_gain_db=None, double_bounce="pairs")
    # Isotropic radar antennas (with an orientation too: it must not matter) against links without any
    # antenna (LinkSpec's default, the API of before: no factor at all).
    plain = RadarConfig(links=links, antenna=Isotropic())
    turned = RadarConfig(links=[lk.model_copy(update={"tx_antenna": Isotropic(boresight=(0.3, 1.0, 0.2))})
                                for lk in links], antenna=Isotropic())
    a, b = facet_paths(m, plain, **opts), facet_paths(m, turned, **opts)
    assert LinkSpec("x", np.zeros(3), np.zeros(3), Isotropic(), Isotropic()).antennas() is None
    for name in a:
        assert np.array_equal(a[name].ids, b[name].ids)
        assert np.array_equal(a[name].gains, b[name].gains)
        assert np.array_equal(a[name].delays, b[name].delays, equal_nan=True)
        kinds = a[name].ids // len(scene.body_faces)
        assert kinds.max() > 2 * len(scene.walls)  # double-bounce paths are among those compared
    # A directional receive antenna does change the bistatic link (the comparison above can fail).
    horn = RadarConfig(links=[links[0], links[1].model_copy(update={"rx_antenna": _beam((0.0, 1.0, 0.0))})],
                       antenna=Isotropic())
    c = facet_paths(m, horn, **opts)
    assert np.array_equal(c["mono"].gains, a["mono"].gains)
    assert not np.array_equal(c["bi"].gains, a["bi"].gains)
