"""Issue 39, groups 1 and 2 (importers): hostile ASF/AMC, OpenCap JSON and joint-position NPZ/CSV files are one
line naming the file (and line, frame, bone or field) with exit status 2, never a silently wrong import or a
"bug in rtchannel". Inputs are written by `synthetic_mocap` (no third-party data); each case failed before.

The angle bound is the BVH reader's (`source.MAX_ANGLE_DEG` = 1e5 deg, ~280 turns): unwrapped angles pass 360
deg, but not by this much; every importer now refuses what the BVH reader refuses.
"""
import io
import json
import zipfile

import numpy as np
import pytest

import synthetic_mocap as sm
from rtchannel.cli import main
from rtchannel.motion.asf_amc import read_amc, read_asf
from rtchannel.motion.errors import MotionImportError
from rtchannel.motion.load import load_motion
from rtchannel.motion.source import MAX_ANGLE_DEG


@pytest.fixture(autouse=True)
def no_simulation(monkeypatch):
    """Bad input must be refused while importing: a simulation starting fails the case at once."""
    import rtchannel.pipeline as pipeline

    def started(*a, **k):
        raise AssertionError("the simulation started although the input is invalid")

    monkeypatch.setattr(pipeline, "simulate", started)


def _one_line_exit_2(capsys, args) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


def _simulate(capsys, motion, *extra) -> str:
    return _one_line_exit_2(capsys, ["simulate", "--motion-file", str(motion), "--activity", "stand", "--quiet",
                                     "--no-plots", "--out", str(motion.parent / "out"), *map(str, extra)])


def test_the_synthetic_takes_import(tmp_path):
    """The good inputs the cases below corrupt: each imports as a 1.2-2.2 m person standing (head above the
    hips above the feet), so a refusal below is the corruption's, not the generator's."""
    amc, asf = sm.write_asf_amc(tmp_path)
    sm.write_opencap(tmp_path / "oc.json")
    names, pos = sm.standing_joints()
    np.savez(tmp_path / "j.npz", positions=pos, names=np.array(names), fps=60.0, up="z")
    (tmp_path / "j.csv").write_text(sm.joints_csv_text(names, pos))
    for path, extra in ((amc, {"skeleton": asf}), (tmp_path / "oc.json", {}), (tmp_path / "j.npz", {}),
                        (tmp_path / "j.csv", {"up": "z"})):
        m = load_motion(path, activity="stand", **extra)
        z = m.positions[0, :, 2]
        assert 1.2 <= m.rig.height <= 2.2, (path.name, m.rig.height)
        assert z[m.rig.index("Head")] > z[0] > z[m.rig.index("LeftFoot")], path.name


# ------------------------------------------------------------------ group 1: AMC takes imported silently wrong
def _amc(tmp_path, frames=None, text=None):
    amc, asf = sm.write_asf_amc(tmp_path, frames)
    if text is not None:
        amc.write_text(text)
    return amc, asf


def test_amc_bone_the_asf_lacks_is_an_error_naming_bone_line_and_frame(tmp_path, capsys):
    frames = sm.amc_frames()
    frames[5]["ltail"] = [1.0, 2.0]  # the take of another skeleton
    amc, asf = _amc(tmp_path, frames)
    with pytest.raises(MotionImportError, match=r"take\.amc, line \d+, frame 5: bone 'ltail' is not in the skeleton "
                                                r"actor\.asf"):
        read_amc(amc, read_asf(asf))
    assert "'ltail'" in _simulate(capsys, amc, "--skeleton", asf)


def test_amc_frame_lacking_a_bone_is_an_error_not_the_rest_pose(tmp_path, capsys):
    frames = sm.amc_frames()
    del frames[7]["lfemur"]
    amc, asf = _amc(tmp_path, frames)
    with pytest.raises(MotionImportError, match=r"frame 7: the frame lacks bone 'lfemur'$"):
        read_amc(amc, read_asf(asf))
    assert "lfemur" in _simulate(capsys, amc, "--skeleton", asf)
    frames = sm.amc_frames()
    for fr in frames:  # a bone missing from every frame is refused too: nothing is filled in
        fr.pop("lfingers")
    amc, asf = _amc(tmp_path, frames)
    with pytest.raises(MotionImportError, match=r"frame 0: the frame lacks bone 'lfingers'"):
        read_amc(amc, read_asf(asf))


def test_truncated_last_amc_frame_is_refused(tmp_path, capsys):
    text = sm.amc_text()
    amc, asf = _amc(tmp_path, text=text[:text.rfind("\nrtibia")] + "\n")  # the file cut inside the last frame
    n = len(sm.amc_frames())
    with pytest.raises(MotionImportError, match=rf"frame {n - 1}: the frame lacks bone .* \(the file ends inside it: "
                                                r"truncated\?\)"):
        read_amc(amc, read_asf(asf))
    assert "truncated" in _simulate(capsys, amc, "--skeleton", asf)


def test_amc_frames_out_of_order_are_refused(tmp_path):
    text = sm.amc_text().replace("\n5\n", "\n7\n", 1)  # a frame number skipped: frames lost
    amc, asf = _amc(tmp_path, text=text)
    with pytest.raises(MotionImportError, match=r"frame number 7 after 4"):
        read_amc(amc, read_asf(asf))


@pytest.mark.parametrize("bone, col, value", [("lfemur", 0, 1e7), ("lfemur", 2, 1e300), ("root", 4, 1e300),
                                              ("root", 3, -2 * MAX_ANGLE_DEG), ("root", 0, 1e300)])
def test_amc_values_beyond_the_bvh_bounds_are_refused(tmp_path, capsys, bone, col, value):
    frames = sm.amc_frames()
    frames[3][bone][col] = value
    amc, asf = _amc(tmp_path, frames)
    with pytest.raises(MotionImportError,
                       match=rf"frame 3: bone '{bone}': (angle|position) .* is not finite or beyond"):
        read_amc(amc, read_asf(asf))
    assert f"bone '{bone}'" in _simulate(capsys, amc, "--skeleton", asf)


def test_amc_angle_bound_is_the_bvh_bound_in_either_unit(tmp_path):
    """1e5 deg passes and 1.0001e5 deg fails, in degrees and (the AMC's :RADIANS) in radians."""
    for unit, scale in ((":DEGREES", 1.0), (":RADIANS", np.pi / 180)):
        for value, ok in ((MAX_ANGLE_DEG, True), (1.0001 * MAX_ANGLE_DEG, False)):
            frames = sm.amc_frames()
            frames[2]["ltibia"][0] = value * scale
            amc, asf = _amc(tmp_path, text=sm.amc_text(frames, header=f":FULLY-SPECIFIED\n{unit}\n"))
            if ok:
                root, values = read_amc(amc, read_asf(asf))
                assert values["ltibia"][2, 0] == pytest.approx(value, rel=1e-12)  # the skeleton's unit: degrees
            else:
                with pytest.raises(MotionImportError, match="beyond"):
                    read_amc(amc, read_asf(asf))


# ------------------------------------------------------------------ group 2: bad ASF files were "a bug" (exit 1)
ASF_CASES = [
    (dict(root_axis="XQZ"), r"line 9: malformed ASF \(axis order 'XQZ' is not a permutation of XYZ\)"),
    (dict(root_axis="XXY"), r"line 9: malformed ASF \(axis order 'XXY'"),
    (dict(root_order="TX TY TZ R RY RZ"), r"line 8: malformed ASF \(root order: .*got 'R'\)"),
    (dict(root_order="TX TY TZ RX RX RZ"), r"line 8: malformed ASF \(root order"),
    (("dof rx ry rz", "dof rx ry qq"), r"malformed ASF \(dof 'qq': channels are rx, ry, rz\)"),
    (("dof rx ry rz", "dof rx ry r"), r"malformed ASF \(dof 'r'"),
    (("dof rx ry rz", "dof rx tx"), r"malformed ASF \(dof 'tx': translation/length channels are not supported\)"),
    (("dof rx ry rz", "dof rx rx"), r"malformed ASF \(a dof channel is listed twice\)"),
    (("axis 0 0 0 XYZ", "axis 0 0 0 XYQ"), r"malformed ASF \(axis order 'XYQ'"),
    (("axis 0 0 0 XYZ", "axis 1e300 0 0 XYZ"), r"malformed ASF \(axis is not finite or beyond"),
    (("orientation 0 0 0", "orientation 0 1e300 0"), r"line 11: malformed ASF \(root orientation is not finite"),
    (("angle deg", "angle grad"), r"line 6: malformed ASF \(angle unit 'grad' is not deg or rad\)"),
    (("length 0.43", "length -0.43"), r"malformed ASF \(negative bone length\)"),
    (("length 0.43", "length 1e300"), r"malformed ASF \(length is not finite or beyond"),
    (("name lfoot", "name ltibia"), r"malformed ASF \(bone 'ltibia' is defined twice"),
]


@pytest.mark.parametrize("edit, message", ASF_CASES, ids=[m[:40] for _, m in ASF_CASES])
def test_malformed_asf_is_one_line_naming_the_line(tmp_path, capsys, edit, message):
    text = sm.asf_text(**edit) if isinstance(edit, dict) else sm.asf_text().replace(*edit, 1)
    amc, asf = sm.write_asf_amc(tmp_path)
    asf.write_text(text)
    with pytest.raises(MotionImportError, match=r"actor\.asf, " + (message if message.startswith("line") else
                                                                    r"line \d+: " + message)):
        read_asf(asf)
    assert "actor.asf, line" in _simulate(capsys, amc, "--skeleton", asf)


# ------------------------------------------------------------------ OpenCap JSON
def _opencap(tmp_path, doc=None, text=None):
    p = tmp_path / "take.json"
    p.write_text(text if text is not None else json.dumps(doc))
    return p


def test_deeply_nested_opencap_json_is_one_line(tmp_path, capsys):
    p = _opencap(tmp_path, text='{"time": ' + "[" * 100_000 + "]" * 100_000 + "}")
    assert "nested too deeply" in _simulate(capsys, p)


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.update(time=[t * 1e-9 for t in d["time"]]), r"time stamps give 1e\+11 frames/s, outside 1\.\.10000"),
    (lambda d: d["time"].__setitem__(-1, 1e300), r"the time stamps span 1e\+300 s, more than 3600 s"),
    (lambda d: d.update(time=[1e300 + t for t in d["time"]]), r"frame 1: time must increase"),
    (lambda d: d["time"].__setitem__(30, d["time"][30] + 0.003), r"frame 30: time steps are not uniform"),
    (lambda d: d["bodies"]["femur_l"]["rotation"].__setitem__(4, [1e300, 0, 0]),
     r"frame 4: body femur_l: rotation 1e\+300 is not finite or beyond \+-1745 rad"),
    (lambda d: d["bodies"]["pelvis"]["translation"].__setitem__(3, [0, 1e300, 0]),
     r"frame 3: body pelvis: translation 1e\+300 is not finite or beyond \+-100 m"),
])
def test_opencap_times_and_values_out_of_range_are_one_line(tmp_path, capsys, edit, message):
    doc = sm.opencap_doc()  # 100 Hz
    edit(doc)
    p = _opencap(tmp_path, doc)
    with pytest.raises(MotionImportError, match=r"take\.json, " + message if message.startswith("frame") else
                       r"take\.json: " + message):
        load_motion(p)
    _simulate(capsys, p)


# ------------------------------------------------------------------ joint positions (NPZ, CSV)
def _npz(tmp_path, **arrays):
    names, pos = sm.standing_joints()
    arrays = {"positions": pos, "names": np.array(names), "fps": 60.0, **arrays}
    p = tmp_path / "j.npz"
    np.savez(p, **arrays)
    return p


@pytest.mark.parametrize("arrays, message", [
    (dict(fps=np.array([60.0, 30.0])), r"fps must be a single number, got float64 \[2\]"),
    (dict(names=np.array("left_hip")), r"names must be 18 strings \(one per joint of positions\)"),
    (dict(units=np.array(["m", "cm"])), r"units must be a single value"),
    (dict(positions=np.array([["a"]])), r"positions must be numbers \[frames, joints, 3\]"),
    (dict(positions=np.zeros((60, 18, 3))), r"frame 0: the hips coincide or lie on the trunk's line"),
])
def test_bad_joint_npz_is_one_line(tmp_path, capsys, arrays, message):
    p = _npz(tmp_path, **arrays)
    with pytest.raises(MotionImportError, match=r"j\.npz(, frame 0)?: " + message.replace("frame 0: ", "")):
        load_motion(p)
    _simulate(capsys, p)


def _lying_npz(path, shape, extra_bytes: int = 2000):
    """An NPZ whose positions.npy header claims `shape` (float64) over `extra_bytes` of data."""
    from numpy.lib import format as npy

    names, _ = sm.standing_joints()
    head = io.BytesIO()
    npy.write_array_header_1_0(head, {"descr": "<f8", "fortran_order": False, "shape": shape})
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("positions.npy", head.getvalue() + b"\0" * extra_bytes)
        for key, value in (("names", np.array(names)), ("fps", np.array(60.0))):
            buf = io.BytesIO()
            np.save(buf, value)
            z.writestr(f"{key}.npy", buf.getvalue())


def test_npz_header_claiming_70_gib_is_refused_before_allocating(tmp_path, capsys):
    """A 2 kB member whose header claims 200 000 x 15 000 x 3 float64 (67 GiB): refused from the header, as
    is an honest header beyond the bounds (a zip bomb of zeros would have a matching size)."""
    p = tmp_path / "j.npz"
    _lying_npz(p, (200_000, 15_000, 3))
    assert p.stat().st_size < 8192
    with pytest.raises(MotionImportError, match=r"j\.npz: not a joint-position NPZ .*the array header disagrees"):
        load_motion(p)
    _simulate(capsys, p)
    q = tmp_path / "wide.npz"  # an honest header beyond the bounds: 1001 joints (the BVH reader's limit is 1000)
    np.savez(q, positions=np.zeros((2, 1001, 3)), names=np.array([f"j{k}" for k in range(1001)]), fps=60.0)
    with pytest.raises(MotionImportError, match=r"positions \[2, 1001, 3\]: 2\.\.200000 frames, 1\.\.1000 joints"):
        load_motion(q)


def test_joint_csv_coordinate_of_1e300_is_refused_before_any_arithmetic(tmp_path, capsys):
    names, pos = sm.standing_joints()
    pos[4, 1, 2] = 1e300
    p = tmp_path / "j.csv"
    p.write_text(sm.joints_csv_text(names, pos))
    with pytest.raises(MotionImportError, match=r"j\.csv, frame 4: right_hip is 1e\+300 m from the origin"):
        load_motion(p)
    _simulate(capsys, p)
    p.write_text(sm.joints_csv_text(names, np.zeros_like(pos)))  # all joints at one point: no body frame
    assert "coincide" in _simulate(capsys, p)
    p.write_text(sm.joints_csv_text(names, pos).splitlines()[0] + "\n")  # a header, no rows: no warning line
    assert "no data rows" in _simulate(capsys, p)


def test_joint_csv_time_must_be_uniform(tmp_path):
    names, pos = sm.standing_joints()
    lines = sm.joints_csv_text(names, pos).splitlines()
    cells = lines[11].split(",")
    cells[0] = repr(float(cells[0]) + 0.004)  # a quarter frame late at 60 Hz
    lines[11] = ",".join(cells)
    p = tmp_path / "j.csv"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(MotionImportError, match=r"frame 10: time steps are not uniform"):
        load_motion(p, up="z")
