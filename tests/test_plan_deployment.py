"""Deployment randomisation in dataset plans (issue 27): radar distance and height drawn per item, walk legs,
direction and pace, activities anywhere in their clip; plans without these fields keep their items."""
import copy

import numpy as np
import pytest
from pydantic import ValidationError

from rtchannel.dataset.items import build_motion
from rtchannel.dataset.plan import Plan, expand
from rtchannel.motion.compose import clip_start_anywhere, fit_clip
from rtchannel.motion.procedural import generate

BASE = {"name": "d", "seed": 5,
        "motion": {"sources": [{"procedural": "walk", "variants": 6, "params": {"speed": [0.6, 1.2],
                                                                                "distance": [1.5, 2.0]}},
                               {"procedural": "sit", "variants": 6}],
                   "heights": [[1.5, 1.9]], "time_scales": [[0.7, 1.4]], "headings_deg": [[-30, 30]],
                   "clip_s": {"walk": 10.0, "*": 5.0}},
        "physical": {"radar": "glasgow", "angles_deg": [0], "downtilt_deg": [0, 10],
                     "link_sets": [{"name": "a", "links": [{"name": "radar1", "tx": [0.0, -3.0, 1.0]}]},
                                   {"name": "b", "links": [{"name": "radar1", "tx": [0.0, -3.0, 1.0]}]}]}}


def _plan(**updates) -> Plan:
    data = copy.deepcopy(BASE)
    for layer, fields in updates.items():
        data[layer].update(fields)
    return Plan.model_validate(data)


def _distance(it) -> float:
    return float(np.hypot(*it.radar["links"][0]["tx"][:2]))


def test_radar_distance_and_height_are_drawn_per_item_along_the_link_azimuth():
    items = expand(_plan(physical={"distance_m": {"walk": [3.0, 4.0], "*": [1.0, 2.0]}, "height_m": [0.5, 1.6]}))
    for it in items:
        x, y, z = it.radar["links"][0]["tx"]
        lo, hi = (3.0, 4.0) if it.activity == "walk" else (1.0, 2.0)
        assert lo <= _distance(it) <= hi and 0.5 <= z <= 1.6
        assert abs(x) < 1e-12 and y < 0  # the link set's azimuth (-y) is kept
        # the kit's boresight follows the drawn height (horizontal before the tilt)
        assert it.radar["antenna"]["downtilt_deg"] is not None
    # both placements of a motion differ (own draws), and the draws span their ranges
    by_motion = {}
    for it in items:
        by_motion.setdefault(it.motion["key"], set()).add(round(_distance(it), 9))
    assert all(len(v) == 2 for v in by_motion.values())
    sits = [_distance(it) for it in items if it.activity == "sit"]
    assert max(sits) - min(sits) > 0.5


def test_placement_draws_leave_every_other_draw_unchanged():
    plain, placed = expand(_plan()), expand(_plan(physical={"distance_m": [1.0, 5.0], "height_m": [0.5, 1.6]}))
    assert [it.motion for it in plain] == [it.motion for it in placed]
    tilt = [[it.radar["antenna"]["downtilt_deg"] for it in items] for items in (plain, placed)]
    assert tilt[0] == tilt[1]
    assert [it.seed for it in plain] == [it.seed for it in placed]
    assert {tuple(it.radar["links"][0]["tx"]) for it in plain} == {(0.0, -3.0, 1.0)}


def test_walk_legs_range_direction_and_own_pace():
    items = expand(_plan(motion={"walk_legs": [1, 4], "walk_reverse": 1.0, "unscaled": ["walk"]}))
    walks = {it.motion["key"]: it.motion for it in items if it.activity == "walk"}
    legs = [m.get("walk_legs", 1) for m in walks.values()]
    assert set(legs) <= {1, 2, 3, 4} and len(set(legs)) >= 2
    # walk_reverse 1: every walk turned 180 deg (headings drawn in +-30 deg, so now 150-210 deg)
    assert all(150 <= m["heading_deg"] <= 210 for m in walks.values())
    assert all(m["time_scale"] == 1.0 for m in walks.values())
    sits = [it.motion for it in items if it.activity == "sit"]
    assert all(-30 <= m["heading_deg"] <= 30 and m["time_scale"] != 1.0 for m in sits)
    plain = expand(_plan(motion={"walk_legs": 1}))
    assert [it.motion["heading_deg"] for it in plain if it.activity == "sit"] == [m["heading_deg"] for m in sits]


@pytest.mark.parametrize("bad", [{"walk_legs": [3, 2]}, {"walk_legs": [0, 2]}, {"walk_legs": 21},
                                 {"walk_reverse": 1.5}, {"clip_start_s": "somewhere"}, {"clip_overhang": 0.95}])
def test_bad_motion_fields_are_named(bad):
    with pytest.raises(ValidationError, match=next(iter(bad))):
        _plan(motion=bad)


@pytest.mark.parametrize("bad", [{"distance_m": [0.1, 2]}, {"distance_m": {"jump": [1, 2]}}, {"height_m": 9}])
def test_bad_placement_fields_are_named(bad):
    with pytest.raises(ValidationError, match=next(iter(bad))):
        _plan(physical=bad)


def test_clip_start_anywhere_spans_starts_that_keep_the_motion_mostly_inside():
    # a 2 s motion in a 5 s clip with 30 % allowed outside: first frame from -0.6 s to 5 - 1.4 = 3.6 s
    assert clip_start_anywhere(2.0, 5.0, 0.0, 0.3) == pytest.approx(-0.6)
    assert clip_start_anywhere(2.0, 5.0, 1.0, 0.3) == pytest.approx(3.6)
    assert clip_start_anywhere(2.0, 5.0, 0.5, 0.0) == pytest.approx(1.5)  # centred when nothing may stick out
    # a 12 s motion in a 10 s clip: the recording always cuts it; from 10 - 12 * 0.7 = 1.6 s to -3.6 s
    assert clip_start_anywhere(12.0, 10.0, 0.0, 0.3) == pytest.approx(-3.6)
    assert clip_start_anywhere(12.0, 10.0, 1.0, 0.3) == pytest.approx(1.6)
    # fit_clip accepts every start it returns: the motion is never missed entirely
    m = generate("sit", duration=2.0, pad_before=0.0, pad_after=0.0)
    for u in (0.0, 0.37, 1.0):
        s = clip_start_anywhere(m.duration, 5.0, u, 0.9)
        assert fit_clip(m, 5.0, start_s=s).n_frames == 301
    with pytest.raises(ValueError):
        clip_start_anywhere(2.0, 5.0, 1.5, 0.3)


def test_anywhere_items_build_clips_that_begin_or_end_inside_the_activity():
    items = expand(_plan(motion={"clip_start_s": "anywhere", "clip_overhang": 0.3}))
    starts = []
    for it in [i for i in items if i.activity == "sit"][::2]:
        m = build_motion(it.motion)
        assert m.duration == pytest.approx(5.0, abs=0.5 / m.fps) and np.isfinite(m.positions).all()
        starts.append(m.params["clip"]["start_s"])
    assert min(starts) < 0 < 0.8 < max(starts)  # spread over the clip (some begin inside), not one onset


def test_slow_walks_cover_their_distance_and_arm_swing_scales_the_swing():
    """A 0.3 m/s walk (frail gait) is generated and covers exactly its distance; arm_swing 0.3 cuts the shoulder's
    swing angle to 0.3x; the hand's fore-aft travel relative to the hips also carries the trunk's counter-rotation
    (unchanged), so it drops to about half (measured 0.50)."""
    from rtchannel.motion.pose import avatar_rig

    def wrist_swing(m):
        i = avatar_rig().index("LeftHand")
        rel = m.positions[:, i, 0] - m.positions[:, 0, 0]
        mid = slice(m.n_frames // 3, 2 * m.n_frames // 3)
        return float(np.ptp(rel[mid]))

    slow = generate("walk", speed=0.3, distance=1.5, seed=2)
    assert np.isfinite(slow.positions).all()
    hips = slow.positions[:, 0, 0]
    assert hips[-1] - hips[0] == pytest.approx(1.5, abs=0.01)
    full, weak = (generate("walk", speed=1.0, distance=2.0, seed=2, arm_swing=a) for a in (1.0, 0.3))
    assert 0.3 * wrist_swing(full) < wrist_swing(weak) < 0.65 * wrist_swing(full)


def test_one_room_per_motion_holds_the_person_and_every_antenna():
    from rtchannel.scene.rooms import room_bounds

    items = expand(_plan(physical={"distance_m": [1.0, 5.0], "height_m": [0.5, 1.6],
                                   "room": {"margin_m": [0.3, 2.0], "person_clear_m": 2.0}}))
    rooms = {}
    for it in items:
        rooms.setdefault(it.motion["key"], set()).add(it.room)
        x0, x1, y0, y1, h = room_bounds(it.room)
        x, y, z = it.radar["links"][0]["tx"]
        # every antenna at least the smallest margin (0.3 m, less the name's 1 cm rounding) inside every wall
        assert min(x - x0, x1 - x, y - y0, y1 - y) >= 0.29 and h >= z + 0.5
        assert min(-x0, x1, -y0, y1) >= 2.0 + 0.29  # the person's free floor
    assert all(len(r) == 1 for r in rooms.values())  # the items of a motion share one mesh-backend run
    assert len({next(iter(r)) for r in rooms.values()}) == len(rooms)  # rooms differ between motions
    assert all(it.room is None for it in expand(_plan()))


def test_an_item_in_its_drawn_room_simulates_on_the_mesh_backend():
    """The facets backend traces the body in the item's generated room (walls at the drawn bounds)."""
    from rtchannel.dataset.items import run_item

    plan = _plan(physical={"distance_m": [2.0, 2.5], "room": {"margin_m": 0.5, "person_clear_m": 2.0,
                                                               "height_m": 2.5}})
    it = next(i for i in expand(plan.model_copy(update={"backend": "facets",
                                                         "backend_options": {"lod": "2k"}})) if i.activity == "sit")
    rec = run_item(it)
    assert rec["entry"]["params"]["room"] == it.room and it.room.startswith("room:")
    assert np.isfinite(rec["links"]["radar1"]["p_vt"]).all()


def test_aimed_radar_tilts_at_the_trunk_from_its_height_distance_and_the_stature():
    # paper: antenna 1.5 m high, 3 m away, person 1.8 m, aim at 0.5 h = 0.9 m: tilt = atan(0.6 / 3) = 11.31 deg
    # below horizontal; an aiming error of +2 deg adds to it; a radar at 0.5 m then looks up, atan(-0.4 / 3)
    from rtchannel.dataset.plan_physical import AimDraw

    rng = np.random.default_rng(0)
    assert AimDraw(height_frac=0.5, error_deg=0.0).downtilt_deg((3.0, 0.0, 1.5), 1.8, rng) == pytest.approx(
        np.degrees(np.arctan(0.2)), abs=1e-12)
    assert AimDraw(height_frac=0.5, error_deg=2.0).downtilt_deg((0.0, -3.0, 1.5), 1.8, rng) == pytest.approx(
        np.degrees(np.arctan(0.2)) + 2.0, abs=1e-12)
    assert AimDraw(height_frac=0.5, error_deg=0.0).downtilt_deg((3.0, 0.0, 0.5), 1.8, rng) == pytest.approx(
        -np.degrees(np.arctan(0.4 / 3)), abs=1e-12)
    # in a plan: every item's tilt lies between the aim at the highest and the lowest trunk point, +- the error
    items = expand(_plan(physical={"downtilt_deg": None, "aim": {"height_frac": [0.45, 0.6], "error_deg": [-8, 8]},
                                   "distance_m": [1.2, 5.0], "height_m": [0.5, 1.6]}))
    tilts = []
    for it in items:
        x, y, z = it.radar["links"][0]["tx"]
        d, h = np.hypot(x, y), it.motion["height"]
        lo, hi = (np.degrees(np.arctan2(z - f * h, d)) for f in (0.6, 0.45))
        tilt = it.radar["antenna"]["downtilt_deg"]
        assert lo - 8 - 1e-9 <= tilt <= hi + 8 + 1e-9
        tilts.append(tilt - np.degrees(np.arctan2(z - 0.525 * h, d)))
    assert -8 < min(tilts) < -5 and 5 < max(tilts) < 8  # the error is drawn across its range


def test_drawn_beam_takes_its_peak_gain_from_the_beamwidths():
    # Balanis eq. 2-27: G = 32400 / (HPBW_az HPBW_el) [deg^2]; 24 x 24 deg -> 56.25 = 17.50 dBi (the kit's quoted 17)
    from processing.radar.antenna import practical_gain_dbi
    from rtchannel.dataset.plan_physical import BeamDraw

    assert practical_gain_dbi(24, 24) == pytest.approx(10 * np.log10(56.25), abs=1e-12)
    b = BeamDraw(e_plane_deg=20.0, h_over_e=1.25).draw(np.random.default_rng(0))  # vertical elements: E = elevation
    assert (b["hpbw_el_deg"], b["hpbw_az_deg"]) == (20.0, 25.0)
    assert b["peak_gain_dbi"] == pytest.approx(10 * np.log10(32400 / 500), abs=1e-12)
    h = BeamDraw(e_plane_deg=20.0, h_over_e=1.25).draw(np.random.default_rng(0), polarization="H")
    assert (h["hpbw_el_deg"], h["hpbw_az_deg"]) == (25.0, 20.0)
    items = expand(_plan(physical={"hpbw_el_deg": None, "beam": {"e_plane_deg": [18, 40], "h_over_e": [1.0, 1.3]}}))
    gains = [it.radar["antenna"]["peak_gain_dbi"] for it in items]
    # the widest beam (40 x 52 deg) gives 11.9 dBi, the narrowest (18 x 18) 20.0 dBi: never a narrow beam's gain
    # on a wide beam
    assert 11.9 <= min(gains) and max(gains) <= 20.01 and max(gains) - min(gains) > 3


@pytest.mark.parametrize("bad", [{"aim": {"height_frac": 0.5}},  # with downtilt_deg of BASE
                                 {"downtilt_deg": None, "aim": {"error_deg": [-50, 0]}},
                                 {"beam": {"e_plane_deg": 20}, "hpbw_el_deg": 24},
                                 {"beam": {"h_over_e": 0.5}}])
def test_bad_aim_and_beam_fields_are_refused(bad):
    with pytest.raises(ValidationError):
        _plan(physical=bad)


def test_polarisation_is_drawn_per_placement_and_sets_the_beams_planes():
    items = expand(_plan(physical={"hpbw_el_deg": None, "polarization": ["V", "H"],
                                   "beam": {"e_plane_deg": [18, 40], "h_over_e": [1.1, 1.3]}}))
    pols = [it.radar["antenna"]["polarization"] for it in items]
    assert 0.3 < np.mean([p == "H" for p in pols]) < 0.7
    for it in items:  # the E-plane (the narrower) lies in the plane of the elements
        a = it.radar["antenna"]
        assert (a["hpbw_el_deg"] < a["hpbw_az_deg"]) == (a["polarization"] == "V")
    with pytest.raises(ValidationError):
        _plan(physical={"polarization": ["X"]})
