"""The `sionna` backend with the radar's antenna patterns (Sionna RT arrays, `rtchannel.backends.sionna_antennas`).

All traces are diffuse-only in free space on the 2k avatar with Sionna's deterministic sampler (the same
candidates in every run, so two runs differ only in the antenna factors).
"""
import math

import numpy as np
import pytest

from processing.radar.antenna import GaussianBeam, Isotropic, YagiBeam, gain
from rtchannel.backends.points import point_paths
from rtchannel.backends.sionna_antennas import place_antennas
from rtchannel.backends.sionna_rt import _tracer, sionna_paths, trace_frames
from rtchannel.body.avatar import load_avatar
from rtchannel.motion.procedural import generate
from rtchannel.radar import Link, RadarConfig
from rtchannel.scene.rt_scene import get_scene

FREQ = 24.125e9
TX = (3.0, 0.0, 1.1)
HORN = GaussianBeam(hpbw_az_deg=30, hpbw_el_deg=30, peak_gain_dbi=16, look_at=(0.0, 0.0, 1.1))


@pytest.fixture(scope="module")
def body():
    return load_avatar("2k", 1.75).vertices.astype(float)


@pytest.fixture(scope="module")
def scene():
    return get_scene("free_space", "2k", 1.75, FREQ)


def _total_power(scene, radar, verts, rays) -> dict[str, float]:
    ps = trace_frames(scene, radar, np.zeros(1), verts[None], np.zeros_like(verts)[None], samples_per_src=rays,
                      specular=False, deterministic=True)
    return {name: float(np.sum(np.abs(p.gains) ** 2)) for name, p in ps.items()}


def _g2(psi_deg: float) -> float:
    """Normalised two-way power pattern G(psi)^2 / G0^2 of a 30-degree Gaussian beam."""
    return math.exp(-2 * 4 * math.log(2) * (psi_deg / 30.0) ** 2)


def test_small_target_off_axis_follows_the_two_way_pattern(body, scene):
    # A 9 cm target (the avatar shrunk 20x) 3 m in front of a monostatic horn: boresight on it, then
    # turned 20 deg away in azimuth. Every path's factor is G(psi_i)^2 with psi_i within delta (the target's
    # angular half-size seen from the radar) of the nominal angle, so the power ratio lies between
    # G(20 + delta)^2 / G0^2 and G(20 - delta)^2 / G(delta)^2 (the Gaussian falls monotonically); for
    # delta = 0.87 deg: 0.068..0.105 around G(20)^2 / G0^2 = 0.085. One-way (0.29), no pattern (1) or a
    # pattern turned the wrong way fail.
    c = (body.min(axis=0) + body.max(axis=0)) / 2
    target = (body - c) * 0.05 + [0.0, 0.0, 1.1]
    u = (target - TX) / np.linalg.norm(target - TX, axis=1, keepdims=True)
    delta = math.degrees(np.max(np.arccos(np.clip(u @ [-1.0, 0.0, 0.0], -1, 1))))
    assert delta < 1.0
    alpha = math.radians(20.0)
    power = []
    for b in ((-1.0, 0.0, 0.0), (-math.cos(alpha), math.sin(alpha), 0.0)):
        horn = HORN.model_copy(update={"look_at": None, "boresight": b})
        power.append(_total_power(scene, RadarConfig(links=[Link(name="r", tx=TX)], antenna=horn, receiver=None),
                                  target, 1_000_000)["r"])
    ratio = power[1] / power[0]
    assert _g2(20 + delta) < ratio < _g2(20 - delta) / _g2(delta), ratio


def _paths(scene, radar, verts, rays=200_000):
    """One deterministic solve of `radar`'s single antenna group, with interaction points (internals)."""
    scene.set_body(verts)
    place_antennas(scene, radar.links, radar)
    res = _tracer(scene, True)(scene.sionna_scene, rays, 1, False, True, False, False, 0, 512, 1_000_000)
    keep = res["valid"] & (np.abs(res["a"]) > 0)
    return res["a"][keep], res["vertices"][keep][:, 0]


def test_every_path_carries_the_projects_tx_and_rx_pattern(body, scene):
    # Bistatic: a horn turned 10 deg off the body, a Yagi receiver; both turn about z only, so their local
    # theta-hat (the "V" polarisation) is the world one and the only change against isotropic antennas is
    # the amplitude sqrt(G_tx(u_tx) G_rx(u_rx)) at the single-bounce point. Tolerance: both runs are float32
    # with identical candidates; the pattern sees the direction to ~1e-7 rad, which moves G by
    # 8 ln2 psi dpsi / HPBW^2 < 1e-6 relative; 1e-4 leaves room for the float32 sqrt/exp/atan2.
    yaw = math.radians(180.0 - 10.0)
    horn = HORN.model_copy(update={"look_at": None, "boresight": (math.cos(yaw), math.sin(yaw), 0.0)})
    yagi = YagiBeam(hpbw_az_deg=40, hpbw_el_deg=50, look_at=(0.3, 0.0, 1.1))
    rx = (0.0, -3.0, 1.1)
    link = Link(name="b", tx=TX, rx=rx, tx_antenna=horn, rx_antenna=yagi)
    a_pat, p_pat = _paths(scene, RadarConfig(links=[link], receiver=None), body)
    a_iso, p_iso = _paths(scene, RadarConfig(links=[link.model_copy(update={"tx_antenna": None, "rx_antenna": None})],
                                             antenna=Isotropic(), receiver=None), body)
    np.testing.assert_array_equal(p_pat, p_iso)  # the same paths
    assert len(a_pat) > 100
    expected = (gain(horn, TX, p_pat) * gain(yagi, rx, p_pat)) ** 2
    np.testing.assert_allclose(np.abs(a_pat) ** 2 / np.abs(a_iso) ** 2, expected, rtol=1e-4)
    assert expected.max() / expected.min() > 100  # the body really spans the patterns


def test_links_with_different_antenna_shapes_trace_as_if_alone(body, scene):
    # Sionna holds one tx and one rx array per scene: links of different shapes are separate solves, and
    # each must give exactly (bit for bit: same candidates, same kernels) what it gives on its own.
    yagi = YagiBeam(hpbw_az_deg=40, hpbw_el_deg=50, look_at=(0.0, 0.0, 1.1))
    links = [Link(name="horn", tx=TX), Link(name="yagi", tx=(0.0, -3.0, 1.1), tx_antenna=yagi, rx_antenna=yagi)]
    both = _total_power(scene, RadarConfig(links=links, antenna=HORN, receiver=None), body, 100_000)
    for lk in links:
        alone = _total_power(scene, RadarConfig(links=[lk], antenna=HORN, receiver=None), body, 100_000)
        assert both[lk.name] == alone[lk.name]
    # Yagi (directivity ~13 dBi two ways) against the 16-dBi horn: the links really differ.
    assert both["horn"] != both["yagi"]


def _old_placement(scene, links):
    """The backend's placement before antenna patterns: Sionna "iso" arrays, devices without orientation."""
    import mitsuba as mi
    import sionna.rt as rt

    s = scene.sionna_scene
    for name in list(s.transmitters) + list(s.receivers):
        s.remove(name)
    s.tx_array = rt.PlanarArray(num_rows=1, num_cols=1, pattern="iso", polarization="V")
    s.rx_array = rt.PlanarArray(num_rows=1, num_cols=1, pattern="iso", polarization="V")
    for k, lk in enumerate(links):
        s.add(rt.Transmitter(name=f"tx{k}", position=mi.Point3f(*map(float, lk.tx_pos))))
        s.add(rt.Receiver(name=f"rx{k}", position=mi.Point3f(*map(float, lk.rx_pos))))


def test_isotropic_antennas_are_bit_identical_to_unit_gain_devices(body, scene):
    links = [Link(name="r1", tx=TX), Link(name="r2", tx=(0.0, -3.0, 1.1))]
    # An isotropic antenna's orientation (here a boresight) changes nothing.
    radar = RadarConfig(links=links, antenna=Isotropic(boresight=(0.0, 1.0, 1.0)), receiver=None)
    scene.set_body(body)
    solve = _tracer(scene, True)
    args = (scene.sionna_scene, 100_000, 1, False, True, False, False, 0, 512, 1_000_000)
    _old_placement(scene, links)
    old = solve(*args)
    place_antennas(scene, links, radar)
    new = solve(*args)
    assert old["valid"].sum() > 100
    for key in ("valid", "src", "tgt", "a", "vertices"):
        np.testing.assert_array_equal(new[key], old[key])


def test_default_horns_change_power_as_in_the_points_backend():
    # The seed kit (30-deg Gaussian horns, directivity 16.1 dBi, looking at (0, 0, 1.1) m) against isotropic
    # antennas on a 2 s walk from (-1, 0) along +x: radar 1 sees it head-on near boresight (+30..31 dB, two
    # ways), radar 2 sees it cross its beam from 18 deg off to boresight (+22 -> +30 dB). Both backends apply
    # the same G_tx G_rx but average it over different scatterers (points: 21 skeleton points with area
    # gains; sionna: Lambertian returns from the skin), so their power-weighted mean directions differ by
    # about the skeleton-to-skin offset seen from 3 m, <= 0.12 m / 3 m = 2.3 deg, mostly in height where the
    # body is long. The two-way loss 24 (psi / 30 deg)^2 dB changes by 48 psi dpsi / 900 per degree: at
    # psi <= 10 deg (the power-weighted centroids: radar 1 throughout, radar 2 once it is in the beam)
    # 0.5 dB per deg, so 2.3 deg gives 1.2 dB; 1.5 dB allows that (measured: <= 0.5 dB). A missing rx
    # pattern (-15 dB), a one-way or mis-aimed beam (>= 5 dB on radar 2's early frames) fail.
    m = generate("walk", duration=1.0, start=(-1.0, 0.0), pad_before=0.0, pad_after=0.0).resampled(2.0)
    horn, iso = RadarConfig(receiver=None), RadarConfig(receiver=None, antenna=Isotropic())
    assert horn.antenna.kind == "gaussian"
    kw = dict(scene="free_space", lod="2k", samples_per_src=200_000, specular=False, deterministic=True)
    s_h, s_i = sionna_paths(m, horn, **kw), sionna_paths(m, iso, **kw)
    p_h, p_i = point_paths(m, horn), point_paths(m, iso)

    def change_db(a, b):
        return 10 * np.log10(np.sum(np.abs(a.gains) ** 2, axis=1) / np.sum(np.abs(b.gains) ** 2, axis=1))

    for name in ("radar1", "radar2"):
        ds, dp = change_db(s_h[name], s_i[name]), change_db(p_h[name], p_i[name])
        np.testing.assert_allclose(ds, dp, atol=1.5, err_msg=name)
    # radar 2: the walk crosses its beam, the change grows by > 5 dB (sionna and points alike)
    ds2 = change_db(s_h["radar2"], s_i["radar2"])
    assert ds2[-1] - ds2[0] > 5.0


def test_polarisation_goes_to_the_arrays_and_splits_the_solver_calls(scene):
    """Sionna holds one array per scene: a "V" and an "H" link are two groups; an "H" array's pattern has
    C_theta = 0 and |C_phi| = sqrt(G) (slant angle pi/2), for Sionna's iso element and a registered horn."""
    import drjit as dr
    import mitsuba as mi

    from rtchannel.backends.sionna_antennas import link_groups

    h_horn = HORN.model_copy(update={"polarization": "H"})
    radar = RadarConfig(links=[Link(name="v", tx=TX), Link(name="h", tx=TX, tx_antenna=h_horn, rx_antenna=h_horn)],
                        antenna=HORN)
    groups = link_groups(radar, radar.links)
    assert [[lk.name for lk in g] for g in groups] == [["v"], ["h"]]
    for ant, gain_db in ((Isotropic(polarization="H"), 0.0), (h_horn, 16.0)):
        r = RadarConfig(links=[Link(name="h", tx=TX)], antenna=ant)
        place_antennas(scene, r.links, r)
        c_theta, c_phi = scene.sionna_scene.tx_array.antenna_pattern.patterns[0](mi.Float(np.pi / 2), mi.Float(0.0))
        assert float(dr.abs(c_theta)[0]) < 1e-6
        assert float(dr.abs(c_phi)[0]) == pytest.approx(10 ** (gain_db / 20), rel=1e-4)
