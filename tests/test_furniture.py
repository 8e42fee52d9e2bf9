"""Furniture: the built-in chair, its scene file, its placement under a sitter, and what it does to the radar.

Physics checks: the chair occludes exactly the body facets whose line of sight crosses it (an independent
segment-box test predicts the lost paths), it adds no paths of its own to the facets backend, a static
chair return is removed by the DSP's clutter removal, and no body vertex gets into the chair beyond the
seat contact.
"""
from dataclasses import replace

import numpy as np
import pytest
from pydantic import ValidationError

from processing.radar.antenna import Isotropic
from processing.pathset import PathSet
from processing.io.signature_file import read_signature_file
from processing.radar.waveform import C0
from rtchannel import Motion, Radar, Scene, simulate
from rtchannel.scene.chair_fit import (chair_for, chair_penetration, procedural_seat_height,
                                       seated_frames)
from rtchannel.scene.furniture import (BACK_TOP_ABOVE_SEAT_M, LEG_SECTION_M, SEAT_DEPTH_M, SEAT_THICKNESS_M,
                                       SEAT_WIDTH_M, Furniture, chair_boxes, chair_mesh, furniture_dir, write_ply)

TAKE = "mocap/cmu/sit/75_17.bvh"  # through the data registry


@pytest.fixture(scope="module", autouse=True)
def _scene_cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("RTCHANNEL_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
        yield


@pytest.fixture(scope="module")
def sit():
    return Motion.procedural("sit", seed=0)


@pytest.fixture(scope="module")
def take():
    from thirdparty import data_path

    return Motion.from_file(data_path(TAKE), activity="sit")


def _signed_volume(v, f):
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6)


# ------------------------------------------------------------------------------------------ the chair
def test_chair_is_six_closed_outward_boxes_of_standard_size():
    h = 0.45
    v, f = chair_mesh(h)
    assert v.shape == (48, 3) and f.shape == (72, 3)
    leg = LEG_SECTION_M
    # seat board + 2 front legs (floor to seat underside) + 2 rear legs/posts (floor to backrest top) + board
    expected = (SEAT_DEPTH_M * SEAT_WIDTH_M * SEAT_THICKNESS_M + 2 * leg ** 2 * (h - SEAT_THICKNESS_M)
                + 2 * leg ** 2 * (h + BACK_TOP_ABOVE_SEAT_M) + leg * SEAT_WIDTH_M * (0.47 - 0.18))
    assert _signed_volume(v, f) == pytest.approx(expected, rel=1e-12)  # positive: outward winding
    assert np.allclose(v.min(0), [-0.21, -0.22, 0.0]) and np.allclose(v.max(0), [0.21, 0.22, 0.92])
    seat_top = chair_boxes(h)[0, 1, 2]
    assert seat_top == pytest.approx(h)


def test_stored_chair_asset_is_the_builders_chair(tmp_path):
    import trimesh

    stored = trimesh.load(furniture_dir() / "chair.ply", process=False)
    v, f = chair_mesh(0.45)
    assert np.array_equal(np.asarray(stored.faces), f)
    assert np.abs(np.asarray(stored.vertices) - v).max() < 1e-7  # float32 storage
    write_ply(tmp_path / "c.ply", v, f)
    assert (tmp_path / "c.ply").read_bytes() == (furniture_dir() / "chair.ply").read_bytes()


def test_furniture_validation(tmp_path, monkeypatch):
    with pytest.raises(ValidationError, match="unknown ITU material"):
        Furniture(material="balsa")
    with pytest.raises(ValidationError, match="sized by seat_height"):
        Furniture(scale=2.0)
    with pytest.raises(ValidationError, match="seat_height"):
        Furniture(seat_height=2.0)
    with pytest.raises(ValidationError):
        Furniture(colour="red")
    with pytest.raises(ValidationError, match="expected 'chair' or a .ply or .obj"):
        Furniture(mesh="table.stl")
    outside = tmp_path / "table.ply"
    write_ply(outside, *chair_mesh(0.7))
    with pytest.raises(ValidationError, match="outside the allowed folders"):
        Furniture(mesh=str(outside))
    monkeypatch.setenv("RTCHANNEL_FURNITURE_DIRS", str(tmp_path))
    table = Furniture(mesh=str(outside), scale=2.0, position=(1.0, 2.0, 0.0), yaw_deg=90.0)
    with pytest.raises(ValidationError, match="seat_height applies to the built-in chair"):
        Furniture(mesh=str(outside), seat_height=0.5)
    v, _ = table.world_mesh()
    # scale 2 about the origin, then +90 deg: local (0.21, 0.22) corner -> (-0.44, 0.42) + (1, 2)
    assert v[:, 0].min() == pytest.approx(1 - 0.44) and v[:, 1].max() == pytest.approx(2 + 0.42)
    d = table.describe()
    assert d["triangles"] == 72 and len(d["sha256"]) == 64 and Furniture.from_describe(d) == table


# ------------------------------------------------------------------------------------------ scene file
def test_scene_file_is_content_addressed_and_round_trips(sit, tmp_path, monkeypatch):
    a = Scene.room().with_chair_for(sit)
    b = Scene.room().with_furniture(a.furniture[0].model_dump())
    assert a.xml_path() == b.xml_path() and a.xml_path().is_file()
    moved = Scene.room().with_furniture(a.furniture[0].model_copy(update={"yaw_deg": 10.0}))
    assert moved.xml_path() != a.xml_path()
    assert Scene.room().xml_path().name == "room.xml"  # no furniture: the source file itself
    assert not list(a.xml_path().parent.glob("*.tmp"))
    assert Scene.from_describe(a.describe()) == a and a.name == "room+chair"
    # relative mesh references of a user's base scene are made absolute in the generated file
    (tmp_path / "m").mkdir()
    write_ply(tmp_path / "m" / "box.ply", *chair_mesh(0.45))
    user = tmp_path / "user.xml"
    user.write_text('<scene version="2.1.0"><bsdf type="itu-radio-material" id="w"><string name="type" '
                    'value="wood"/></bsdf><shape type="ply" id="box"><string name="filename" value="m/box.ply"/>'
                    '<ref id="w" name="bsdf"/></shape></scene>')
    text = Scene(user).with_furniture(Furniture()).xml_path().read_text()
    assert f"value=\"{tmp_path / 'm' / 'box.ply'}\"" in text


def test_generated_scene_loads_in_sionna_and_the_chair_is_static_geometry(sit):
    from rtchannel.body.avatar import load_avatar
    from rtchannel.scene.rt_scene import RadarPlacementError, RTScene, get_scene

    scene = Scene.room().with_chair_for(sit)
    chair = scene.furniture[0]
    av = load_avatar("2k")
    rt = RTScene(scene, av.faces, av.vertices, 24.125e9)
    names = [n for n, _, _ in rt.static_meshes]
    assert names == ["floor", "wall_xp", "wall_xn", "wall_yp", "wall_yn", "furniture0-chair"]
    _, v, f = rt.static_meshes[-1]
    want, want_f = chair.world_mesh()
    assert len(f) == 72 and np.abs(v[f] - want[want_f]).max() < 1e-6  # float32 on load
    # every chair face is below MIN_WALL_AREA_M2 (seat 0.185 m^2): no image sources of its own
    assert [w.name for w in rt.walls] == ["floor", "wall_xp", "wall_xn", "wall_yp", "wall_yn"]
    # inside the seat board, 1.5 cm from its faces: beyond the 1 cm distance test, caught as inside
    inside = chair.to_world([0.0, 0.0, chair.seat_height - SEAT_THICKNESS_M / 2])
    with pytest.raises(RadarPlacementError, match="inside 'furniture0-chair'"):
        rt.check_clearance(inside)
    rt.check_clearance(np.array([[3.0, 0.0, 1.1], [0.0, -3.0, 1.1]]))
    rt.check_clearance(np.array([[5.0, 0.0, 1.1]]))  # behind a wall (open faces): not "inside" anything
    # the ray tracer's scene cache keys on content: an equal description reuses the loaded scene
    same = Scene.room().with_furniture(chair.model_dump())
    assert get_scene(scene, "2k", 1.75, 24.125e9) is get_scene(same, "2k", 1.75, 24.125e9)


# ------------------------------------------------------------------------------------------ placement
@pytest.mark.parametrize("activity", ["sit", "stand"])
@pytest.mark.parametrize("seed, height, heading, start", [(0, 1.75, 0.0, (0.0, 0.0)), (1, 1.55, 45.0, (1.0, 1.0)),
                                                          (2, 1.95, -100.0, (-1.0, 0.5))])
def test_procedural_sitter_sits_on_the_chair_without_intersecting_it(activity, seed, height, heading, start):
    m = Motion.procedural(activity, seed=seed, height=height, heading_deg=heading, start=start)
    chair = chair_for(m)
    # the generator's own seat: 0.45 m for 1.75 m, scaled with the body
    assert chair.seat_height == pytest.approx(0.45 * height / 1.75, abs=1e-4)
    assert chair.yaw_deg == pytest.approx(heading, abs=0.5)  # seated facing = the motion's heading
    seated = seated_frames(m)
    # sit ends seated, stand starts seated (the 0.5 s pad plus the settled part of the activity)
    assert (seated[-1] if activity == "sit" else seated[0]) and seated.sum() / m.fps > 0.8
    depth = chair_penetration(chair, m)  # 10k skin, every frame
    # The generator puts the hip joints 0.095 m above the seat; the avatar's buttock skin lies ~0.086 m
    # below them: ~1 cm of "soft tissue compression" into the seat, nothing else.
    assert depth.max() < 0.012
    _rests_on_seat(chair, m, seated)


def _rests_on_seat(chair, m, seated):
    """Neither floating nor sunk: the lowest skin over the seat (above its underside) is within 1.5 cm of the
    seat top in the median seated frame."""
    from rtchannel.scene.chair_fit import _skin

    p = chair.to_local(_skin(m, "10k")[0][seated])
    h = chair.seat_height
    over = (np.abs(p[..., 0]) <= SEAT_DEPTH_M / 2) & (np.abs(p[..., 1]) <= SEAT_WIDTH_M / 2) & (
        p[..., 2] > h - SEAT_THICKNESS_M)
    gap = np.where(over, p[..., 2], np.inf).min(axis=1) - h
    assert abs(float(np.median(gap))) < 0.015


def test_skin_estimate_of_the_seat_agrees_with_the_generator(sit):
    anonymous = replace(sit, params={})  # as if imported: no generator parameters
    assert procedural_seat_height(anonymous) is None
    est = chair_for(anonymous).seat_height
    # lowest buttock skin 0.086 m below the hip joints vs the generator's 0.095 m: 0.45 - 0.009
    assert est == pytest.approx(0.45, abs=0.015) and est < 0.45


def test_feet_tucked_under_the_seat_do_not_lower_it(sit, monkeypatch):
    """A short sitter's heels can sit under the pelvis (an OpenCap sit-to-stand take with a 1.48 m body put the
    seat at 0.02 m). Feet moved onto the floor right under the hips must leave the skin estimate unchanged."""
    import rtchannel.body.skinning as skinning
    from rtchannel.body.avatar import load_avatar

    anonymous = replace(sit, params={})
    av = load_avatar("10k")
    names = av.rig.names
    feet = np.isin(np.asarray(av.dense_weights()).argmax(axis=1),
                   [names.index(b) for b in ("LeftFoot", "RightFoot", "LeftToeBase", "RightToeBase")])
    hips = anonymous.positions[:, names.index("Hips")]
    plain = skinning.skin_vertices

    def tucked(avatar, motion, *a, **k):
        v = np.array(plain(avatar, motion, *a, **k))
        v[:, feet, :2] = hips[:, None, :2]
        v[:, feet, 2] = 0.02
        return v

    monkeypatch.setattr(skinning, "skin_vertices", tucked)
    # the same tolerance as the untucked estimate above: 0.45 m generator seat, buttock skin within 1.5 cm
    assert chair_for(anonymous).seat_height == pytest.approx(0.45, abs=0.015)


def test_real_take_75_17(take):
    chair = chair_for(take)
    seated = seated_frames(take)
    t = np.flatnonzero(seated) / take.fps
    # the take: stands ~0.6 s, sits down, stays seated ~1.3 s, stands up from ~2.1 s
    assert 0.6 < t[0] < 0.8 and 2.0 < t[-1] < 2.2 and 0.9 < len(t) / take.fps < 1.6
    assert 0.24 < chair.seat_height < 0.30  # a low seat: the hip joints sustain 0.34-0.35 m
    assert abs(chair.yaw_deg) < 10.0
    depth = chair_penetration(chair, take)
    # 1.45 cm at the landing (the hips dip 4 cm below the sustained seated height for ~0.1 s): within 2 cm
    assert depth.max() < 0.02 and np.median(depth[seated]) < 0.005
    _rests_on_seat(chair, take, seated)


def test_a_walk_has_no_seat_and_the_auto_chair_only_comes_for_sit_and_stand(sit):
    walk = Motion.procedural("walk", duration=2.0)
    with pytest.raises(ValueError, match="no seated phase"):
        chair_for(walk)
    assert Scene.for_motion(walk, None, "auto") is None
    assert Scene.for_motion(sit, None, "none") is None
    auto = Scene.for_motion(sit, None, "auto")
    assert auto.source == "room" and [f.label for f in auto.furniture] == ["chair"]
    with pytest.raises(ValueError, match="no seated phase"):
        Scene.for_motion(replace(walk, activity="sit"), "room", "auto")


def test_cli_chair_option(sit):
    from rtchannel.cli import build_parser
    from rtchannel.cli.common import UserError
    from rtchannel.cli.simulate import scene_with_chair
    from rtchannel.scene.render import _static_geometry

    import inspect

    from rtchannel import simulate, simulate_radars, trace
    from rtchannel.scene.chair_fit import DEFAULT_CHAIR

    p = build_parser()
    # one chair default: the CLI's is the API's
    assert (p.parse_args(["simulate", "--out", "x"]).chair == p.parse_args(["render", "--out", "x"]).chair
            == DEFAULT_CHAIR)
    defaults = {inspect.signature(f).parameters["chair"].default for f in (simulate, simulate_radars, trace)}
    assert defaults == {DEFAULT_CHAIR}
    assert p.parse_args(["render", "--out", "x", "--chair", "none"]).chair == "none"
    with pytest.raises(SystemExit):
        p.parse_args(["simulate", "--out", "x", "--chair", "sofa"])
    with pytest.raises(UserError, match="--chair none"):
        scene_with_chair(None, replace(Motion.procedural("walk", duration=2.0), activity="stand"), "auto")
    scene = scene_with_chair(Scene("room"), sit, "auto")
    drawn = _static_geometry(scene, 1.75, 24.125e9, np.array([10.0, -10.0, 5.0]))
    assert sorted(len(f) for _, f, _ in drawn) == [2, 2, 2, 72]  # floor, two walls, the chair


# ------------------------------------------------------------------------------------------ radar physics
def _segment_crosses_boxes(chair, src, pts):
    """Independent line-of-sight oracle: does the segment src -> each point cross any chair box (slab test)?"""
    o, p = chair.to_local(src), chair.to_local(pts)
    d = p - o
    out = np.zeros(len(p), bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for lo, hi in chair_boxes(chair.seat_height):
            t1, t2 = (lo - o) / d, (hi - o) / d
            t_in, t_out = np.nanmax(np.minimum(t1, t2), axis=1), np.nanmin(np.maximum(t1, t2), axis=1)
            out |= (t_out >= t_in) & (t_out > 0) & (t_in < 1)
    return out


@pytest.fixture(scope="module")
def seated_still(sit):
    from rtchannel.motion.augment import trim

    return trim(sit, sit.duration - 0.1)  # the last 7 frames: seated, nearly still


@pytest.mark.parametrize("where, radar_pos", [("behind", (-3.0, 0.0, 1.1)), ("behind, low", (-3.0, 0.0, 0.4)),
                                              ("open side", (3.0, 0.0, 1.1))])
def test_chair_occludes_exactly_the_body_facets_behind_it(sit, seated_still, where, radar_pos):
    from rtchannel.backends.facets import facet_paths
    from rtchannel.body.avatar import load_avatar
    from rtchannel.body.skinning import skin_vertices

    scene = Scene.room().with_chair_for(sit)
    radar = Radar.monostatic(radar_pos)
    # diffuse only: its power is area-weighted, so hiding a fifth of the facets must cost power; a PO glint
    # on an unhidden facet could dominate either sum and make the power drop say nothing about occlusion
    opts = dict(lod="2k", trace_fps=None, walls=False, min_relative_gain_db=None, image_lod=None, po=False)
    empty = facet_paths(seated_still, radar, scene=Scene.room(), **opts, clutter=False)["radar1"]
    chair = facet_paths(seated_still, radar, scene=scene, **opts, clutter=False)["radar1"]
    seen_empty = set(empty.ids[empty.gains[0] != 0].tolist())
    seen_chair = set(chair.ids[chair.gains[0] != 0].tolist())
    av = load_avatar("2k")
    cent = skin_vertices(av, seated_still, [0])[0][av.faces].mean(axis=1)
    behind_chair = _segment_crosses_boxes(scene.furniture[0], np.array(radar_pos), cent)
    predicted = {f for f in seen_empty if not behind_chair[f]}
    assert seen_chair <= seen_empty  # a static occluder can only take paths away
    # float32 rays may flip a grazing facet: allow 0.5 % (measured: 0 mismatches)
    assert len(predicted ^ seen_chair) <= 0.005 * len(seen_empty)
    power = [float((np.abs(ps.gains[0]) ** 2).sum()) for ps in (empty, chair)]
    drop_db = 10 * np.log10(power[1] / power[0])
    if where == "open side":
        assert seen_chair == seen_empty and drop_db == pytest.approx(0.0, abs=1e-9)
    else:  # the backrest hides the back: 182 (261 low) of ~500 facets, 2.0 (2.1) dB
        assert len(seen_empty - seen_chair) > 0.2 * len(seen_empty) and drop_db < -1.0


@pytest.fixture(scope="module")
def sit_runs(sit):
    """facets (2k) simulations of the procedural sit in the empty room and with the chair, seed radars."""
    scene = Scene.room().with_chair_for(sit)
    return {name: simulate(sit, Radar.seed(1), "facets", scene=sc, lod="2k", clutter=False)
            for name, sc in (("empty", Scene.room()), ("chair", scene))}, scene


def test_chair_adds_no_paths_and_no_zero_velocity_line(sit, sit_runs):
    from rtchannel.backends.facets import facet_paths
    from rtchannel.body.avatar import load_avatar
    from rtchannel.scene.rt_scene import get_scene

    runs, scene = sit_runs
    n_faces = load_avatar("2k").n_faces
    n_walls = len(get_scene(scene, "2k", 1.75, 24.125e9).walls)
    assert n_walls == len(get_scene("room", "2k", 1.75, 24.125e9).walls) == 5
    for ps in facet_paths(sit, Radar.seed(1), scene=scene, lod="2k", clutter=False).values():
        # ids are body facets f + F kind: direct (0), single-bounce images (1..2W), double bounce (up to
        # 1 + 3W + W^2 with every wall pair; see rtchannel.backends.facets): nothing else exists
        assert ps.ids.min() >= 0 and ps.ids.max() < n_faces * (1 + 3 * n_walls + n_walls ** 2)
    for link in runs["empty"].signatures:
        a, b = runs["empty"].signatures[link], runs["chair"].signatures[link]
        zero = int(np.argmin(np.abs(a.velocity)))
        # A static chair line would add P_chair / (P_chair + P_body) to this bin in every window (0.97 for
        # a 1 m^2 chair, see the MTI test). Occlusion only re-weights body paths: measured 1.5e-4 and 8.8e-4.
        assert abs(a.p_vt[zero].mean() - b.p_vt[zero].mean()) < 0.01


def test_static_chair_return_is_removed_by_the_mti(sit):
    """Add the chair's own monostatic return (a static 1 m^2 scatterer at the backrest, ~12 dB above the
    body) to the facets paths: after the mean-subtraction MTI p(v,t) is unchanged up to float32 rounding;
    without it the zero-velocity bin takes almost all the mass."""
    from rtchannel.backends.facets import facet_paths
    from rtchannel.pipeline import process_paths

    scene = Scene.room().with_chair_for(sit)
    # Unit-gain antennas: the ~12 dB above is the RCS contrast (with the default horns, which weight chair
    # and body by their own directions, the zero-velocity bin without MTI measured 0.88 instead).
    radar = Radar.monostatic((-3.0, 0.0, 1.1), antenna=Isotropic())
    ps = facet_paths(sit, radar, scene=scene, lod="2k", clutter=False)["radar1"]
    back = scene.furniture[0].to_world([-0.19, 0.0, 0.75])
    r = float(np.linalg.norm(back - radar.links[0].tx_pos))
    a = radar.waveform.wavelength / ((4 * np.pi) ** 1.5 * r ** 2)  # sigma = 1 m^2, |a|^2 = Pr/Pt
    a *= float(radar.link_gain(radar.links[0], np.asarray(back)))  # the horns see the chair too, like the body
    k = ps.n_frames
    with_chair = PathSet(ps.times, np.column_stack([ps.delays, np.full(k, 2 * r / C0)]),
                         np.column_stack([ps.gains, np.full(k, a, complex)]), np.r_[ps.ids, ps.ids.max() + 1],
                         np.column_stack([ps.delay_rates, np.zeros(k)]), ps.link)
    for removal in ("mean", "none"):
        rad = radar.model_copy(update={"dsp": radar.dsp.model_copy(update={"static_removal": removal})})
        body = process_paths({"radar1": ps}, rad, noise_seed=3)["radar1"].signature
        both = process_paths({"radar1": with_chair}, rad, noise_seed=3)["radar1"].signature
        zero = int(np.argmin(np.abs(body.velocity)))
        if removal == "mean":
            # The static path is constant chirp to chirp; what survives the mean subtraction is the complex64
            # rounding of the IQ (eps 6e-8 of a sample ~4x the body's): |dp| ~ 1e-7 (measured 4e-8).
            assert np.abs(both.p_vt - body.p_vt).max() < 1e-5
        else:
            assert both.p_vt[zero].mean() > 0.9 > body.p_vt[zero].mean() + 0.2


def test_scene_description_round_trips_through_the_signature_file(sit_runs, tmp_path):
    runs, scene = sit_runs
    path = runs["chair"].save(tmp_path / "signature.h5")
    stored = read_signature_file(path)[0]["config"]["backend_options"]["scene"]
    assert stored == scene.describe()
    assert Scene.from_describe(stored) == scene and Scene.from_describe(stored).xml_path() == scene.xml_path()
    assert "procedural generator's seat" in stored["furniture"][0]["note"]
