"""Idle motion (rtchannel.motion.idle): small band-limited upper-body rotations on top of any motion."""
import dataclasses

import numpy as np
import pytest
from pydantic import ValidationError
from scipy.spatial.transform import Rotation

from rtchannel.motion.pose import Motion
from rtchannel.motion.idle import GROUPS, IdleMotion, add_idle, band_noise
from thirdparty import data_path

LEGS = ("Hips", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase", "RightUpLeg", "RightLeg", "RightFoot",
        "RightToeBase")


@pytest.fixture(scope="module")
def pick():
    return Motion.procedural("pick", seed=3)


def _local(m: Motion, j: int) -> np.ndarray:
    p = m.rig.parents[j]
    return np.swapaxes(m.rotations[:, p], -1, -2) @ m.rotations[:, j]


def test_legs_stay_and_each_joint_turns_by_the_requested_rms(pick):
    idle = IdleMotion()
    out = add_idle(pick, idle, seed=7)
    names = list(pick.rig.names)
    for n in LEGS:  # planted feet stay planted: not one bit of the legs moves
        j = names.index(n)
        np.testing.assert_array_equal(out.positions[:, j], pick.positions[:, j])
        np.testing.assert_array_equal(out.rotations[:, j], pick.rotations[:, j])
    for group, deg in idle.rms().items():
        for n in GROUPS[group]:
            j = names.index(n)
            # the local rotation changes by exactly the drawn rotation vector, scaled to `deg` RMS per axis
            d = np.swapaxes(_local(pick, j), -1, -2) @ _local(out, j)
            rv = np.rad2deg(Rotation.from_matrix(d).as_rotvec())
            np.testing.assert_allclose(np.sqrt(np.mean(rv ** 2, axis=0)), deg, rtol=1e-6)
    # bones keep their lengths (rigid segments)
    for j, p in enumerate(pick.rig.parents):
        if p >= 0:
            np.testing.assert_allclose(np.linalg.norm(out.positions[:, j] - out.positions[:, p], axis=1),
                                       np.linalg.norm(pick.positions[:, j] - pick.positions[:, p], axis=1),
                                       atol=1e-9)
    assert out.params["idle"]["seed"] == 7 and out.params["idle"]["elbow_deg"] == idle.elbow_deg


def test_hand_speed_is_that_of_a_fidget_not_a_gesture(pick):
    """The forearm (0.25 m, elbow to wrist) turning 2 deg RMS about each axis moves the hand by
    0.25 m x 0.035 rad x sqrt(2) (two axes across the bone) = 12 mm RMS; at the band's RMS frequency (~0.8-1 Hz
    for 0.3-1.5 Hz with 8th-order skirts) that is 2 pi f x 12 mm = 0.06-0.08 m/s. The other joints (the
    preset's amplitudes) add comparable shares: 0.1-0.3 m/s, above the Glasgow MTI's 0.1 m/s as the real
    0 m/s line is, and far below an activity's 0.5-2 m/s."""
    still = Motion(rig=pick.rig, fps=pick.fps, rotations=np.repeat(pick.rotations[:1], 300, 0),
                   positions=np.repeat(pick.positions[:1], 300, 0), activity="pick")
    j = list(pick.rig.names).index("RightHand")
    forearm = IdleMotion(spine_deg=0, neck_deg=0, shoulder_deg=0, elbow_deg=2.0, wrist_deg=0)
    preset = IdleMotion(spine_deg=0.7, neck_deg=1.0, shoulder_deg=1.7, elbow_deg=2.0, wrist_deg=2.7)
    for idle, lo, hi in ((forearm, 0.045, 0.095), (preset, 0.1, 0.3)):
        for seed in range(3):
            v = np.linalg.norm(np.diff(add_idle(still, idle, seed).positions[:, j], axis=0), axis=1) * still.fps
            assert lo < np.sqrt(np.mean(v ** 2)) < hi


def test_band_noise_has_unit_rms_and_its_power_in_the_band():
    rng = np.random.default_rng(0)
    x = band_noise(6000, 60.0, (0.3, 1.5), rng, size=4)
    np.testing.assert_allclose(np.sqrt(np.mean(x ** 2, axis=1)), 1.0, rtol=1e-12)
    f = np.fft.rfftfreq(x.shape[1], 1 / 60.0)
    power = (np.abs(np.fft.rfft(x, axis=1)) ** 2).sum(axis=0)
    # 4th-order Butterworth run forwards and backwards: 8th-order skirts, -24 dB an octave out (0.15, 3 Hz)
    inside = power[(f >= 0.2) & (f <= 2.0)].sum() / power.sum()
    assert inside > 0.95
    with pytest.raises(ValueError, match="frame rate"):
        band_noise(100, 2.0, (0.3, 1.5), rng)


def test_a_body_lying_after_a_fall_is_still():
    fall = Motion.procedural("fall", seed=0, pad_after=1.0)
    out = add_idle(fall, IdleMotion(), seed=2)
    ratio = fall.positions[:, 0, 2] / fall.rig.rest[0, 2]
    lying = ratio < IdleMotion().lying_fade * 2 / 3
    standing = ratio > IdleMotion().lying_fade
    assert lying.sum() > 30 and standing.sum() > 30
    np.testing.assert_allclose(out.positions[lying], fall.positions[lying], atol=1e-12)  # rounding only
    assert np.abs(out.positions[standing] - fall.positions[standing]).max() > 0.01


def test_same_seed_same_motion_zero_amplitude_no_change(pick):
    a, b = add_idle(pick, IdleMotion(), 5), add_idle(pick, IdleMotion(), 5)
    np.testing.assert_array_equal(a.positions, b.positions)
    assert not np.array_equal(a.positions, add_idle(pick, IdleMotion(), 6).positions)
    zero = IdleMotion(**{f"{g}_deg": 0.0 for g in GROUPS})
    np.testing.assert_array_equal(add_idle(pick, zero, 5).positions, pick.positions)


@pytest.mark.parametrize("bad", [{"band_hz": (1.5, 0.3)}, {"band_hz": (0.0, 1.0)}, {"elbow_deg": -1.0},
                                 {"wrist": 3.0}])
def test_invalid_idle_settings_are_rejected(bad):
    with pytest.raises(ValidationError):
        IdleMotion(**bad)


def test_glasgow_items_carry_idle_motion_and_it_survives_the_mti():
    """A held pose is removed by the Glasgow MTI (4th-order high-pass at 0.1 m/s): after a simulated stand-up
    the columns go below the noise. With idle motion (the measured sway and joint rotations: chest, head and
    hands at ~0.04 m/s RMS, peaks above the cut-off) a weak line near 0 m/s keeps part of them."""
    from rtchannel.dataset.items import build_motion, run_item
    from rtchannel.dataset.plan import expand, load_plan

    data_path("mocap/cmu/sit/75_17.bvh")  # the preset's real takes come through the data registry
    items = expand(load_plan("glasgow"))
    assert all(it.motion["idle"]["elbow_deg"] > 0 for it in items)
    def last_move(motion: dict) -> float:
        m = build_motion({k: v for k, v in motion.items() if k not in ("idle", "idle_seed")})
        speed = np.abs(np.diff(m.positions, axis=0)).max(axis=(1, 2)) * m.fps
        return float(m.times[1:][speed > 0].max())

    # the stand-up among the first procedural ones that ends earliest: the longest still tail
    stands = [i for i in items if i.activity == "stand" and i.motion["kind"] == "procedural"][:36:6]
    it = min(stands, key=lambda i: last_move(i.motion))
    still = {k: v for k, v in it.motion.items() if k not in ("idle", "idle_seed")}
    assert "idle" in build_motion(it.motion).params and "idle" not in build_motion(still).params
    end = last_move(it.motion)
    assert end < 4.0
    out = {}
    for name, motion in (("still", still), ("idle", it.motion)):
        arrays = run_item(dataclasses.replace(it, motion=motion))["links"]["radar1"]
        # columns whose 0.2 s window starts 0.5 s after the last movement (the MTI has rung down by then)
        late = arrays["time"] - 0.1 > end + 0.5
        out[name] = arrays["valid"][late], arrays["mean_velocity"][late]
    assert late.sum() >= 10
    assert not out["still"][0].any()
    # RMS 0.04 m/s with a Gaussian spread crosses 0.1 m/s now and then: part of the columns, never a fast line
    assert out["idle"][0].mean() > 0.25 and np.abs(out["idle"][1][out["idle"][0]]).max() < 0.3


def test_plan_draws_the_idle_factor_per_motion_and_rejects_one_out_of_range(tmp_path):
    from rtchannel.dataset.plan import expand, load_plan

    data_path("mocap/cmu/sit/75_17.bvh")  # the preset's real takes come through the data registry
    plan = load_plan("glasgow").model_dump(mode="json")
    plan["motion"]["idle_scale"] = [0.0, 1.0]
    items = expand(type(load_plan("glasgow")).model_validate(plan))
    elbow = {it.motion["key"]: it.motion["idle"]["elbow_deg"] for it in items}
    assert len(set(elbow.values())) == len(elbow) > 60  # one draw per motion, shared by its items
    assert 0.0 <= min(elbow.values()) and max(elbow.values()) <= 2.0
    plan["motion"]["idle_scale"] = [0.0, 10.0]  # wrists 27 deg: within 30; elbows 20 deg: within 30
    type(load_plan("glasgow")).model_validate(plan)
    plan["motion"]["idle"]["wrist_deg"] = 5.0  # 50 deg at the top of the range
    with pytest.raises(ValidationError, match="idle_scale 10.0 takes the idle amplitudes out of range"):
        type(load_plan("glasgow")).model_validate(plan)


def test_glasgow_idle_amplitudes_are_the_ones_measured_on_real_standing_takes():
    # the preset's idle values are scripts/idle_from_mocap.py's speed-matched amplitudes of two real standing takes
    # (CMU 77_02 and the standing part of 82_08): their simulated chest, head and hand speeds equal the real ones
    # within 25 % (one common factor on the measured angles; the remaining per-part mismatch is ~15 %), and the
    # drawn scale 0.3-3 (a decade around that mean) spans the two takes' chest-speed ratios to their mean (0.4-1.6)
    import importlib.util
    from pathlib import Path

    from rtchannel.dataset.plan import load_plan
    from thirdparty import data_path

    for take in ("mocap/cmu/stand/77_02.c3d", "mocap/cmu/walk/82_08.c3d"):
        data_path(take)
    spec = importlib.util.spec_from_file_location("idle_from_mocap", Path(__file__).resolve().parents[1] / "scripts"
                                                  / "idle_from_mocap.py")
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    plan = load_plan("glasgow")
    amps, _ = script.matched()
    assert {f"{g}_deg": v for g, v in amps.items()} == {
        k: v for k, v in plan.motion.idle.model_dump().items() if k.endswith("_deg")}
    real = []
    for path, _ in script.TAKES:
        r = script.Motion.from_file(data_path(path)).resampled(script.FPS)
        a, b = script.standing_span(r)
        real.append(script.band_speeds(r.positions[a:b]))
    sim = script.simulated_speeds(amps, seeds=4)
    for part in sim:
        assert sim[part] == pytest.approx(np.mean([x[part] for x in real]), rel=0.25)
    lo, hi = plan.motion.idle_scale
    mean = np.mean([x["chest"] for x in real])
    assert all(lo <= x["chest"] / mean <= hi for x in real)


def test_sway_tilts_the_whole_body_about_the_ankles():
    # an inverted pendulum: a point h above the ankles moves horizontally by h * theta (small angles), per axis
    # RMS h * theta_rms; the ankles stay where they are and the body keeps its shape (all joints turn together)
    pose = Motion.procedural("stand", height=1.75, seed=0).resampled(60.0)
    n = 1200
    still = Motion(rig=pose.rig, fps=60.0, rotations=np.repeat(pose.rotations[-1:], n, 0),
                   positions=np.repeat(pose.positions[-1:], n, 0), activity="stand")
    zero = {f"{g}_deg": 0.0 for g in GROUPS}
    out = add_idle(still, IdleMotion(sway_deg=0.5, **zero), seed=3)
    names = list(pose.rig.names)
    ankles = [names.index("LeftFoot"), names.index("RightFoot")]
    np.testing.assert_allclose(out.positions[:, ankles].mean(axis=1), still.positions[:, ankles].mean(axis=1),
                               atol=1e-9)
    j = names.index("Spine1")
    h = still.positions[0, j, 2] - still.positions[0, ankles, 2].mean()
    d = out.positions[:, j, :2] - still.positions[:, j, :2]
    # 0.5 deg: the small-angle error is ~1e-5 relative; the RMS of a band-limited draw is exact by construction
    np.testing.assert_allclose(np.sqrt((d ** 2).mean(axis=0)), h * np.radians(0.5), rtol=0.02)
    # rigid: every bone keeps its length and every joint turns by the same rotation
    for k, p in enumerate(pose.rig.parents):
        if p >= 0:
            np.testing.assert_allclose(np.linalg.norm(out.positions[:, k] - out.positions[:, p], axis=1),
                                       np.linalg.norm(still.positions[:, k] - still.positions[:, p], axis=1), atol=1e-9)
    turn = out.rotations[:, 0] @ np.swapaxes(still.rotations[:, 0], -1, -2)
    np.testing.assert_allclose(out.rotations[:, j], turn @ still.rotations[:, j], atol=1e-12)
    # without sway, the draws of the joints are those of before (sway noise is drawn after them)
    a = add_idle(still, IdleMotion(), seed=3)
    b = add_idle(still, IdleMotion(sway_deg=0.0), seed=3)
    np.testing.assert_array_equal(a.positions, b.positions)
