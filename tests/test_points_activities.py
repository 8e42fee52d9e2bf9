"""The point backend on procedural activities: numbers derivable on paper."""
import numpy as np
import pytest
from scipy.signal import find_peaks

from processing.radar.antenna import Isotropic, peak_gain_dbi
from processing.dsp.mti import cutoff_hz, moving_average_length
from processing.radar.waveform import C0
from rtchannel.backends.points import BODY_RCS_M2, point_paths
from rtchannel.motion.procedural import generate
from rtchannel.radar import Link, RadarConfig
from rtchannel.pipeline import simulate
from rtchannel.motion.pose import JOINT_INDEX


def test_point_delays_are_exact_geometry():
    m = generate("sit", height=1.6)
    radar = RadarConfig(links=[Link(name="mono", tx=(3, 0, 1.1)), Link(name="bi", tx=(3, 0, 1.1), rx=(0, -3, 1.1))])
    paths = point_paths(m, radar)
    # scatterer 0 is the head centre, half-way along the Head bone: compare through its own position
    pos = m.attached_points(np.array([JOINT_INDEX["Head"]]), m.rig.rest[[JOINT_INDEX["Head"]]] +
                            0.5 * (m.rig.tails[[JOINT_INDEX["Head"]]] - m.rig.rest[[JOINT_INDEX["Head"]]]))[:, 0]
    r1, r2 = np.linalg.norm(pos - [3, 0, 1.1], axis=1), np.linalg.norm(pos - [0, -3, 1.1], axis=1)
    np.testing.assert_allclose(paths["mono"].delays[:, 0], 2 * r1 / C0, rtol=1e-12)
    np.testing.assert_allclose(paths["bi"].delays[:, 0], (r1 + r2) / C0, rtol=1e-12)
    assert paths["mono"].n_paths == 21
    seed = point_paths(m, radar, scale="seed")["mono"]
    assert np.allclose(np.sum(np.abs(seed.gains[0]) ** 2), 1.0)
    # radar scale: P_r/P_t = G^2 lambda^2 sigma / ((4 pi)^3 R^4) with the head's share of the body RCS and
    # the default horn (Gaussian beam, 30 deg HPBW, aimed at (0, 0, 1.1)) at psi off boresight both ways
    d = pos - [3, 0, 1.1]
    r = np.linalg.norm(d, axis=1)
    psi = np.arccos(-d[:, 0] / r)  # boresight is -x
    g = 10 ** (peak_gain_dbi(radar.antenna) / 10) * np.exp(-4 * np.log(2) * (psi / np.radians(30.0)) ** 2)
    lam = radar.waveform.wavelength
    expected = g ** 2 * lam ** 2 * np.abs(seed.gains[0, 0]) ** 2 * BODY_RCS_M2 / ((4 * np.pi) ** 3 * r ** 4)
    np.testing.assert_allclose(np.abs(paths["mono"].gains[:, 0]) ** 2, expected, rtol=1e-12)
    iso = point_paths(m, radar.model_copy(update={"antenna": Isotropic()}))["mono"]
    np.testing.assert_allclose(np.abs(iso.gains[:, 0]) ** 2, expected / g ** 2, rtol=1e-12)


@pytest.mark.parametrize("speed", [0.9, 1.3, 1.7])
def test_walk_toward_radar_mean_velocity_equals_walking_speed(speed):
    # Every body point moves at the walking speed on average, so eq. 8 averaged over whole gait
    # cycles gives the speed (times cos of the small elevation angle to a far radar: > 0.99 here).
    m = generate("walk", speed=speed, distance=5.0, pad_before=0.0, pad_after=0.0)
    radar = RadarConfig(links=[Link(name="r", tx=(14.0, 0.0, 1.0))])
    sig = simulate(m, radar).links["r"].signature
    hips_v = np.gradient(m.positions[:, 0, 0], 1 / m.fps)
    steady = np.flatnonzero(np.abs(hips_v - speed) < 0.25 * speed)
    foot_z = m.positions[:, JOINT_INDEX["LeftFoot"], 2]
    peaks, _ = find_peaks(foot_z[steady[0]:steady[-1]], prominence=0.02)
    assert len(peaks) >= 2, "need at least one whole stride"
    t0, t1 = m.times[steady[0] + peaks[0]], m.times[steady[0] + peaks[-1]]
    sel = (sig.time >= t0) & (sig.time <= t1)
    assert abs(sig.mean_velocity[sel].mean() - speed) < 0.10 * speed


def test_fall_peak_mean_velocity_exceeds_sit():
    radar = RadarConfig(links=[Link(name="r", tx=(3.0, 0.0, 1.1))])
    peak = {a: np.abs(simulate(generate(a), radar).links["r"].signature.mean_velocity).max() for a in ("fall", "sit")}
    assert peak["fall"] > peak["sit"]


def test_fall_toward_and_away_from_the_radar_has_the_sign_of_its_travel():
    # a radar 3 m ahead (+x): the body falls toward it (forward) or away (backward). The mean radial
    # velocity integrated over the fall is a power-weighted range change, within the body's: the feet move
    # least, the head most (1.8 m forward; backward 0.9 m, with the pelvis 0.3 m); its sign is the direction of
    # travel (positive = approaching)
    radar = RadarConfig(links=[Link(name="r", tx=(3.0, 0.0, 1.1))])
    moved = {}
    for direction in ("forward", "backward"):
        sig = simulate(generate("fall", seed=0, fall_direction=direction), radar).links["r"].signature
        moved[direction] = float(np.sum(sig.mean_velocity) * (sig.time[1] - sig.time[0]))
    assert 0.3 < moved["forward"] < 1.8 and -0.9 < moved["backward"] < -0.2


@pytest.mark.parametrize("activity", ["fall", "walk", "stand", "sit", "pick"])
def test_every_activity_gives_finite_signatures(activity):
    res = simulate(generate(activity, seed=2), RadarConfig().for_direction(7))
    for link in res.links.values():
        s = link.signature
        assert np.isfinite(s.p_vt).all() and np.isfinite(s.mean_velocity).all()
        assert s.valid.mean() > 0.5
        assert np.abs(s.mean_velocity).max() < 6.3


def test_iq_transform_acts_before_dsp_and_on_kept_iq():
    radar = RadarConfig(links=[Link(name="r", tx=(3.0, 0.0, 1.1))])
    m = generate("sit", duration=2.0)
    plain = simulate(m, radar, keep_iq=True).links["r"]
    seen = []

    def zero_second_half(name, iq):
        seen.append(name)
        out = iq.copy()
        out[iq.shape[0] // 2:] = 0
        return out

    cut = simulate(m, radar, keep_iq=True, iq_transform=zero_second_half).links["r"]
    assert seen == ["r"]
    half = plain.iq.shape[0] // 2
    assert np.all(cut.iq[half:] == 0) and np.array_equal(cut.iq[:half], plain.iq[:half])
    # the default clutter filter (centred moving average of L chirps) reaches L/2 chirps past the cut; after
    # that and one window nothing is left: the windows are empty and their mean velocity exactly 0, while
    # the unmodified sit still moves
    wf = radar.waveform
    reach = moving_average_length(cutoff_hz(radar.dsp, wf.carrier_hz), 1 / wf.pri_s) // 2
    late = cut.signature.time > cut.signature.time[0] + (half + reach + 64) * wf.pri_s
    assert late.sum() > 10 and not cut.signature.valid[late].any()
    assert np.abs(cut.signature.mean_velocity[late]).max() < 1e-6
    assert np.abs(plain.signature.mean_velocity[late]).max() > 0.05


def test_antenna_inside_the_body_is_refused():
    """An antenna at the pelvis of a standing person is inside the body: one-line RadarPlacementError naming
    the link and time; 0.5 m in front of the chest (>= 0.15 m from every scatterer) is accepted."""
    from rtchannel.errors import RadarPlacementError, USER_ERRORS

    m = generate("stand", height=1.75)
    pelvis = m.positions[0, JOINT_INDEX["Hips"]]  # global joint positions [F, J, 3]
    inside = RadarConfig(links=[Link(name="mono", tx=tuple(float(x) for x in pelvis))])
    with pytest.raises(RadarPlacementError, match=r"link 'mono': the transmitter .* cm from body scatterer") as e:
        point_paths(m, inside)
    assert isinstance(e.value, USER_ERRORS) and "\n" not in str(e.value)
    d = np.linalg.norm(point_paths(m, RadarConfig.monostatic((3, 0, 1.1)))["radar1"].delays, axis=-1)
    assert np.isfinite(d).all()
