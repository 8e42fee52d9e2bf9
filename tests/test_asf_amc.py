"""ASF/AMC import (issue 23): forward kinematics worked by hand on a small skeleton, units from the ASF, and
every HDM05 take of the data registry (picks and lie-downs by four actors)."""
from pathlib import Path

import numpy as np
import pytest

from rtchannel.motion.asf_amc import forward_kinematics_asf, read_amc, read_asf
from rtchannel.motion.errors import MotionImportError
from rtchannel.motion.load import load_motion
from thirdparty import registered

ASF = """# a two-bone leg
:version 1.10
:units
  mass 1.0
  length 0.45
  angle deg
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name lfemur
     direction 0 -1 0
     length 10
     axis 0 0 90 XYZ
     dof rx ry rz
  end
  begin
     id 2
     name ltibia
     direction 0 -1 0
     length 10
     axis 0 0 0 XYZ
     dof rx
  end
:hierarchy
  begin
    root lfemur
    lfemur ltibia
  end
"""
AMC = """:FULLY-SPECIFIED
:DEGREES
1
root 1 2 3 0 0 0
lfemur 0 0 0
ltibia 0
2
root 1 2 3 0 0 90
lfemur 90 0 0
ltibia 90
"""


def test_forward_kinematics_by_hand(tmp_path):
    """Frame 1, zero pose: knee at root + (0, -10, 0), ankle at + (0, -20, 0). Frame 2: root turned 90 deg
    about z (x -> y, y -> -x); the femur's axis C = Rz(90) turns its rx of 90 deg into a rotation about
    C x = +y, which leaves the femur's -y direction as it is: knee = (1, 2, 3) + Rz(90) (0, -10, 0) =
    (11, 2, 3); the tibia (C = I) adds rx 90 in the femur's frame: Rz(90) Ry(90) Rx(90) (0, -10, 0)
    = Rz(90) Ry(90) (0, 0, -10) = Rz(90) (-10, 0, 0) = (0, -10, 0), so the ankle is at (11, -8, 3)."""
    (tmp_path / "s.asf").write_text(ASF)
    (tmp_path / "m.amc").write_text(AMC)
    skel = read_asf(tmp_path / "s.asf")
    assert skel.metres_per_unit == pytest.approx(0.0254 / 0.45, rel=1e-12)  # 1/0.45 inch
    root, values = read_amc(tmp_path / "m.amc", skel)
    g, start, end = forward_kinematics_asf(skel, root, values)
    np.testing.assert_allclose(end["lfemur"], [[1, -8, 3], [11, 2, 3]], atol=1e-9)  # file units
    np.testing.assert_allclose(start["ltibia"], end["lfemur"], atol=1e-12)
    np.testing.assert_allclose(end["ltibia"], [[1, -18, 3], [11, -8, 3]], atol=1e-9)
    assert 1e-9 * skel.metres_per_unit < 1e-3  # within 1 mm, as the issue asks, by a wide margin


def test_malformed_asf_and_amc_are_one_line_errors(tmp_path):
    (tmp_path / "s.asf").write_text(ASF.replace("length 10\n     axis 0 0 0", "length ten\n     axis 0 0 0"))
    with pytest.raises(MotionImportError, match=r"s\.asf, line \d+: malformed ASF"):
        read_asf(tmp_path / "s.asf")
    (tmp_path / "ok.asf").write_text(ASF)
    (tmp_path / "m.amc").write_text(AMC.replace("lfemur 90 0 0", "lfemur 90 0"))
    with pytest.raises(MotionImportError, match=r"m\.amc, line 9, frame 1: bone 'lfemur' has 2 values"):
        read_amc(tmp_path / "m.amc", read_asf(tmp_path / "ok.asf"))
    with pytest.raises(Exception, match="needs its ASF skeleton"):
        load_motion(tmp_path / "m.amc")


HDM05 = registered("mocap/hdm05/pick/*.amc") + registered("mocap/hdm05/lie_down/*.amc")


@pytest.mark.parametrize("take", HDM05, ids=lambda p: Path(p).stem)
def test_every_hdm05_take_imports_with_default_flags(take, shared_data):
    """A person 1.4-2.0 m tall standing on the floor at the start; the picks' head drops by >= 0.4 m and
    returns; the lie-downs end with the hips below 0.3 m (the takes' README)."""
    from rtchannel.body.avatar import load_avatar
    from rtchannel.body.skinning import skin_vertices

    actor = Path(take).name.split("_")[1]
    m = load_motion(shared_data(take), skeleton=shared_data(f"mocap/hdm05/asf/HDM_{actor}.asf"),
                    activity="pick" if "/pick/" in take else "fall")
    assert 1.4 <= m.rig.height <= 2.0 and m.fps == 120.0
    v0 = skin_vertices(load_avatar("2k"), m, [0])[0]
    assert abs(v0[:, 2].min()) < 0.03 and v0[:, 2].max() > 1.3  # standing, soles on the floor
    head, hips = m.positions[:, m.rig.index("Head"), 2], m.positions[:, 0, 2]
    if "/pick/" in take:
        assert head[0] - head.min() >= 0.4 and head[-1] > head[0] - 0.2
    else:
        assert hips[-1] < 0.3


def test_plan_sources_take_amc_folders_with_their_actors_skeletons(tmp_path, shared_data):
    from rtchannel.dataset.plan import expand, load_plan

    for t in HDM05[:1]:
        shared_data(t)  # skips without the data
    plan = tmp_path / "p.yaml"
    plan.write_text("name: p\nmotion:\n  sources:\n    - files: data:mocap/hdm05/pick\n      activity: pick\n"
                    "      options: {skeleton: data:mocap/hdm05/asf}\n")
    items = expand(load_plan(plan))
    skel = {Path(it.motion["path"]).name.split("_")[1]: Path(it.motion["options"]["skeleton"]).name for it in items}
    assert skel == {"bd": "HDM_bd.asf", "bk": "HDM_bk.asf", "dg": "HDM_dg.asf", "mm": "HDM_mm.asf"}


def test_opencap_sit_to_stand_series_imports_with_its_five_cycles(shared_data):
    """OpenCap body kinematics (OpenSim bodies, 100 Hz): a 1.4-2.0 m person whose hips rise from the seat
    (~0.5 m) to standing (~0.95 m) and back five times (stand-ups at 0.6, 3.2, 5.9, 8.5, 11.1 s; the take's
    README), soles on the floor."""
    from rtchannel.body.avatar import load_avatar
    from rtchannel.body.skinning import skin_vertices

    m = load_motion(shared_data("mocap/opencap/sit_stand/opencap_STS_sample_mocap.json"), activity="stand")
    assert m.fps == pytest.approx(100.0) and 1.4 <= m.rig.height <= 2.0
    hips = m.positions[:, 0, 2]
    standing = hips > 0.5 * (hips.min() + hips.max())
    rises = np.flatnonzero(np.diff(standing.astype(int)) == 1) / m.fps
    assert len(rises) == 5 and np.all(np.abs(rises - [0.6, 3.2, 5.9, 8.5, 11.1]) < 0.6), rises
    assert hips.max() - hips.min() > 0.3
    v0 = skin_vertices(load_avatar("2k"), m, [0])[0]
    assert abs(v0[:, 2].min()) < 0.03


def test_opencap_json_errors_are_one_line(tmp_path):
    p = tmp_path / "take.json"
    p.write_text('{"time": [0, 0.01], "bodies": {"pelvis": {}}}')
    with pytest.raises(MotionImportError, match=r"take\.json: not OpenSim full-body kinematics: lacks bodies"):
        load_motion(p)
    p.write_text("[1, 2")
    with pytest.raises(MotionImportError, match=r"take\.json: not OpenCap body kinematics JSON"):
        load_motion(p)


def _joint_tracks_of(m):
    names = {"left_hip": "LeftUpLeg", "right_hip": "RightUpLeg", "LKnee": "LeftLeg", "RKnee": "RightLeg",
             "ankle_l": "LeftFoot", "ankle_r": "RightFoot",
             "left_big_toe": "LeftToeBase", "right_big_toe": "RightToeBase",
             "left_shoulder": "LeftArm", "right_shoulder": "RightArm",
             "l_elbow": "LeftForeArm", "r_elbow": "RightForeArm",
             "left_wrist": "LeftHand", "right_wrist": "RightHand", "neck": "Neck1", "nose": "Head"}
    return names, np.stack([m.positions[:, m.rig.index(v)] for v in names.values()], axis=1)


@pytest.mark.parametrize("form", ["npz", "csv"])
def test_joint_positions_round_trip_onto_the_skeleton(form, tmp_path):
    """Joint positions written from a known motion (a procedural walk on the avatar rig, names in several
    spellings) solve back onto the same rig: hips, knees and ankles within 1 mm (a chain of known joints);
    shoulders, elbows, wrists and head within 10 cm (joint positions carry no segment rotation: the thorax is
    rebuilt from the shoulders and the trunk's direction, which moves the shoulder girdle a few cm)."""
    from rtchannel import Motion

    m = Motion.procedural("walk", height=1.75, seed=0, speed=1.2)
    names, pos = _joint_tracks_of(m)
    path = tmp_path / f"walk.{form}"
    if form == "npz":
        np.savez(path, positions=pos, names=np.array(list(names)), fps=m.fps, up="z")
    else:
        cols = ["time"] + [f"{n}_{a}" for n in names for a in "xyz"]
        rows = np.column_stack([m.times, pos.reshape(len(pos), -1)])
        path.write_text(",".join(cols) + "\n" + "\n".join(",".join(f"{x:.9f}" for x in r) for r in rows) + "\n")
    back = load_motion(path, activity="walk", height=1.75, floor=False, align=False,
                       **({} if form == "npz" else {"up": "z"}))
    for joint in ("LeftUpLeg", "RightUpLeg", "LeftLeg", "RightLeg", "LeftFoot", "RightFoot"):
        err = np.abs(back.positions[:, back.rig.index(joint)] - m.positions[:, m.rig.index(joint)]).max()
        assert err < 1e-3, (joint, err)
    for joint in ("LeftArm", "LeftForeArm", "LeftHand", "RightHand", "Head"):
        err = np.abs(back.positions[:, back.rig.index(joint)] - m.positions[:, m.rig.index(joint)]).max()
        assert err < 0.1, (joint, err)


def test_joint_positions_lacking_a_required_joint_are_one_line(tmp_path):
    p = tmp_path / "j.npz"
    np.savez(p, positions=np.zeros((3, 2, 3)), names=np.array(["left_hip", "right_hip"]), fps=30.0)
    with pytest.raises(MotionImportError, match=r"j\.npz: joint positions lack left_knee"):
        load_motion(p)
