"""Issue 39, groups 2-6 (commands): decompression-bomb images, dataset dry runs that try what they can,
placement of imported takes, YAML and scheduler addresses, and the smaller ones (ensemble outputs and members,
`dataset --info` on a damaged index, the data cache and links). The contract: bad input is one line on stderr
and exit status 2, good input gives valid output, nothing is written outside the output folder. Each case
failed before (exit 0 with a silently wrong result, or "internal error", exit 1).
"""
import hashlib
import struct
import zlib

import numpy as np
import pytest
import yaml
from test_data_registry import fake  # noqa: F401 - the registry fixture (mirror, cache, HTTP origin)

import synthetic_mocap as sm
from processing.errors import InputError
from rtchannel.cli import main


def _one_line_exit_2(capsys, args) -> str:
    assert main([str(a) for a in args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "internal error" not in err[0], err
    return err[0]


@pytest.fixture
def no_simulation(monkeypatch):
    """Refusals must come before any simulation: starting one fails the case."""
    import rtchannel.pipeline as pipeline

    def started(*a, **k):
        raise AssertionError("the simulation started although the input is invalid")

    monkeypatch.setattr(pipeline, "simulate", started)


# ------------------------------------------------------------------ group 2: a PNG claiming 40000 x 40000 pixels
def png_bomb(path, width: int = 40_000, height: int = 40_000) -> None:
    """A few hundred bytes of PNG whose header claims `width` x `height` 8-bit RGB pixels (4.8 GB decoded)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(bytes(4096), 9))
                     + chunk(b"IEND", b""))


@pytest.mark.parametrize("size", [(40_000, 40_000), (10_000, 10_000), (6_000, 6_000)])
def test_image_size_is_bounded_before_decoding(tmp_path, size):
    """40000^2 trips PIL's own error, 10000^2 its warning (which would be a second stderr line), 6000^2 (36 MP)
    only the project's bound of 2^25 pixels."""
    from processing.realdata.spectrogram_image import MAX_IMAGE_PIXELS, SpectrogramImageError, load_rgb

    p = tmp_path / "1P01A01R01.png"
    png_bomb(p, *size)
    assert p.stat().st_size < 1000 and size[0] * size[1] > MAX_IMAGE_PIXELS
    with pytest.raises(SpectrogramImageError, match=r"1P01A01R01\.png: .*exceeds the 33554432 pixels"):
        load_rgb(p)


@pytest.mark.parametrize("command", ["evaluate", "robustness"])
def test_decompression_bomb_in_images_is_one_line(model_path, tmp_path, capsys, command):
    folder = tmp_path / "imgs"
    folder.mkdir()
    png_bomb(folder / "1P01A01R01.png")
    extra = ["--quick"] if command == "robustness" else []
    line = _one_line_exit_2(capsys, [command, "--model", model_path, "--images", folder, "--out", tmp_path / "o",
                                     *extra])
    assert "pixels" in line


# ------------------------------------------------------------------ group 3: dataset --dry-run tries what it can
def _plan(tmp_path, sources, **motion) -> str:
    amc, asf = sm.write_asf_amc(tmp_path)
    names, pos = sm.standing_joints()
    np.savez(tmp_path / "j.npz", positions=pos, names=np.array(names), fps=60.0, up="z")
    p = tmp_path / "plan.yaml"
    p.write_text(yaml.safe_dump({"name": "t", "motion": {"sources": sources, **motion}}))
    return str(p)


@pytest.mark.parametrize("source, message", [
    ({"files": "take.amc", "activity": "pick"}, r"motion\.sources\.0: take\.amc: an \.amc motion needs its ASF"),
    ({"files": "j.npz", "activity": "pick", "options": {"skeleton": "actor.asf"}},
     r"motion\.sources\.0: j\.npz: an \.amc motion needs .* only an \.amc motion takes one"),
    ({"files": "j.npz", "activity": "pick", "trim": [0.8, 0.2]}, r"trim \[0\.8, 0\.2\]: need 0 <= START < END"),
    ({"files": "j.npz", "activity": "pick", "trim": [-0.5, 0.5]}, r"trim \[-0\.5, 0\.5\]: need 0 <= START < END"),
    ({"files": "j.npz", "activity": "pick", "trim": [50, None]}, r"j\.npz: trim starts at 50 s, after the take's end"),
    ({"files": "j.npz", "activity": "pick", "trim": [0.5, 0.51]},
     r"j\.npz: trim \(0\.5, 0\.51\) s leaves fewer than two"),
    ({"files": "take.amc", "activity": "pick", "options": {"skeleton": 5}}, r"options\.skeleton: expected str"),
    ({"files": "j.npz", "activity": "pick", "options": {"max_gap_s": 1.0}}, r"max_gap_s and on_long_gap apply to C3D"),
])
def test_dry_run_refuses_plans_whose_items_would_all_fail(tmp_path, capsys, no_simulation, source, message):
    import re

    line = _one_line_exit_2(capsys, ["dataset", "--config", _plan(tmp_path, [source]), "--dry-run"])
    assert re.search(message, line), line
    assert not (tmp_path / "out").exists()


def test_dry_run_loads_each_motion_file_once_and_accepts_a_good_plan(tmp_path, capsys, no_simulation, monkeypatch):
    from rtchannel.motion import load

    calls = []
    real = load.load_motion
    monkeypatch.setattr(load, "load_motion", lambda *a, **k: calls.append(a[0]) or real(*a, **k))
    plan = _plan(tmp_path, [{"files": "take.amc", "activity": "pick", "options": {"skeleton": "actor.asf"}},
                            {"files": "j.npz", "activity": "sit", "trim": [0.1, 0.8]},
                            {"files": "j.npz", "activity": "stand", "trim": [0.2, None]}],
                 headings_deg=[0, 90])
    assert main(["dataset", "--config", plan, "--dry-run"]) == 0
    assert "motion files: 2 loaded and checked" in capsys.readouterr().out
    assert sorted(p.name for p in calls) == ["j.npz", "take.amc"]  # j.npz once for its two sources


def test_dry_run_refuses_a_motion_file_that_does_not_load(tmp_path, capsys, no_simulation):
    plan = _plan(tmp_path, [{"files": "j.npz", "activity": "walk"}])
    names, pos = sm.standing_joints()
    pos[3, 0, 0] = 1e300
    np.savez(tmp_path / "j.npz", positions=pos, names=np.array(names), fps=60.0)
    line = _one_line_exit_2(capsys, ["dataset", "--config", plan, "--dry-run"])
    assert "motion.sources.0: j.npz:" in line and "frame 3" in line


# ------------------------------------------------------------------ group 4: placement of imported takes
@pytest.mark.parametrize("args, needle", [
    (["--start", "1e6", "0"], "--start: 1e+06 0 m"), (["--start", "150", "0"], "--start: 150 0 m"),
    (["--heading", "1e300"], "--heading: 1e+300 deg is outside +-3600 deg"),
    (["--speed", "2"], "--speed applies to a procedural activity"),
    (["--duration", "3"], "--duration applies to a procedural activity"),
])
def test_imported_take_placement_is_checked_as_procedural(tmp_path, capsys, no_simulation, args, needle):
    names, pos = sm.standing_joints()
    np.savez(tmp_path / "j.npz", positions=pos, names=np.array(names), fps=60.0, up="z")
    line = _one_line_exit_2(capsys, ["simulate", "--motion-file", tmp_path / "j.npz", "--activity", "stand",
                                     "--out", tmp_path / "o", *args])
    assert needle in line


def test_frame_rate_of_a_take_is_bounded_as_a_procedural_one(tmp_path, capsys, no_simulation):
    """--fps 5000 is refused for a procedural motion (ProceduralParams: 10..2000 Hz): so for a motion file,
    before the take is read (1e300 Hz asked for 1e300 frames, 1e-300 Hz said "a Motion needs two frames")."""
    names, pos = sm.standing_joints()
    np.savez(tmp_path / "j.npz", positions=pos, names=np.array(names), fps=60.0, up="z")
    for fps in ("5000", "1e300", "1e-300"):
        line = _one_line_exit_2(capsys, ["simulate", "--motion-file", tmp_path / "j.npz", "--activity", "stand",
                                         "--fps", fps, "--out", tmp_path / "o"])
        assert "--fps:" in line and "outside 10..2000 Hz" in line


def test_chair_is_refused_for_the_points_backend(tmp_path, capsys, no_simulation):
    line = _one_line_exit_2(capsys, ["simulate", "--activity", "sit", "--chair", "none", "--out", tmp_path / "o"])
    assert "--chair applies to the mesh backends" in line


def test_people_filter_with_a_huge_number_is_one_line(tmp_path, capsys):
    """Python refuses int() of more than 4300 digits with a plain ValueError (a bug report before)."""
    from processing.realdata.real_images import RealImageError, parse_people, read_labels_csv

    with pytest.raises(RealImageError, match="bad --people part"):
        parse_people("P" + "9" * 5000)
    labels = tmp_path / "labels.csv"
    labels.write_text("file,activity,subject\na.png,walk,P" + "9" * 5000 + "\n")
    with pytest.raises(RealImageError, match="is not like P36 or 36"):
        read_labels_csv(labels)


@pytest.mark.parametrize("option", ["--up y", "--skeleton actor.asf"])
def test_options_of_motion_files_are_refused_for_procedural_activities(tmp_path, capsys, no_simulation, option):
    name, value = option.split()
    line = _one_line_exit_2(capsys, ["simulate", "--activity", "walk", name, tmp_path / value if name == "--skeleton"
                                     else value, "--out", tmp_path / "o"])
    assert f"{name} applies to --motion-file" in line


@pytest.mark.parametrize("motion, needle", [({"headings_deg": [1e300]}, "heading 1e+300 deg outside"),
                                            ({"starts": [[150, 0]]}, "start coordinate 150.0 m outside")])
def test_plan_placement_is_bounded(tmp_path, capsys, no_simulation, motion, needle):
    plan = _plan(tmp_path, [{"procedural": "walk"}], **motion)
    assert needle in _one_line_exit_2(capsys, ["dataset", "--config", plan, "--dry-run"])


def test_dry_run_refuses_starts_outside_the_mesh_backends_room(tmp_path, capsys, no_simulation):
    plan = _plan(tmp_path, [{"procedural": "walk"}], starts=[[0, 0], [5, 0]])
    line = _one_line_exit_2(capsys, ["dataset", "--config", plan, "--backend", "facets", "--dry-run"])
    assert "motion.starts [5.0, 0.0] puts the person outside the facets backend's room" in line
    assert main(["dataset", "--config", plan, "--dry-run"]) == 0  # points: free space


@pytest.fixture
def no_tracing(monkeypatch):
    import rtchannel.pipeline as pipeline

    def traced(*a, **k):
        raise AssertionError("the backend ran although the person is outside the room")

    monkeypatch.setattr(pipeline, "backend_function", lambda name: traced)


def test_walker_outside_the_room_is_refused_before_tracing(tmp_path, capsys, no_tracing):
    """The default room's walls are at x, y = +-4 m (scenes/room.xml); a walk started at x = 5 m is outside, one
    centred on the origin is inside, and a room:... scene uses its own bounds."""
    from rtchannel import Motion
    from rtchannel.assets import scenes_dir
    from rtchannel.pipeline import trace
    from rtchannel.scene.rooms import DEFAULT_ROOM

    xml = (scenes_dir() / "room.xml").read_text()
    for wall in ('translate x="4"', 'translate x="-4"', 'translate y="4"', 'translate y="-4"', 'scale x="1.5" y="4"'):
        assert wall in xml  # the bounds below are this file's
    assert DEFAULT_ROOM == (-4.0, 4.0, -4.0, 4.0, 3.0)
    outside = Motion.procedural("walk", start=(5.0, 0.0), seed=0)
    with pytest.raises(InputError, match=r"scene room: the person is outside the room's walls \(x -4\.\.4 m"):
        trace(outside, backend="facets")
    with pytest.raises(InputError,
                       match=r"scene room:-10,-6,-2,2,3: the person is outside the room.s walls \(x -10\.\.-6 m"):
        trace(Motion.procedural("walk", seed=0), backend="sionna", scene="room:-10,-6,-2,2,3")
    with pytest.raises(AssertionError, match="the backend ran"):  # inside: checked, then traced
        trace(Motion.procedural("walk", seed=0), backend="facets")
    line = _one_line_exit_2(capsys, ["simulate", "--activity", "walk", "--start", "5", "0", "--backend", "facets",
                                     "--out", tmp_path / "o", "--no-plots", "--quiet"])
    assert "outside the room's walls" in line and not (tmp_path / "o" / "signature.h5").exists()


# ------------------------------------------------------------------ group 5: YAML and addresses
def test_malformed_crossval_plan_is_one_line_without_its_content(tmp_path, capsys):
    plan = tmp_path / "cv.yaml"
    plan.write_text("experiments:\n  - name: a\n    train: [secret-content\n")
    line = _one_line_exit_2(capsys, ["crossval", "--plan", plan, "--out", tmp_path / "cv.csv"])
    assert "crossval plan" in line and "line 4" in line and "secret" not in line
    plan.write_text("experiments:\n  - {name: ../../escape, train: d, test: d}\n")
    assert "name must be 1-64 letters" in _one_line_exit_2(capsys, ["crossval", "--plan", plan, "--out",
                                                                    tmp_path / "cv.csv"])
    plan.write_text("experiments:\n  - {name: a, train: d, test: d}\n  - {name: a, train: e, test: e}\n")
    assert "distinct" in _one_line_exit_2(capsys, ["crossval", "--plan", plan, "--out", tmp_path / "cv.csv"])


def test_deeply_nested_option_value_is_one_line(tmp_path, capsys, no_simulation):
    """--option values are parsed as YAML: a run of '[' was a RecursionError (the plan and radar readers bound
    their nesting; a single value needs none)."""
    line = _one_line_exit_2(capsys, ["simulate", "--activity", "fall", "--out", tmp_path / "o", "--option",
                                     "trajectories=" + "[" * 5000])
    assert "nested too deeply" in line


@pytest.mark.parametrize("address", ["bogus://x", "tcp://host:99999", "tcp://"])
def test_bad_scheduler_address_is_one_line_before_any_work(tmp_path, capsys, address):
    line = _one_line_exit_2(capsys, ["dataset", "--config", "seed", "--out", tmp_path / "ds", "--scheduler", address,
                                     "--quiet"])
    assert "not a Dask scheduler address" in line and not (tmp_path / "ds").exists()


# ------------------------------------------------------------------ group 6: smaller ones
def _clf(seed: int):
    import torch

    from processing.classifier import Classifier, ModelConfig, PreprocessConfig, build_model
    from processing.io.dataset_store import ACTIVITIES

    torch.manual_seed(seed)
    model = build_model(ModelConfig(input_size=(16, 16), padding="same", channels=(4, 4), mlp_hidden=8))
    model.eval()
    return Classifier(model=model, preprocess=PreprocessConfig(n_velocity=16, n_time=16), classes=list(ACTIVITIES),
                      links=["radar1", "radar2"], meta={"train_config": {"seed": seed}})


def test_ensemble_out_folder_and_a_member_given_twice(tmp_path, capsys):
    from processing.classifier import save_checkpoint

    a, b = (save_checkpoint(tmp_path / f"{n}.pt", _clf(s)) for n, s in (("a", 0), ("b", 1)))
    folder = tmp_path / "models"
    folder.mkdir()
    line = _one_line_exit_2(capsys, ["ensemble", "--models", a, b, "--out", folder])
    assert "is a folder" in line and not (tmp_path / "models.pt").exists() and not any(folder.iterdir())
    assert main(["ensemble", "--models", str(a), str(b), "--out", str(tmp_path / "ab.pt")]) == 0
    capsys.readouterr()
    line = _one_line_exit_2(capsys, ["ensemble", "--models", tmp_path / "ab.pt", a, "--out", tmp_path / "e.pt"])
    assert "holds the same network" in line and "count twice" in line and not (tmp_path / "e.pt").exists()
    # train and crossval name their outputs the same way
    assert "is a folder" in _one_line_exit_2(capsys, ["train", "--data", tmp_path, "--out", folder])
    assert "is a folder" in _one_line_exit_2(capsys, ["crossval", "--train", "x", "--test", "x", "--out", folder])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.pt", "ab.pt", "b.pt", "models"]


def test_dataset_info_on_a_corrupt_index_exits_2(tmp_path, capsys):
    ds = tmp_path / "ds"
    (ds / "shards").mkdir(parents=True)
    (ds / "index.jsonl").write_text('{"not": "an entry"}\n{"item_id": "x"}\n')
    line = _one_line_exit_2(capsys, ["dataset", "--info", ds])
    assert "is damaged" in line


def test_data_cache_never_writes_through_a_link(fake, monkeypatch, tmp_path):  # noqa: F811
    """fetch_folder copies a mirror file into the cache: a link planted in the file's place is replaced (the
    file it pointed to is untouched); a link planted as a folder of the cache is refused."""
    from rtchannel import data_registry as reg

    origin, mirror, cache, files = fake
    extra = "realdata/x/2P1A02R01.png"
    data = b"\x89PNG other"
    (origin / extra).write_bytes(data)
    entries = dict(reg.registry())
    url = entries["realdata/x/1P1A01R01.png"].url.replace("1P1A01R01", "2P1A02R01")
    entries[extra] = reg.Entry(extra, hashlib.sha256(data).hexdigest(), len(data), url, "CC0 (test)")
    monkeypatch.setattr(reg, "registry", lambda: entries)
    (mirror / "realdata/x").mkdir(parents=True)
    (mirror / "realdata/x/1P1A01R01.png").write_bytes(files["realdata/x/1P1A01R01.png"])
    victim = tmp_path / "victim.txt"
    victim.write_bytes(b"precious")
    (cache / "realdata/x").mkdir(parents=True)
    (cache / "realdata/x/1P1A01R01.png").symlink_to(victim)
    folder = reg.fetch_folder("realdata/x")
    assert victim.read_bytes() == b"precious"
    link = folder / "1P1A01R01.png"
    assert not link.is_symlink() and link.read_bytes() == files["realdata/x/1P1A01R01.png"]
    outside = tmp_path / "outside"
    outside.mkdir()
    for p in list((cache / "realdata/x").iterdir()):
        p.unlink()
    (cache / "realdata/x").rmdir()
    (cache / "realdata").rmdir()
    (cache / "realdata").symlink_to(outside, target_is_directory=True)
    with pytest.raises(InputError, match=r"data cache: .*realdata is a symbolic link"):
        reg.fetch_folder("realdata/x")
    assert not any(outside.iterdir())
