"""The public Python API: the example script equals the CLI, the walkthrough runs, the nouns behave."""
import importlib.util
import re
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest

import rtchannel
from rtchannel import Motion, Radar, Scene, simulate
from rtchannel.cli import main

REPO = Path(__file__).resolve().parents[1]


def _load_example(name: str):
    spec = importlib.util.spec_from_file_location(name, REPO / "examples" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_api_example_equals_the_cli(tmp_path):
    api_file = _load_example("simulate_walk").main(tmp_path / "api")
    assert main(["simulate", "--activity", "walk", "--backend", "points", "--direction", "1", "--seed", "0",
                 "--out", str(tmp_path / "cli"), "--quiet", "--no-plots"]) == 0
    assert (tmp_path / "api" / "pvt.png").is_file()
    with h5py.File(api_file) as a, h5py.File(tmp_path / "cli" / "signature.h5") as c:
        assert sorted(a) == sorted(c) == ["radar1", "radar2"]
        for link in a:
            for key in ("p_vt", "mean_velocity", "range_distribution", "velocity", "time"):
                np.testing.assert_array_equal(a[link][key][()], c[link][key][()], err_msg=f"{link}/{key}")
        for key in ("activity", "backend", "seed", "direction_deg"):
            assert a.attrs[key] == c.attrs[key]


def _python_blocks(md: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", md.read_text(), flags=re.S)


def test_walkthrough_runs(capsys, shared_data):
    shared_data("mocap/cmu/sit/75_17.bvh")  # the walkthrough imports a CMU take through the data registry
    blocks = _python_blocks(REPO / "docs" / "walkthrough.md")
    assert len(blocks) >= 5
    namespace: dict = {}
    for k, code in enumerate(blocks):
        exec(compile(code, f"walkthrough block {k + 1}", "exec"), namespace)  # noqa: S102 - our own docs
    out = capsys.readouterr().out
    assert "hips from" in out and "facets:" in out
    text = (REPO / "docs" / "walkthrough.md").read_text()
    # the tour follows the top-level API: trace -> synthesise -> process, nothing imported from deep paths
    assert all(f"{step}(" in text for step in ("trace", "synthesise", "process"))
    assert not re.findall(r"^\s*(?:from|import) (?:processing|rtchannel\.)", "\n".join(blocks), flags=re.M)


def test_examples_never_write_into_the_checkout(tmp_path, monkeypatch):
    """Run with no arguments, the example writes into a new temporary folder; no example names an output path
    inside the repository."""
    import tempfile

    for f in (REPO / "examples").glob("*.py"):
        text = f.read_text()
        assert "docs/img" not in text and '"out/' not in text and "__file__" not in text, f.name
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # where mkdtemp makes the default folder
    written = _load_example("simulate_walk").main()
    assert written.is_relative_to(tmp_path) and written.is_file()


def test_lazy_exports_and_radar_presets():
    assert set(rtchannel.__all__) >= {"Motion", "Radar", "Scene", "simulate", "load_signatures"}
    with pytest.raises(AttributeError):
        rtchannel.nope  # noqa: B018
    r = Radar.seed(direction=11)
    assert r.orientation_deg == -160.0
    np.testing.assert_allclose(r.links[0].tx, (3 * np.cos(np.radians(-160)), 3 * np.sin(np.radians(-160)), 1.1),
                               atol=1e-12)
    mono = Radar.monostatic((1.0, 2.0, 1.5), name="x")
    assert [lk.name for lk in mono.links] == ["x"] and mono.links[0].monostatic


def test_scene_description_and_points_warning():
    assert Scene.room().xml_path().name == "room.xml" and Scene.free_space().name == "free_space"
    with pytest.raises(ValueError, match="neither"):
        Scene("no_such_scene").xml_path()
    m = Motion.procedural("pick", seed=1)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = simulate(m, Radar.seed(), backend="points", scene=Scene.room())
    assert any("free-space model" in str(w.message) for w in caught)
    assert res.config["backend"] == "points" and res.config["activity"] == "pick"


def test_walk_centring_follows_heading():
    m = Motion.procedural("walk", heading_deg=90.0, distance=3.0)
    hips = m.positions[:, 0, :2]
    # centred on the origin along +y: starts near y = -1.5 m, ends near y = +1.5 m (+ the last stride)
    assert abs(hips[0, 1] + 1.5) < 1e-9 and abs(hips[0, 0]) < 1e-9
    assert 1.2 < hips[-1, 1] < 2.5 and abs(hips[-1, 0]) < 0.1


def test_trace_then_synthesise_is_simulate_and_keeps_the_channel():
    import numpy as np

    from processing.errors import InputError
    from rtchannel import PathSets, Radar, trace, synthesise

    motion = Motion.procedural("fall", height=1.7, seed=3)
    radar = Radar.seed(direction=1)
    channel = trace(motion, radar, backend="points")
    assert isinstance(channel, PathSets) and set(channel) == {lk.name for lk in radar.links}
    assert channel["radar1"].delays.shape[0] == motion.n_frames  # one row of delays per animation frame
    a, b = simulate(motion, radar, backend="points"), synthesise(channel)
    for name in a.signatures:
        assert np.array_equal(a.signatures[name].p_vt, b.signatures[name].p_vt)
    assert a.config == b.config
    moved = Radar.seed(direction=2)  # other antenna positions: the channel does not hold them
    with pytest.raises(InputError, match="trace again"):
        synthesise(channel, moved)


def test_activities_have_one_home():
    from processing.io import dataset_store
    from processing.labels import ACTIVITIES
    from rtchannel.motion import activities, procedural

    assert dataset_store.ACTIVITIES is ACTIVITIES is activities.ACTIVITIES is procedural.ACTIVITIES
