import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from rtchannel.cli import main

COMMANDS = ["simulate", "render", "bench", "compare", "dataset", "train", "evaluate", "crossval", "robustness", "data"]


def test_help_for_every_command(capsys):
    assert main(["--help"]) == 0
    for cmd in COMMANDS:
        assert main([cmd, "--help"]) == 0
        assert cmd in capsys.readouterr().out


def _one_error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


@pytest.mark.parametrize("yaml_text, field", [
    ("waveform:\n  pri_s: -0.0005\n", "pri_s"),
    ("waveform:\n  adc_rate_hz: 1000\n", "adc_rate_hz"),
    ("links:\n  - {name: r1, tx: [1, 2]}\n", "links.0.tx"),
    ("dsp:\n  range_sum: sideways\n", "dsp.range_sum"),
])
def test_bad_radar_config_is_one_line_exit_2(tmp_path, capsys, yaml_text, field):
    cfg = tmp_path / "radar.yaml"
    cfg.write_text(yaml_text)
    assert main(["simulate", "--out", str(tmp_path / "o"), "--radar-config", str(cfg), "--quiet"]) == 2
    assert field in _one_error_line(capsys)


@pytest.mark.parametrize("args, needle", [
    (["--activity", "dance"], "dance"),
    (["--height", "-1"], "height"),
    (["--direction", "19"], "direction"),
    (["--radar-config", "/nonexistent.yaml"], "not found"),
    (["--activity", "sit", "--fall-direction", "backward"], "--fall-direction"),
    (["--activity", "fall", "--fall-direction", "down"], "fall-direction"),
    (["--motion-file", "/nonexistent.bvh", "--fall-direction", "left"], "procedural fall"),
])
def test_bad_arguments_are_one_line_exit_2(tmp_path, capsys, args, needle):
    assert main(["simulate", "--out", str(tmp_path), "--quiet", *args]) == 2
    assert needle in _one_error_line(capsys)


def test_simulate_writes_signature_file_and_plots(tmp_path):
    out = tmp_path / "walk"
    assert main(["simulate", "--activity", "walk", "--out", str(out), "--direction", "11", "--seed", "3",
                 "--duration", "2.0", "--quiet", "--keep-iq"]) == 0
    with h5py.File(out / "signature.h5") as f:
        assert f.attrs["activity"] == "walk" and f.attrs["backend"] == "points"
        assert f.attrs["seed"] == 3 and f.attrs["direction_deg"] == -160.0
        assert "motion" in f.attrs["config"] and "waveform" in f.attrs["config"]
        assert set(f) == {"radar1", "radar2"}
        g = f["radar1"]
        nv, nt = g["p_vt"].shape
        assert g["velocity"].shape == (nv,) and g["time"].shape == (nt,) and g["mean_velocity"].shape == (nt,)
        assert g["range_distribution"].shape == (g["range"].shape[0], nt)
        assert g["iq"].shape[1] == 128 and np.isfinite(g["p_vt"][()]).all()
    for png in ("pvt.png", "mean_velocity.png", "range.png", "range_doppler.png"):
        assert (out / png).stat().st_size > 10_000


def test_fall_direction_reaches_the_stored_motion(tmp_path):
    import json

    out = tmp_path / "fall"
    assert main(["simulate", "--activity", "fall", "--fall-direction", "backward", "--out", str(out), "--quiet",
                 "--no-plots"]) == 0
    with h5py.File(out / "signature.h5") as f:
        assert json.loads(f.attrs["config"])["motion"]["fall_direction"] == "backward"


def test_console_script_entry_point(tmp_path):
    r = subprocess.run([sys.executable, "-m", "rtchannel.cli", "simulate", "--out", str(tmp_path),
                        "--activity", "nope", "--quiet"], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "nope" in r.stderr


def test_simulate_motion_capture_file(tmp_path, shared_data):
    out = tmp_path / "mocap"
    bvh = shared_data("mocap/cmu/walk/07_02_iclone.bvh")
    assert main(["simulate", "--motion-file", str(bvh), "--start", "-2", "0", "--out", str(out),
                 "--quiet", "--no-plots"]) == 0
    with h5py.File(out / "signature.h5") as f:
        mv = f["radar1"]["mean_velocity"][()]
        # a 1.2-1.5 m/s walk straight toward Radar 1: the body's mean radial velocity is positive
        assert 0.8 < np.median(mv) < 1.8
        assert "07_02" in f.attrs["config"]


def test_missing_motion_file_is_one_line(tmp_path, capsys):
    assert main(["simulate", "--motion-file", str(tmp_path / "x.bvh"), "--out", str(tmp_path), "--quiet"]) == 2
    assert "not found" in _one_error_line(capsys)


def test_render_writes_scene_png(tmp_path):
    out = tmp_path / "scene.png"
    assert main(["render", "--activity", "sit", "--out", str(out), "--frames", "0", "60", "--lod", "2k"]) == 0
    assert out.stat().st_size > 20_000


def test_render_cuts_away_walls_facing_the_camera():
    from rtchannel.scene.render import _static_geometry

    # camera outside the room beyond x = 4 m and y = -4 m: those two walls go, floor and two walls stay
    kept = _static_geometry("room", 1.75, 24.125e9, np.array([10.0, -10.0, 5.0]))
    assert len(kept) == 3
    flat = [g for g in kept if np.ptp(g[0][:, 2]) < 1e-6]
    assert len(flat) == 1  # the floor
    walls = [g[0] for g in kept if np.ptp(g[0][:, 2]) > 1e-6]
    assert sorted(round(float(np.mean(v[:, 0])), 3) for v in walls) == [-4.0, 0.0]  # x = -4 wall, y = +4 wall


def test_compare_accepts_comma_separated_backends(tmp_path):
    out = tmp_path / "cmp"
    assert main(["compare", "--backends", "points,points", "--activities", "fall", "--out", str(out), "--quiet"]) == 0
    assert (out / "dtw_points_vs_points.csv").is_file() and (out / "table_points_vs_points.md").is_file()


# --- issue 13: every user-error type reaches the command line as one line and exit status 2
def test_user_error_types_are_one_line_exit_2(tmp_path, capsys, shared_data):
    from rtchannel.errors import USER_ERRORS, ConfigError, SceneFileError
    from processing.errors import CheckpointError, DatasetFormatError, InputError, TrainingError
    from processing.realdata.ancortek import AncortekFormatError
    from rtchannel.motion.errors import MotionImportError

    for cls in (ConfigError, SceneFileError, CheckpointError, DatasetFormatError, TrainingError, AncortekFormatError):
        assert issubclass(cls, InputError) and issubclass(cls, USER_ERRORS)
    assert isinstance(MotionImportError("x.bvh", "bad", line=3), USER_ERRORS)
    take = tmp_path / "take.bvh"
    text = shared_data("mocap/cmu/sit/75_17.bvh").read_text()
    take.write_text(text.replace("Frame Time: 0.0333332", "Frame Time: 1e300", 1))
    assert main(["simulate", "--motion-file", str(take), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    line = _one_error_line(capsys)
    assert "take.bvh, line" in line and "frame time 1e300" in line


def test_resampling_a_motion_file_to_an_absurd_rate_is_refused(tmp_path, capsys, shared_data):
    take = shared_data("mocap/cmu/sit/75_17.bvh")
    assert main(["simulate", "--motion-file", str(take), "--fps", "1e6", "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "fps: " in _one_error_line(capsys)


def test_output_path_under_a_file_is_one_line(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    args = ["simulate", "--activity", "fall", "--duration", "0.9", "--out", str(blocker / "out"), "--quiet",
            "--no-plots"]
    assert main(args) == 2
    assert str(blocker) in _one_error_line(capsys)


def test_scene_outside_sandbox_is_one_line(tmp_path, capsys):
    scene = tmp_path / "s.xml"
    scene.write_text('<scene version="2.1.0"><include filename="/etc/passwd"/></scene>')
    args = ["simulate", "--backend", "facets", "--scene", str(scene), "--activity", "fall", "--duration", "0.9",
            "--out", str(tmp_path / "o"), "--quiet", "--no-plots"]
    assert main(args) == 2
    line = _one_error_line(capsys)
    assert "points outside the scene's folder" in line and "root:" not in line


@pytest.mark.parametrize("args, needle", [
    (["simulate", "--activity", "fall", "--seed", str(2**70)], "seed"),  # ProceduralParams: stored as int64
    (["train", "--data", "nowhere", "--floor-db", "inf"], "floor_db"),  # PreprocessConfig: finite only
])
def test_fixed_argument_bounds(tmp_path, capsys, args, needle):
    assert main([*args, "--out", str(tmp_path / "o")]) == 2
    assert needle in _one_error_line(capsys)


def test_recording_shorter_than_one_window_writes_nothing(tmp_path, capsys):
    """Last guard (issue 13, 6): an empty signature is never written with exit 0."""
    cfg = tmp_path / "radar.yaml"
    cfg.write_text("dsp:\n  window_chirps: 4096\n")  # 2 s of chirps at 0.5 ms; the motion lasts ~1.3 s
    args = ["simulate", "--activity", "fall", "--duration", "0.9", "--radar-config", str(cfg), "--out",
            str(tmp_path / "o"), "--quiet", "--no-plots"]
    assert main(args) == 2
    assert "no complete DSP window" in _one_error_line(capsys) and not (tmp_path / "o" / "signature.h5").exists()


def test_console_script_ends_simulate_at_once(monkeypatch, tmp_path):
    # `run` (the console script) skips interpreter finalisation after `simulate` only (os._exit, after
    # flushing); other commands and library calls of `main` end normally.
    import rtchannel.cli as cli

    ended = []
    monkeypatch.setattr(cli.os, "_exit", ended.append)
    assert cli.run(["simulate", "--out", str(tmp_path), "--activity", "nope", "--quiet"]) == 2
    assert ended == [2]
    ended.clear()
    assert cli.run(["simulate", "--help"]) == 0 and ended == [0]
    ended.clear()
    assert cli.run(["bench", "--help"]) == 0 and ended == []


def test_console_script_flushes_before_ending(tmp_path):
    # Every line the command printed reaches a pipe, and the outputs are complete, despite os._exit.
    out = tmp_path / "walk"
    r = subprocess.run([sys.executable, "-m", "rtchannel.cli", "simulate", "--duration", "1.0", "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    wrote = [line.split(" ", 1)[1] for line in r.stdout.splitlines() if line.startswith("wrote ")]
    assert [Path(w).name for w in wrote] == ["signature.h5", "pvt.png", "mean_velocity.png", "range.png",
                                             "range_doppler.png"]
    with h5py.File(out / "signature.h5") as f:
        assert f["radar2"]["p_vt"].shape[1] == f["radar2"]["time"].shape[0] > 0


def _break_simulate(monkeypatch, exc):
    import rtchannel.cli.simulate as sim

    def boom(args):
        raise exc
    monkeypatch.setattr(sim, "cmd_simulate", boom)


def test_internal_errors_are_bugs_exit_1_with_traceback_on_request(tmp_path, capsys, monkeypatch):
    """Only user errors are exit 2; a library's own ValueError (a numpy shape bug, say) is a bug: one line
    saying so and exit 1, or the traceback with --debug / RTCHANNEL_DEBUG=1."""
    _break_simulate(monkeypatch, ValueError("operands could not be broadcast together with shapes (3,) (4,)"))
    assert main(["simulate", "--out", str(tmp_path / "o")]) == 1
    line = _one_error_line(capsys)
    assert "internal error" in line and "ValueError" in line and "--debug" in line
    with pytest.raises(ValueError, match="broadcast"):
        main(["--debug", "simulate", "--out", str(tmp_path / "o")])
    monkeypatch.setenv("RTCHANNEL_DEBUG", "1")
    with pytest.raises(ValueError, match="broadcast"):
        main(["simulate", "--out", str(tmp_path / "o")])


def test_user_errors_stay_exit_2_and_llvm_missing_is_one_of_them(tmp_path, capsys, monkeypatch):
    from processing.errors import InputError
    from rtchannel.scene.llvm import LLVMNotFoundError

    assert issubclass(LLVMNotFoundError, InputError)
    _break_simulate(monkeypatch, LLVMNotFoundError("no usable libLLVM (>= 16) found for Dr.Jit: install LLVM"))
    assert main(["simulate", "--out", str(tmp_path / "o")]) == 2
    assert "libLLVM" in _one_error_line(capsys)


@pytest.mark.parametrize("argv,words", [
    (["render", "--out", "{t}/r.png", "--strip", "{t}/x.mp4"], ["x.mp4", "'.mp4'", ".gif"]),
    (["render", "--out", "{t}/r.bmp"], ["r.bmp", "'.bmp'", ".png"]),
])
def test_output_formats_decided_by_extension_are_refused_up_front(argv, words, tmp_path, capsys):
    """A file's name says what it holds: an extension the writer cannot produce is one line before any
    rendering, and nothing is written."""
    argv = [a.replace("{t}", str(tmp_path)) for a in argv]
    assert main(argv) == 2
    line = _one_error_line(capsys)
    assert all(w in line for w in words), line
    assert list(tmp_path.iterdir()) == []
