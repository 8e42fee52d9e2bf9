"""The `glasgow` dataset preset and the motion composition it relies on (back-and-forth walks, fixed clips)."""
import json

import numpy as np
import pytest

from rtchannel.motion.pose import Motion
from rtchannel.cli import main
from rtchannel.dataset.items import build_motion
from rtchannel.dataset.plan import expand, load_plan
from rtchannel.motion.compose import back_and_forth, fit_clip
from rtchannel.radar import RadarConfig
from thirdparty import data_path, registered

# Largest per-frame step [m] of any joint at 60 fps: 0.12 m = 7.2 m/s. The fastest body part in walking, the
# swinging foot, peaks at ~5 m/s (0.08 m per frame); a join without a turn (a pose switched to one facing
# the other way) would move the hands and feet by 0.3-1 m in one frame.
MAX_STEP_M = 0.12
GLASGOW_TAKES = (registered("mocap/cmu/walk/*_iclone.bvh") + registered("mocap/cmu/walk_daz/*.bvh")
                 + ["mocap/cmu/sit/75_17.bvh", "mocap/opencap/sit_stand/opencap_STS_sample_mocap.json"]
                 + registered("mocap/hdm05/pick/*") + registered("mocap/hdm05/asf/*")
                 + registered("mocap/msm2017/pick/*"))  # the preset's real takes


@pytest.fixture(scope="module")
def items():
    for take in GLASGOW_TAKES:  # the preset fetches them through the data registry
        data_path(take)
    return expand(load_plan("glasgow"))


def test_preset_expands_into_five_classes_on_the_glasgow_radar(items):
    acts = {it.activity for it in items}
    assert acts == {"walk", "sit", "stand", "pick", "fall"}
    counts = {a: sum(it.activity == a for it in items) for a in acts}
    assert len(set(counts.values())) == 1  # balanced classes
    for it in items[:: max(1, len(items) // 60)] + [it for it in items if it.motion["kind"] == "file"][:5]:
        radar = RadarConfig.model_validate(it.radar)
        wf = radar.waveform
        assert (wf.carrier_hz, wf.bandwidth_hz, wf.pri_s, wf.samples_per_chirp) == (5.8e9, 400e6, 1e-3, 128)
        assert radar.antenna.kind == "yagi" and radar.receiver.transmit_power_dbm == 18.0
        assert radar.dsp.window_chirps == 200 and radar.dsp.velocity_crop_mps == 6.0
        (link,) = radar.links
        # the radar 1.2-5 m from the activity spot (origin), walks and falls further (the preset's header),
        # antennas 0.5-1.6 m high
        lo = {"walk": 2.6, "fall": 2.8}.get(it.activity, 1.2)
        assert lo <= np.hypot(*link.tx_pos[:2]) <= 5.0 and 0.5 <= link.tx_pos[2] <= 1.6 and it.angle_deg == 0.0
        # boresight toward the person's vertical axis, aimed at the trunk (0.45-0.6 of the stature) +-8 deg, and
        # a drawn beam whose peak gain follows from it (Balanis eq. 2-27)
        b = radar.antenna.boresight_unit(link.tx_pos)
        np.testing.assert_allclose(b[:2] / np.hypot(*b[:2]), -link.tx_pos[:2] / np.hypot(*link.tx_pos[:2]),
                                   atol=1e-12)
        tilt = radar.antenna.downtilt_deg
        d, h, stature = np.hypot(*link.tx_pos[:2]), link.tx_pos[2], it.motion["height"]
        aimed = [np.degrees(np.arctan2(h - f * stature, d)) for f in (0.6, 0.45)]
        assert aimed[0] - 8.0 - 1e-9 <= tilt <= aimed[1] + 8.0 + 1e-9
        assert np.degrees(np.arcsin(b[2])) == pytest.approx(-tilt, abs=1e-9)
        az, el = radar.antenna.hpbw_az_deg, radar.antenna.hpbw_el_deg
        assert 18.0 <= min(az, el) <= 40.0 and 1.0 <= max(az, el) / min(az, el) <= 1.3 + 1e-9
        assert radar.antenna.peak_gain_dbi == pytest.approx(10 * np.log10(32400 / (az * el)), abs=1e-12)
        assert it.motion["clip_s"] == (10.0 if it.activity == "walk" else 5.0)
    # the four placements of one motion are drawn independently, and cover the ranges
    dist = np.array([np.hypot(*it.radar["links"][0]["tx"][:2]) for it in items if it.activity == "sit"])
    assert dist.min() < 1.5 and dist.max() > 4.7
    # real motion capture: walks of 13 people's takes, the two parts of 75_17, OpenCap, HDM05, MSM2017
    files = {(it.activity, it.source) for it in items if it.motion["kind"] == "file"}
    assert {("sit", "75_17.bvh"), ("stand", "75_17.bvh")} <= files
    assert sum(a == "walk" for a, _ in files) == 13
    assert {a for a, f in files if "opencap" in f} == {"sit", "stand"}
    # falls in every direction the generator has: seed mod 3 = 0 forward, 1 left, 2 right, and backward by name
    falls = [it.motion["params"] for it in items if it.activity == "fall"]
    assert {p.get("fall_direction") or ("forward", "left", "right")[p["seed"] % 3] for p in falls} == \
        {"forward", "left", "right", "backward"}
    # per-part RCS shares at 5.8 GHz on the area law (the preset's header): trunk up, shins and feet down
    for it in items[:2]:
        scale = it.gain_set["scale"]
        assert scale["chest"] == scale["pelvis"] > 1 > scale["left_shin"] > scale["left_foot"] == scale["right_toe"]
    assert {it.gain_set["name"] for it in items} == {"rcs_jitter"}
    # every item of a motion is its own deployment: four placements, none a copy of another
    placements = {}
    for it in items:
        placements.setdefault(it.motion["key"], set()).add(json.dumps(it.radar, sort_keys=True))
    assert all(len(v) == 4 for v in placements.values())
    # polarisation drawn per placement (not published for the kit): both, about half each
    pols = [it.radar["antenna"]["polarization"] for it in items]
    assert set(pols) == {"V", "H"} and 0.4 < np.mean([p == "H" for p in pols]) < 0.6
    # no campaign's onsets: every activity lies anywhere in its clip; people of 1.45-1.95 m at 0.6-1.6x pace,
    # facing the radar +-60 deg; walks of 1-4 legs, either way first, at their own speed
    assert {it.motion["clip_start_s"] for it in items} == {"anywhere"}
    assert all(1.45 <= it.motion["height"] <= 1.95 and -60 <= it.motion["heading_deg"] % 360 - 360 * (
        it.motion["heading_deg"] % 360 > 180) <= 60 or it.activity == "walk" for it in items)
    walks = [it.motion for it in items if it.activity == "walk"]
    assert {m.get("walk_legs", 1) for m in walks} == {1, 2, 3, 4} and all(m["time_scale"] == 1.0 for m in walks)
    assert 0.3 < np.mean([abs(m["heading_deg"]) > 90 for m in walks]) < 0.7
    assert all(it.motion["time_scale"] == 1.0 for it in items if it.activity == "fall")  # gravity's pace
    others = [it.motion["time_scale"] for it in items if it.activity not in ("walk", "fall")]
    assert 0.625 <= min(others) < 0.7 and 1.6 < max(others) <= 1.667
    # sit and stand get a chair on the mesh backends (the points backend is free space), in a room drawn per motion
    assert all(it.chair == "auto" for it in items)
    assert all(it.room.startswith("room:") for it in items) and len({it.room for it in items}) > 100


@pytest.mark.parametrize("activity, kind", [("walk", "procedural"), ("walk", "file"), ("stand", "file")])
def test_built_motions_have_the_clip_length_and_walks_go_back_and_forth(items, activity, kind):
    # a walk of >= 3 legs that fit its 10 s clip (a 0.3 m/s walk of 3 m fills it with one leg)
    it = next(i for i in items if i.activity == activity and i.motion["kind"] == kind and (activity != "walk" or (
        i.motion.get("walk_legs", 1) >= 3 and i.motion.get("params", {}).get("speed", 1.3) >= 1.0
        and i.motion.get("params", {}).get("distance", 2.0) <= 2.5)))
    m = build_motion(it.motion)
    assert m.duration == pytest.approx(it.motion["clip_s"], abs=0.5 / m.fps)
    assert np.abs(np.diff(m.positions, axis=0)).max() <= MAX_STEP_M
    if activity == "walk":
        # radial (x) hips velocity over 0.5 s steps: toward the radar (+x), away, toward again, or the other
        # way round (faced +-60 deg off the radar line, the walk's x component is at least half of it)
        x = m.positions[:: int(m.fps // 2), 0, 0]
        signs = np.sign(np.diff(x)[np.abs(np.diff(x)) > 0.1])  # moving > 0.2 m/s along x
        runs = signs[np.r_[True, signs[1:] != signs[:-1]]]
        assert len(runs) >= 3 and list(runs[:3]) == [runs[0], -runs[0], runs[0]]


def test_every_shipped_walk_take_builds_a_back_and_forth_clip(items):
    """Each CMU walk (one item per take) imports, retargets and fills its 10 s clip without a jump."""
    seen = set()
    for it in items:
        if it.activity != "walk" or it.motion["kind"] != "file" or it.source in seen:
            continue
        seen.add(it.source)
        m = build_motion(it.motion)
        assert m.duration == pytest.approx(10.0, abs=0.5 / m.fps), it.source
        assert np.isfinite(m.positions).all() and np.abs(np.diff(m.positions, axis=0)).max() <= MAX_STEP_M, it.source
    assert len(seen) == 13


def test_back_and_forth_returns_along_its_path_and_fit_clip_holds_poses():
    leg = Motion.procedural("walk", speed=1.2, distance=2.0, pad_before=0.1, pad_after=0.1, seed=1)
    two = back_and_forth(leg, 2, 0.8)
    turn_frames = two.n_frames - 2 * leg.n_frames
    assert turn_frames == round(0.8 * leg.fps) - 1
    # the second leg ends where the first began (turned 180 deg about the path's midpoint), within the
    # few cm the procedural gait's start and end feet placements differ by
    np.testing.assert_allclose(two.positions[-1, 0, :2], leg.positions[0, 0, :2], atol=0.05)
    assert np.abs(np.diff(two.positions, axis=0)).max() <= MAX_STEP_M
    assert back_and_forth(leg, 1, 0.8) is leg
    short = fit_clip(leg, leg.duration + 2.0, lead=0.25)
    assert short.n_frames == round((leg.duration + 2.0) * leg.fps) + 1
    before = int(round(0.25 * (short.n_frames - leg.n_frames)))
    np.testing.assert_array_equal(short.positions[:before + 1], np.broadcast_to(leg.positions[0], (before + 1,
                                                                                                    *leg.positions.shape[1:])))
    np.testing.assert_array_equal(short.positions[-1], leg.positions[-1])
    cut = fit_clip(leg, 1.0)
    assert cut.n_frames == round(leg.fps) + 1
    with pytest.raises(ValueError):
        fit_clip(leg, 1.0, lead=2.0)
    # a recording begun before the motion or inside it, but never one that misses it
    late = fit_clip(leg, 1.0, start_s=-0.5)
    np.testing.assert_array_equal(late.positions, leg.positions[30:91])
    for start in (-leg.duration, 1.0):
        with pytest.raises(ValueError, match="leaves nothing"):
            fit_clip(leg, 1.0, start_s=start)


def test_cli_radar_preset_errors_are_one_line(tmp_path, capsys):
    assert main(["simulate", "--radar", "glasgow", "--radar-distance", "6", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "distance_m" in err
    assert main(["simulate", "--radar-height", "1", "--out", str(tmp_path)]) == 2
    assert "--radar glasgow only" in capsys.readouterr().err


def test_through_image_keeps_what_the_image_shows_and_drops_what_is_below_its_span():
    """Columns 10 dB below the strongest one keep their peak velocity (within one image row, 12 m/s / 317 =
    0.038 m/s, plus half a signature bin); columns 50 dB below it are under the 40 dB span: empty."""
    from processing.dsp.signatures import Signature
    from processing.realdata.spectrogram_image import glasgow_layout
    from processing.realdata.spectrogram_image_writer import through_image

    v = np.linspace(-6, 6, 373)
    t = np.linspace(0.1, 4.9, 200)
    v_true = np.where(t < 2.5, 1.0, -2.0)
    p = np.exp(-0.5 * ((v[:, None] - v_true[None, :]) / 0.1) ** 2)
    p /= p.sum(axis=0)
    power = np.where((t > 1.0) & (t < 4.0), 1.0, np.where(t <= 1.0, 0.1, 1e-5))  # 0, -10, -50 dB
    sig = Signature(time=t, velocity=v, p_vt=p, mean_velocity=np.zeros_like(t), range=np.zeros(0),
                    range_distribution=np.zeros((0, t.size)), valid=np.ones(t.size, bool), power=power)
    out = through_image(sig, glasgow_layout(5.0))
    assert out.p_vt.shape == (317, 383) and out.time[0] < 0.02 and out.time[-1] > 4.98
    shown = out.time < 4.0  # stretched over 0-5 s: the -50 dB part starts at 4.0 + 0.1 * (5 / 4.8) s
    peaks = out.velocity[out.p_vt.argmax(axis=0)]
    truth = np.where(out.time < 2.5, 1.0, -2.0)
    assert np.all(np.abs(peaks[shown] - truth[shown]) <= 12 / 317 + 0.016)
    assert not out.valid[out.time > 4.25].any() and out.p_vt[:, out.time > 4.25].sum() == 0
    assert np.isfinite(out.p_vt).all()


def test_image_layout_needs_glasgow_clip_lengths(tmp_path):
    import yaml

    from rtchannel.dataset.plan import PRESETS_DIR

    plan = yaml.safe_load((PRESETS_DIR / "glasgow.yaml").read_text())
    plan["motion"]["sources"] = [s for s in plan["motion"]["sources"] if "procedural" in s]
    plan["motion"]["clip_s"] = {"walk": 10.0, "*": 6.0}
    p = tmp_path / "g.yaml"
    p.write_text(yaml.safe_dump(plan))
    with pytest.raises(ValueError, match="clip_s must give .* a length of 5 or 10 s"):
        load_plan(p)
    plan["motion"]["clip_s"] = {"walk": 10.0, "*": 5.0}
    p.write_text(yaml.safe_dump(plan))
    assert load_plan(p).storage.image_layout == "glasgow"


def test_stored_item_is_on_the_glasgow_image_grid(items):
    """With storage.image_layout glasgow an item holds what a 5 s Glasgow image holds: 317 velocity rows
    between the frame rows at +-6 m/s (row 36 and 354: 12 m/s / 318 = 0.0377 m/s per row, so the outer row
    centres are at +-(6 - 0.0377) m/s), 383 columns over 0-5 s, no range data, finite p(v,t)."""
    from rtchannel.dataset.items import run_item

    it = next(i for i in items if i.activity == "pick")
    arrays = run_item(it)["links"]["radar1"]
    v, t = arrays["velocity"], arrays["time"]
    assert arrays["p_vt"].shape == (317, 383) and arrays["range"].size == 0
    assert v[0] == pytest.approx(-6 + 12 / 318, abs=1e-4) and v[-1] == pytest.approx(6 - 12 / 318, abs=1e-4)
    assert 0 < t[0] < 0.02 and 4.98 < t[-1] < 5.0
    assert np.isfinite(arrays["p_vt"]).all() and arrays["valid"].any()


@pytest.mark.parametrize("legs", [2, 3, 4])
def test_back_and_forth_walks_are_centred_on_the_activity_spot(items, legs):
    """With an even number of legs the walk ends where it began; it must still straddle the origin (the
    radar stands 2.5 m from it: a 2.4 m leg starting at the origin would walk into it)."""
    it = next(i for i in items if i.activity == "walk" and i.motion["kind"] == "procedural")
    # without the clip (it may cut a long walk anywhere): the whole walk is what is centred
    m = build_motion({**it.motion, "walk_legs": legs, "params": {**it.motion["params"], "distance": 2.4},
                      "clip_s": None})
    hips = m.positions[:, 0, :2]
    centre = 0.5 * (hips.min(axis=0) + hips.max(axis=0))
    # the hips' extent is centred within 1 cm (float rounding of the turns); it spans ~2.4 m along the walk
    np.testing.assert_allclose(centre, 0.0, atol=0.01)
    assert np.hypot(*np.ptp(hips, axis=0)) > 2.0


def test_every_motion_has_its_own_body_and_the_built_motion_drives_it(items):
    # body shapes drawn per motion over BodyShapeRanges' documented defaults (sex 50/50, 18-98 years, BMI 17-40)
    bodies = {it.motion["key"]: it.motion["body"] for it in items}
    assert len({json.dumps(b, sort_keys=True) for b in bodies.values()}) == len(bodies)
    bmi = np.array([b["bmi"] for b in bodies.values()])
    sex = np.array([b["sex"] for b in bodies.values()])
    assert 17.0 <= bmi.min() < 19.0 and 38.0 < bmi.max() <= 40.0 and 0.35 < sex.mean() < 0.65
    assert all(18.0 <= b["age_years"] <= 98.0 for b in bodies.values())
    it = next(i for i in items if i.activity == "sit" and i.motion["kind"] == "procedural")
    m = build_motion(it.motion)
    assert m.rig.shape is not None and m.params["body_shape"]["bmi"] == pytest.approx(it.motion["body"]["bmi"])
    assert m.rig.height == pytest.approx(it.motion["height"])
