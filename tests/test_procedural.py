"""Procedural motion generators: shapes, biomechanical ranges, determinism and parameter validation."""
import numpy as np
import pytest
from pydantic import ValidationError

from rtchannel.motion.procedural import ACTIVITIES, ProceduralParams, generate
from rtchannel.motion.pose import Motion

# Movement is "on" while some joint is > 1 cm away from the first (last) pose: stricter thresholds would
# cut the slow tails of the minimum-jerk profiles, looser ones would count numerical noise.
MOVE_EPS_M = 0.01
# Movement span [s] accepted per activity (fall: onset to lying still; the other ranges are the brief's).
SPAN_S = {"fall": (0.8, 2.0), "sit": (1.5, 3.0), "stand": (1.5, 3.0), "pick": (2.0, 4.0)}


def joint(m: Motion, name: str) -> np.ndarray:
    return m.positions[:, m.rig.index(name)]


def movement_span(m: Motion) -> tuple[float, float]:
    """(start, end) times [s] of the movement between the quiet first and last poses."""
    from_first = np.linalg.norm(m.positions - m.positions[0], axis=-1).max(axis=1)
    from_last = np.linalg.norm(m.positions - m.positions[-1], axis=-1).max(axis=1)
    start = np.argmax(from_first > MOVE_EPS_M)
    end = len(from_last) - 1 - np.argmax(from_last[::-1] > MOVE_EPS_M)
    return m.times[start], m.times[end]


def peak_speed(m: Motion, name: str) -> float:
    return float(np.linalg.norm(np.diff(joint(m, name), axis=0), axis=-1).max() * m.fps)


def trunk_lean_deg(m: Motion) -> np.ndarray:
    """Forward lean of the hips->neck line from vertical [deg] (heading 0)."""
    d = joint(m, "Neck") - joint(m, "Hips")
    return np.degrees(np.arctan2(d[:, 0], d[:, 2]))


def foot_flat_times(m: Motion, side: str) -> np.ndarray:
    """Times [s] at which the toe joint comes to rest on the floor (one per stance)."""
    toe = joint(m, f"{side}ToeBase")
    speed = np.linalg.norm(np.gradient(toe[:, :2], m.times, axis=0), axis=1)
    still = speed < 0.05
    return m.times[1:][still[1:] & ~still[:-1]]


@pytest.mark.parametrize("activity", ACTIVITIES)
def test_every_activity_is_finite_grounded_and_timed(activity):
    m = generate(activity, fps=50.0)
    assert m.activity == activity and m.fps == 50.0
    assert np.isfinite(m.positions).all() and np.isfinite(m.rotations).all()
    assert m.positions[..., 2].min() > -0.02
    rot = m.rotations.reshape(-1, 3, 3)
    assert np.allclose(rot @ rot.transpose(0, 2, 1), np.eye(3), atol=1e-9)
    assert m.params["activity"] == activity and m.params["fps"] == 50.0
    start, end = movement_span(m)
    assert start >= 0.5 - 0.1  # pad_before of quiet standing (heel rise of gait starts right at its end)
    if activity == "walk":
        assert 4.0 / 1.3 < end - start < 4.0 / 1.3 + 2.0
    else:
        lo, hi = SPAN_S[activity]
        assert lo <= end - start <= hi
    # Velocities continuous: no frame-to-frame jump of any joint faster than 10 m/s.
    assert max(peak_speed(m, n) for n in m.rig.names) < 10.0


@pytest.mark.parametrize("height", [1.2, 2.2])
@pytest.mark.parametrize("activity", ACTIVITIES)
def test_heights_scale_and_stay_above_floor(activity, height):
    m = generate(activity, height=height, seed=1)
    assert m.rig.height == height
    assert m.positions[..., 2].min() > -0.02
    upright = 0 if activity != "stand" else -1
    assert joint(m, "Head")[upright, 2] > 0.85 * height


@pytest.mark.parametrize("speed", [0.8, 1.3, 1.8])
def test_walk_mean_speed_and_distance(speed):
    m = generate("walk", speed=speed, distance=10.0)
    hips = joint(m, "Hips")
    # Whole gait cycles in the steady part: left foot-flat to left foot-flat, skipping the start/stop.
    flats = foot_flat_times(m, "Left")
    i, j = (np.searchsorted(m.times, flats[k]) for k in (1, -3))
    mean_speed = (hips[j, 0] - hips[i, 0]) / (m.times[j] - m.times[i])
    assert mean_speed == pytest.approx(speed, rel=0.03)
    assert np.linalg.norm(hips[-1, :2] - hips[0, :2]) == pytest.approx(10.0, rel=0.05)


def test_walk_cadence_and_pelvis_bounce():
    m = generate("walk", distance=10.0)
    flats = np.sort(np.concatenate([foot_flat_times(m, "Left"), foot_flat_times(m, "Right")]))
    steps = np.diff(flats[2:-3])
    assert 1.6 <= 1.0 / steps.mean() <= 2.1  # steps per second
    mid = slice(len(m.times) // 3, 2 * len(m.times) // 3)
    bounce = np.ptp(joint(m, "Hips")[mid, 2])
    assert 0.02 <= bounce <= 0.06


def test_walk_follows_heading_and_start():
    m = generate("walk", heading_deg=120.0, start=(2.0, -1.0), distance=3.0)
    hips = joint(m, "Hips")
    assert hips[0, :2] == pytest.approx([2.0, -1.0], abs=1e-9)
    d = hips[-1, :2] - hips[0, :2]
    assert np.degrees(np.arctan2(d[1], d[0])) == pytest.approx(120.0, abs=1.0)
    assert np.linalg.norm(d) == pytest.approx(3.0, rel=0.05)


def test_walk_stance_foot_is_planted_and_arms_swing_against_legs():
    m = generate("walk", distance=8.0)
    mid = slice(len(m.times) // 4, 3 * len(m.times) // 4)
    for side in ("Left", "Right"):
        toe = joint(m, f"{side}ToeBase")
        on_floor = toe[:, 2] < toe[0, 2] + 1e-4  # toes on the floor (they leave it smoothly at toe-off)
        step = np.linalg.norm(np.diff(toe[:, :2], axis=0), axis=1) * m.fps
        assert step[on_floor[1:] & on_floor[:-1]].max() < 0.05  # m/s: the toes do not skid
    hips = joint(m, "Hips")[mid, 0]
    hand = joint(m, "LeftHand")[mid, 0] - hips
    ankle = joint(m, "LeftFoot")[mid, 0] - hips
    assert np.corrcoef(hand, ankle)[0, 1] < -0.5
    assert np.ptp(hand) > 0.15  # visible arm swing


@pytest.mark.parametrize("seed, direction", [(0, None), (1, None), (2, None), (0, "backward"), (4, "backward")])
def test_fall_drops_the_head_fast_and_ends_lying(seed, direction):  # forward, left, right and backward falls
    m = generate("fall", seed=seed, fall_direction=direction)
    head = joint(m, "Head")[:, 2]
    assert head[0] > 1.4 and head[-1] < 0.4
    assert joint(m, "Hips")[-1, 2] < 0.35
    drop = head[0] - head[-1]
    t90 = m.times[np.argmax(head < head[-1] + 0.9 * drop)]
    t10 = m.times[np.argmax(head < head[-1] + 0.1 * drop)]
    assert 0.5 <= t10 - t90 <= 1.5
    assert peak_speed(m, "Head") > 2 * peak_speed(generate("sit", seed=seed), "Head")


def test_fall_direction_depends_on_seed():
    ends = [joint(generate("fall", seed=s), "Head")[-1, :2] for s in (0, 1, 2)]
    assert ends[0][0] > 1.0  # forward along +x
    assert ends[1][1] > 0.8 and ends[2][1] < -0.8  # to the left (+y) and to the right
    # a named direction overrides the seed's; None keeps it (earlier datasets' seeds make the same falls)
    np.testing.assert_array_equal(generate("fall", seed=1, fall_direction="left").positions,
                                  generate("fall", seed=1).positions)
    assert joint(generate("fall", seed=1, fall_direction="forward"), "Head")[-1, 0] > 1.0


def test_backward_fall_squats_onto_the_buttocks_then_lies_supine():
    m = generate("fall", seed=3, fall_direction="backward", pad_before=0.0, pad_after=0.0)
    hips, head, toes = joint(m, "Hips"), joint(m, "Head"), joint(m, "LeftToeBase")
    # the buttocks land behind the feet (-x, the body faces +x), then the trunk rolls back: the hips are low
    # while the head is still high; until then the toes stay where they stood, afterwards the legs slide out
    sitting = np.flatnonzero(hips[:, 2] < 0.3)[0]
    assert head[sitting, 2] > 0.6 and -0.5 < hips[sitting, 0] < -0.15
    assert np.abs(toes[:sitting, :2] - toes[0, :2]).max() < 0.05
    np.testing.assert_allclose(hips[sitting + 5:, 0], hips[-1, 0], atol=0.03)  # the pelvis stays put
    assert toes[-1, 0] > toes[0, 0] + 0.3
    # supine: pelvis and head near the floor, the head a trunk's length behind the pelvis
    assert hips[-1, 2] < 0.25 and head[-1, 2] < 0.3
    assert head[-1, 0] < hips[-1, 0] - 0.5 and abs(head[-1, 1]) < 0.1
    # no body part below the floor (joint centres at least a few cm up, the skin radius)
    assert m.positions[..., 2].min() > 0.0


@pytest.mark.parametrize("activity", ["sit", "stand"])
def test_sit_and_stand_move_between_standing_and_seat(activity):
    m = generate(activity)
    hips = joint(m, "Hips")[:, 2]
    seat = 0.45
    seated, upright = (hips[-1], hips[0]) if activity == "sit" else (hips[0], hips[-1])
    assert upright > 0.85
    assert seat < seated < seat + 0.15  # hip joint centre ~0.1 m above the seat surface
    assert trunk_lean_deg(m).max() > 25.0
    start, end = movement_span(m)
    assert 1.5 <= end - start <= 3.0


def test_stand_leans_forward_before_the_seat_off():
    m = generate("stand")
    hips = joint(m, "Hips")[:, 2]
    seat_off = np.argmax(hips > hips[0] + 0.02)
    assert trunk_lean_deg(m)[seat_off] > 20.0


def test_seat_height_scales_with_body_height():
    tall, nominal = (joint(generate("sit", height=h), "Hips")[-1, 2] for h in (2.1, 1.75))
    assert tall == pytest.approx(nominal * 2.1 / 1.75, rel=0.02)


def test_pick_reaches_the_floor_and_returns():
    for seed in range(4):
        m = generate("pick", seed=seed)
        hand = min(joint(m, n)[:, 2].min() for n in ("RightHand", "LeftHand"))
        assert hand < 0.2
        assert np.linalg.norm(m.positions[-1] - m.positions[0], axis=-1).max() < 1e-6
        start, end = movement_span(m)
        assert 2.0 <= end - start <= 4.0


@pytest.mark.parametrize("activity", ACTIVITIES)
def test_heading_and_start_apply_to_every_activity(activity):
    a = generate(activity, seed=1)
    b = generate(activity, seed=1, heading_deg=90.0, start=(1.0, 2.0))
    assert joint(a, "Hips")[0, :2] == pytest.approx([0.0, 0.0], abs=1e-9)
    rotated = a.positions[..., [1, 0, 2]] * np.array([-1.0, 1.0, 1.0]) + np.array([1.0, 2.0, 0.0])
    assert np.allclose(b.positions, rotated, atol=1e-9)


def test_seed_determinism():
    for activity in ACTIVITIES:
        a, b, c = generate(activity, seed=3), generate(activity, seed=3), generate(activity, seed=4)
        assert np.array_equal(a.positions, b.positions) and np.array_equal(a.rotations, b.rotations)
        assert a.positions.shape != c.positions.shape or not np.allclose(a.positions, c.positions)


def test_params_object_and_overrides():
    p = ProceduralParams(height=1.6, fps=30.0)
    m = generate("sit", p, seed=2)
    assert m.rig.height == 1.6 and m.fps == 30.0 and m.params["seed"] == 2
    assert generate("walk", duration=2.0).params["duration"] == 2.0


@pytest.mark.parametrize("bad, field", [({"speed": -1.0}, "speed"), ({"height": 3.0}, "height"),
                                        ({"colour": "red"}, "colour"), ({"fps": float("nan")}, "fps"),
                                        ({"speed": 1.3, "step_length": 1.2}, "step_length")])
def test_bad_params_raise_validation_errors_naming_the_field(bad, field):
    with pytest.raises(ValidationError, match=field):
        ProceduralParams(**bad)
    with pytest.raises(ValidationError, match=field):
        generate("walk", **bad)


def test_unknown_activity_and_bad_durations():
    with pytest.raises(ValueError, match="fall, walk, stand, sit, pick"):
        generate("dance")
    with pytest.raises(ValueError, match="duration"):
        generate("sit", duration=0.2)
    with pytest.raises(ValueError, match="distance"):
        generate("walk", distance=4.0, duration=10.0)


@pytest.mark.parametrize("hold", [0.0, 0.13, 0.3])
def test_pick_holds_the_bottom_for_its_hold_fraction(hold):
    """The pick's depth follows w(u) = S(u / t_down) - S((u - t_down - hold) / (1 - t_down - hold)) with S a
    minimum-jerk step, so w = 1 (the hips at their lowest) for exactly hold x duration; minimum jerk leaves
    1 - S(x) ~ 10 (1 - x)^3 near the ends, under 1e-6 for the last ~0.5 % of each edge (< 1 frame here).
    The hips' height is linear in w at the bottom, so the frames within 0.1 um of its minimum are the hold."""
    duration, fps = 2.8, 60.0
    m = generate("pick", seed=1, duration=duration, fps=fps, hold_fraction=hold)
    z = m.positions[:, 0, 2]
    frames = int(np.sum(z - z.min() < 1e-7))
    assert frames == pytest.approx(hold * duration * fps + 1, abs=2)
