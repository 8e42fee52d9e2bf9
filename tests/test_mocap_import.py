"""BVH and C3D import, retargeting onto the avatar, and clear errors for broken files."""
import re
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from rtchannel.body.avatar import load_avatar
from rtchannel.motion.bvh import write_bvh
from rtchannel.motion.errors import MotionImportError
from rtchannel.motion.load import load_motion
from rtchannel.body.skinning import skin_vertices
from thirdparty import needs, registered, where

WALK_NAMES = [p for p in registered("mocap/cmu/walk/*.bvh")]
WALKS = [where(p) for p in WALK_NAMES]
C3D_WALK = where("mocap/cmu/walk/82_08.c3d")
C3D_STAND = where("mocap/cmu/stand/77_02.c3d")
SIT_STAND = where("mocap/cmu/sit/75_17.bvh")

# the CMU takes come through the data registry: without the mirror or cache these tests skip and say how
needs_data = needs(*WALK_NAMES, "mocap/cmu/walk/82_08.c3d", "mocap/cmu/stand/77_02.c3d", "mocap/cmu/sit/75_17.bvh")


@needs_data
def test_mocap_present():
    assert len(WALKS) == 10 and C3D_WALK.is_file() and C3D_STAND.is_file() and SIT_STAND.is_file()


@lru_cache(maxsize=None)
def motion_of(path: Path):
    return load_motion(path, activity="walk")


def feet_vertices(av):
    w = av.dense_weights()
    r = av.rig
    return {s: np.flatnonzero(w[:, [r.index(f"{s}Foot"), r.index(f"{s}ToeBase")]].sum(axis=1) > 0.5)
            for s in ("Left", "Right")}


@needs_data
@pytest.mark.parametrize("path", WALKS, ids=lambda p: p.stem)
def test_walks_import_retarget_and_skin(path):
    m = motion_of(path)
    assert m.rig.n_joints == 31 and m.activity == "walk"
    hips = m.positions[:, 0]
    travel = np.linalg.norm(hips[-1, :2] - hips[0, :2])
    assert 3.5 <= travel <= 5.5
    # 02_02 walks 4.55 m in 147 frames at 60 fps in the file itself (1.86 m/s): the bound allows it
    assert 0.8 <= travel / m.duration <= 1.9
    av = load_avatar("2k")
    v = skin_vertices(av, m)
    assert np.isfinite(v).all()
    assert v[..., 2].min() >= -0.03  # nothing sinks into the floor
    assert np.ptp(v[:, :, 2], axis=1).max() <= m.rig.height + 0.01
    heads = v[:, :, 2].max(axis=1)
    assert np.median(heads) > 0.9 * m.rig.height  # upright
    stance = []
    for side, idx in feet_vertices(av).items():
        ankle = m.positions[:, m.rig.index(f"{side}Foot"), :2]
        speed = np.linalg.norm(np.gradient(ankle, axis=0), axis=1) * m.fps
        stance.append(v[speed < 0.25][:, idx, 2].min(axis=1))
    lowest = np.concatenate(stance)
    assert len(lowest) > 0.3 * m.n_frames
    assert np.abs(lowest).max() <= 0.03  # planted feet touch the floor
    # converter T-pose frames are detected, not listed
    assert m.params["dropped_leading_frames"] == (1 if path.stem[:5] in ("07_03", "07_04", "07_05", "07_06") else 0)
    assert m.params["units"] == "cm" and m.params["up"] == "y"


@needs_data
def test_c3d_stand_then_walk():
    m = load_motion(C3D_WALK)
    assert m.fps == 120.0 and m.params["format"] == "c3d" and m.params["units"] == "mm"
    hips = m.positions[:, 0, :2]
    speed = np.linalg.norm(np.gradient(hips, axis=0), axis=1) * m.fps
    second = [speed[i:i + 120].mean() for i in range(0, m.n_frames - 119, 120)]
    assert max(second[:6]) < 0.25  # standing first
    walking = [k for k, s in enumerate(second) if s > 0.8]
    assert walking and walking[0] >= 6  # then a walk
    assert 3.0 < np.linalg.norm(hips[-1] - hips[0]) < 4.8
    v = skin_vertices(load_avatar("2k"), m, frames=np.arange(0, m.n_frames, 10))
    assert v[..., 2].min() > -0.03 and np.median(v[..., 2].max(axis=1)) > 0.9 * m.rig.height


@needs_data
def test_c3d_standing_take():
    m = load_motion(C3D_STAND, height=1.7)
    hips = m.positions[:, 0]
    assert np.linalg.norm(hips[-1, :2] - hips[0, :2]) < 0.3
    assert m.rig.height == 1.7


def test_bvh_round_trip_cmu_rig_and_units(tmp_path):
    t = np.arange(90) / 60.0
    from test_skinning import smooth_motion
    src = smooth_motion(t, 1.75)
    src = type(src)(src.rig, 60.0, src.rotations, src.positions + [0, 0, 0.05])
    for units in ("cm", "m", "mm"):
        p = tmp_path / f"take_{units}.bvh"
        write_bvh(src, p, units=units)
        m = load_motion(p, align=False, floor=False)
        assert m.params["units"] == units and m.params["rig"] == "cmu"
        assert m.rig.height == pytest.approx(1.75, abs=1e-6)
        np.testing.assert_allclose(m.rotations, src.rotations, atol=1e-5)
        np.testing.assert_allclose(m.positions, src.positions, atol=1e-5)
        grounded = load_motion(p)
        assert grounded.params["floor"] and np.isfinite(grounded.positions).all()
    from processing.errors import InputError

    with pytest.raises(InputError, match="units must be given"):  # was a TypeError (1.0 / None); found by mypy
        write_bvh(src, tmp_path / "no_unit.bvh", units=None)


def _cut(text: str, marker: str, extra: int) -> str:
    return text[: text.index(marker) + extra]


@needs_data
def test_truncated_and_corrupted_bvh(tmp_path):
    text = WALKS[0].read_text()
    lines = text.splitlines()
    motion_line = lines.index("MOTION")
    cases = {
        "cut_in_motion.bvh": "\n".join(lines[: motion_line + 40]) + "\n0.1 0.2",
        "cut_in_hierarchy.bvh": text[: len(text) // 40],
        "fewer_frames.bvh": "\n".join(lines[: motion_line + 50]) + "\n",
    }
    garbled = list(lines)
    row = garbled[motion_line + 20].split()
    row[7] = "1.2.3e"
    garbled[motion_line + 20] = " ".join(row)
    cases["garbled.bvh"] = "\n".join(garbled) + "\n"
    expect = {"cut_in_motion.bvh": rf"line {motion_line + 41}\b",
              "cut_in_hierarchy.bvh": r"line \d+",
              "fewer_frames.bvh": r"truncated",
              "garbled.bvh": rf"line {motion_line + 21}, frame 17: not a number: '1\.2\.3e'"}
    for name, body in cases.items():
        p = tmp_path / name
        p.write_text(body)
        with pytest.raises(MotionImportError, match=re.escape(str(p))) as exc:
            load_motion(p)
        assert re.search(expect[name], str(exc.value)), str(exc.value)
        assert isinstance(exc.value, ValueError)


@needs_data
def test_truncated_and_corrupted_c3d(tmp_path):
    raw = C3D_WALK.read_bytes()
    cut = tmp_path / "cut.c3d"
    cut.write_bytes(raw[: len(raw) // 2 + 7])
    with pytest.raises(MotionImportError, match=r"cut\.c3d, frame \d+: truncated: header says 1699 frames"):
        load_motion(cut)
    bad = bytearray(raw)
    bad[512 + 4: 512 + 40] = b"garbage!" * 4 + b"abcd"  # parameter section
    p = tmp_path / "garbled.c3d"
    p.write_bytes(bytes(bad))
    with pytest.raises(MotionImportError, match=r"garbled\.c3d: not a readable C3D file"):
        load_motion(p)
    p2 = tmp_path / "tiny.c3d"
    p2.write_bytes(raw[:100])
    with pytest.raises(MotionImportError, match=r"tiny\.c3d"):
        load_motion(p2)
    with pytest.raises(MotionImportError, match="unsupported motion file type"):
        load_motion(tmp_path / "take.fbx")


def _write_c3d_with_gap(path, frames):
    import ezc3d
    src = ezc3d.c3d(str(C3D_STAND))
    pts = src["data"]["points"][:, :, :300].copy()
    labels = list(src["parameters"]["POINT"]["LABELS"]["value"])
    k = [lab.split(":")[-1] for lab in labels].index("LKNE")
    pts[:3, k, frames] = np.nan
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [60.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = labels
    c.add_parameter("POINT", "UNITS", ["mm"])
    c["data"]["points"] = pts
    c.write(str(path))


@needs_data
def test_c3d_marker_gaps(tmp_path):
    short = tmp_path / "short_gap.c3d"
    _write_c3d_with_gap(short, np.arange(100, 106))  # 0.1 s at 60 Hz
    m = load_motion(short)
    assert m.params["filled_gaps"] == {"LKNE": [[100, 105]]}
    assert np.isfinite(m.positions).all()
    long = tmp_path / "long_gap.c3d"
    _write_c3d_with_gap(long, np.arange(100, 161))  # 1 s
    with pytest.raises(MotionImportError, match=r"long_gap\.c3d: marker gaps longer than 0\.2 s: LKNE: frames 100-160"):
        load_motion(long)
    with pytest.warns(UserWarning, match="LKNE: frames 100-160"):
        m2 = load_motion(long, on_long_gap="warn")
    assert np.isfinite(m2.positions).all()
    assert load_motion(long, max_gap_s=1.5).params["filled_gaps"] == {"LKNE": [[100, 160]]}


@needs_data
def test_units_and_up_axis_overrides():
    auto = motion_of(WALKS[0])
    given = load_motion(WALKS[0], units="cm", up="y", activity="walk")
    np.testing.assert_allclose(given.positions, auto.positions)
    m = load_motion(WALKS[0], fps=30.0, height=1.6)
    assert m.fps == 30.0 and m.rig.height == 1.6
    assert m.params["leg_ratio"] == pytest.approx(m.params["height"] / auto.params["height"], rel=1e-6)


@needs_data
def test_sit_stand_take_sits_down_then_stands_up():
    """CMU 75_17 (cgspeed 31-joint rig, CMU units, 30 fps): frame 0 is a reference T-pose, then the subject
    sits down on a seat, stays seated and stands up again."""
    m = load_motion(SIT_STAND, activity="sit")
    assert m.params["units"] == "cmu" and m.params["dropped_leading_frames"] == 1
    assert abs(m.fps - 30.0) < 1e-3 and m.n_frames == 81
    r = m.rig
    hips = m.positions[:, r.index("Hips"), 2]
    hands = m.positions[:, [r.index("LeftHand"), r.index("RightHand")], 2]
    # no T-pose left: the hands hang below the shoulders in the first frame
    assert hands[0].max() < m.positions[0, r.index("LeftArm"), 2] - 0.2
    standing, seated = hips[:5].mean(), np.percentile(hips, 5)
    # standing hip-joint height ~0.53 H; seated on a chair-height seat (0.3-0.5 m) it is 0.1 m above it
    assert 0.5 * m.rig.height < standing < 0.6 * m.rig.height
    assert 0.3 < seated < 0.55
    low = np.flatnonzero(hips < seated + 0.05)
    down = np.flatnonzero(hips < standing - 0.1)
    # one sit-down (hips descend), a seated plateau of at least 1 s, one stand-up (hips rise back)
    assert low[0] > 3 and low[-1] - low[0] >= 1.0 * m.fps and np.all(np.diff(low) == 1)
    assert np.all(np.diff(down) == 1) and down[-1] < m.n_frames - 1
    assert hips[-1] > standing - 0.05
    descent = np.diff(hips[:low[0] + 1])
    ascent = np.diff(hips[low[-1]:])
    assert descent.min() < -0.01 and ascent.max() > 0.01
    # seated: thighs roughly horizontal (knee at about hip height)
    k = (low[0] + low[-1]) // 2
    knee = m.positions[k, r.index("LeftLeg"), 2]
    assert abs(knee - hips[k]) < 0.15


def _small_bvh(tmp_path):
    """A short CMU-rig take written by `write_bvh` (units cm): its text and the MOTION line index."""
    from test_skinning import smooth_motion
    src = smooth_motion(np.arange(30) / 60.0, 1.75)
    p = tmp_path / "small.bvh"
    write_bvh(src, p, units="cm")
    lines = p.read_text().splitlines()
    return lines, lines.index("MOTION")


def test_bvh_with_byte_order_mark_is_read(tmp_path):
    lines, _ = _small_bvh(tmp_path)
    plain = load_motion(tmp_path / "small.bvh", align=False, floor=False)
    p = tmp_path / "bom.bvh"
    p.write_bytes(b"\xef\xbb\xbf" + "\n".join(lines).encode() + b"\n")
    m = load_motion(p, align=False, floor=False)
    np.testing.assert_array_equal(m.positions, plain.positions)


@pytest.mark.parametrize("edit, expect", [
    # (line offset from MOTION, new text), message pattern naming the line
    ((1, "Frames: 10"), r"line {f0_10}, frame 10: header says 10 frames but the file holds 30 data rows"),
    ((1, "Frames: -5"), r"line {frames}: frame count -5 outside 1\.\."),
    ((1, "Frames: 2.5"), r"line {frames}: frame count is not an integer"),
    ((2, "Frame Time: 1e300"), r"line {ftime}: frame time 1e300 s outside 0\.0001\.\.1 s"),
    ((2, "Frame Time: 1e-300"), r"line {ftime}: frame time 1e-300 s outside"),
    ((2, "Frame Time: nan"), r"line {ftime}: frame time nan s outside"),
    ((2, "Frame Time: 0.9"), r"line {frames}: 30 frames of 0\.9 s last 27 s|"),  # allowed: 27 s < 1 h
])
def test_bvh_motion_header_bounds(tmp_path, edit, expect):
    lines, mo = _small_bvh(tmp_path)
    k, text = edit
    lines[mo + k] = text
    p = tmp_path / "bad.bvh"
    p.write_text("\n".join(lines) + "\n")
    pattern = expect.format(frames=mo + 2, ftime=mo + 3, f0_10=mo + 4 + 10)
    if pattern.endswith("|"):
        assert load_motion(p, align=False, floor=False).n_frames == 30
        return
    with pytest.raises(MotionImportError, match=pattern):
        load_motion(p)


@pytest.mark.parametrize("col, value, what", [(0, "1e20", "Xposition = 1e\\+20 file units is beyond"),
                                             (5, "1e20", "rotation = 1e\\+20 deg is beyond"),
                                             (0, "5e5", "is 5e\\+03 m from the origin")])
def test_bvh_absurd_values_mid_take(tmp_path, col, value, what):
    lines, mo = _small_bvh(tmp_path)
    row = lines[mo + 3 + 17].split()
    row[col] = value
    lines[mo + 3 + 17] = " ".join(row)
    p = tmp_path / "big.bvh"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(MotionImportError, match=rf"big\.bvh, line {mo + 21}, frame 17: .*{what}"):
        load_motion(p)


@pytest.mark.parametrize("old, new, expect", [
    ("Zrotation Yrotation Xrotation", "Zrotation Yrotation Wrotation", "unknown channel 'Wrotation'"),
    ("Zrotation Yrotation Xrotation", "Zrotation Zrotation Xrotation", "channel Zrotation listed twice"),
    ("OFFSET", "OFFSET nan", "OFFSET of .* is not a number|OFFSET of .* is not finite"),
    ("CHANNELS 3", "CHANNELS 9", "channel count of .* must be an integer 0..6"),
])
def test_bvh_hierarchy_errors(tmp_path, old, new, expect):
    lines, _ = _small_bvh(tmp_path)
    k = next(i for i, ln in enumerate(lines) if old in ln and i > 3)
    lines[k] = lines[k].replace(old, new, 1)
    p = tmp_path / "h.bvh"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(MotionImportError, match=rf"h\.bvh, line \d+: (?:{expect})"):
        load_motion(p)


def test_motion_fps_and_argument_bounds(tmp_path):
    from rtchannel.errors import ConfigError
    _small_bvh(tmp_path)
    p = tmp_path / "small.bvh"
    for fps in (1e6, float("nan"), 0.0, float("inf")):
        with pytest.raises(ConfigError, match="fps"):
            load_motion(p, fps=fps)
    with pytest.raises(ConfigError, match="units"):
        load_motion(p, units=float("inf"))
    with pytest.raises(ConfigError, match="up"):
        load_motion(p, up="w")
    m = load_motion(p)
    with pytest.raises(ConfigError, match=r"fps: .* frames, more than 200000"):
        m.resampled(1e6)  # the CLI's --fps on a motion file goes through Motion.resampled
    with pytest.raises(ConfigError, match="fps: must be a positive finite"):
        m.resampled(float("nan"))


def _c3d_copy(path, edit):
    import ezc3d
    src = ezc3d.c3d(str(C3D_STAND))
    pts = src["data"]["points"][:, :, :200].copy()
    labels = list(src["parameters"]["POINT"]["LABELS"]["value"])
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [60.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = labels
    units = edit(pts, labels)
    c.add_parameter("POINT", "UNITS", [units])
    c["data"]["points"] = pts
    c.write(str(path))


@needs_data
def test_c3d_absurd_values_and_wrong_units(tmp_path):
    def huge(pts, labels):
        pts[:3, [lab.split(":")[-1] for lab in labels].index("LKNE"), 50] = 1e20
        return "mm"
    p = tmp_path / "huge.c3d"
    _c3d_copy(p, huge)
    with pytest.raises(MotionImportError, match=r"huge\.c3d, frame 50: LKNE is 1e\+17 m from the origin"):
        load_motion(p)
    p2 = tmp_path / "units.c3d"
    _c3d_copy(p2, lambda pts, labels: "m")  # data in mm, POINT:UNITS says m
    with pytest.raises(MotionImportError, match=r"units\.c3d: hip-to-ankle marker distance is .* with the file's "
                       r"POINT:UNITS 'm'"):
        load_motion(p2)
    assert load_motion(p2, units="mm").n_frames > 100  # the override fixes it


def test_bvh_with_millions_of_short_lines_is_refused_before_splitting(tmp_path):
    p = tmp_path / "many.bvh"
    p.write_text("HIERARCHY\n" + "1\n" * 500_000)
    with pytest.raises(MotionImportError, match=r"many\.bvh: more than 410000 lines"):
        load_motion(p)


def test_c3d_imports_under_an_address_space_limit(tmp_path):
    """Batch clusters and `ulimit -v` limit address space below the C3D child's own 8 GiB cap: the child must
    only lower limits (raising them fails), so a valid file still imports under 4 GiB."""
    import subprocess
    import sys

    import ezc3d

    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = ["A", "B"]
    c.add_parameter("POINT", "UNITS", ["mm"])
    pts = np.ones((4, 2, 50))
    pts[:3] *= np.arange(50)[None, None, :] * 10.0
    c["data"]["points"] = pts
    path = tmp_path / "tiny.c3d"
    c.write(str(path))
    code = ("import resource; resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))\n"
            "from rtchannel.motion.c3d import read_markers\n"
            f"m, rate, units = read_markers({str(path)!r})\n"
            "print(sorted(m), rate, units, m['A'].shape)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-1500:]
    assert r.stdout.strip() == "['A', 'B'] 100.0 mm (50, 3)"


PLUG_IN_GAIT = registered("mocap/msm2017/pick/*.c3d")


@pytest.mark.parametrize("take", PLUG_IN_GAIT, ids=lambda p: Path(p).stem)
def test_plug_in_gait_stoop_lifts_import_as_picks(take, shared_data):
    """Vicon Plug-in Gait (no MT5 markers, tibia instead of shin markers): a person 1.4-2.0 m tall standing on
    the floor, whose head drops by more than 0.4 m and comes back (the take's README: 1.66 -> 0.92 -> 1.68 m)."""
    m = load_motion(shared_data(take), activity="pick")
    assert m.params["marker_set"] == "plug-in-gait"
    assert 1.4 <= m.rig.height <= 2.0
    av = load_avatar("2k")
    v0 = skin_vertices(av, m, [0])[0]
    assert abs(v0[:, 2].min()) < 0.03  # soles on the floor at the start
    head = m.positions[:, m.rig.index("Head"), 2]
    assert head[0] - head.min() >= 0.4 and abs(head[-1] - head[0]) < 0.1


def test_unknown_marker_set_names_the_closest_set_and_its_missing_markers(tmp_path):
    import ezc3d

    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = ["LASI", "RASI", "LKNE"]
    c.add_parameter("POINT", "UNITS", ["mm"])
    c["data"]["points"] = np.ones((4, 3, 20))
    p = tmp_path / "few.c3d"
    c.write(str(p))
    with pytest.raises(MotionImportError, match=r"few\.c3d.*marker set lacks .*closest known set"):
        load_motion(p)


DAZ_WALKS = registered("mocap/cmu/walk_daz/*.bvh")


@pytest.mark.parametrize("take", DAZ_WALKS, ids=lambda p: Path(p).stem)
def test_daz_rig_walks_of_three_more_people_import(take, shared_data):
    """cgspeed's Daz-friendly CMU conversion (hip, abdomen, lThigh, ...): straight walks of 3.7-4.1 m at
    0.9-1.6 m/s (the takes' README), upright, soles on the floor."""
    m = load_motion(shared_data(take), activity="walk")
    assert m.params["rig"] == "daz" and 1.4 <= m.rig.height <= 2.0
    hips = m.positions[:, 0]
    travel = np.linalg.norm(hips[-1, :2] - hips[0, :2])
    assert 3.4 <= travel <= 4.3 and 0.8 <= travel / m.duration <= 1.7
    v0 = skin_vertices(load_avatar("2k"), m, [0])[0]
    assert abs(v0[:, 2].min()) < 0.03 and v0[:, 2].max() > 1.3


def test_unknown_bvh_rig_names_the_joints_it_lacks(tmp_path):
    bvh = tmp_path / "odd.bvh"
    bvh.write_text("HIERARCHY\nROOT pelvis\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition Zposition Zrotation "
                   "Xrotation Yrotation\n  JOINT lThigh\n  {\n    OFFSET 10 -5 0\n    CHANNELS 3 Zrotation Xrotation "
                   "Yrotation\n    End Site\n    {\n      OFFSET 0 -40 0\n    }\n  }\n}\nMOTION\nFrames: 2\n"
                   "Frame Time: 0.0333333\n0 90 0 0 0 0 0 0 0\n0 90 0 0 0 0 0 0 0\n")
    with pytest.raises(MotionImportError, match=r"odd\.bvh.*closest known rig 'daz' lacks joints .*abdomen"):
        load_motion(bvh)


@pytest.mark.parametrize("up", ["z", "x", "-y"])
def test_a_wrong_up_axis_is_refused_and_the_error_names_the_option(up, tmp_path, capsys, shared_data):
    """A y-up take read as z, x or -y up leaves the person on their side or upside down at the start: one
    line naming --up; the right axis (also given explicitly) imports."""
    from rtchannel.cli import main

    take = str(shared_data("mocap/cmu/sit/75_17.bvh"))
    with pytest.raises(MotionImportError, match=r"not upright at the start .* pass up= \(--up\)"):
        load_motion(take, activity="sit", up=up)
    assert main(["simulate", "--motion-file", take, "--activity", "sit", "--up", up, "--out", str(tmp_path / "x"),
                 "--quiet", "--no-plots"]) == 2
    assert "--up" in capsys.readouterr().err
    assert load_motion(take, activity="sit", up="y").rig.height == pytest.approx(1.745, abs=0.01)


def test_mixamo_rig_is_recognised_by_its_joint_names_and_retargets(tmp_path):
    """A Mixamo-named BVH ("mixamorig:" namespace, Spine/Spine1/Spine2, Neck, no hip joints), made by renaming
    the joints of a BVH written from a known motion: recognised as Mixamo and retargeted onto the same rig,
    hips, legs and arms within 1 mm, the head within 2 cm (Mixamo has one neck bone where the rig has two)."""
    import re

    from rtchannel import Motion

    m = Motion.procedural("pick", height=1.75, seed=0)
    write_bvh(m, tmp_path / "cmu.bvh")
    ren = {"LeftFingerBase": "LeftHandMiddle1", "RightFingerBase": "RightHandMiddle1", "LowerBack": "Spine",
           "Spine": "Spine1", "Spine1": "Spine2", "Neck1": "NeckTwist", "LHipJoint": "LHip_", "RHipJoint": "RHip_"}
    text = re.sub(r"\b(ROOT|JOINT)\s+(\S+)", lambda mo: f"{mo.group(1)} mixamorig:{ren.get(mo.group(2), mo.group(2))}",
                  (tmp_path / "cmu.bvh").read_text())
    (tmp_path / "mixamo.bvh").write_text(text)
    b = load_motion(tmp_path / "mixamo.bvh", activity="pick", height=1.75, floor=False, align=False)
    assert b.params["rig"] == "mixamo"
    for joint in ("Hips", "LeftUpLeg", "RightLeg", "LeftFoot", "LeftArm", "RightHand"):
        assert np.abs(b.positions[:, b.rig.index(joint)] - m.positions[:, m.rig.index(joint)]).max() < 1e-3, joint
    assert np.abs(b.positions[:, b.rig.index("Head")] - m.positions[:, m.rig.index("Head")]).max() < 0.02
