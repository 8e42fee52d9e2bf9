"""One typed options model per backend (`rtchannel.backends.options`) for every command, dataset plans, the
API, the accuracy calibration and the docs table: a bad option is one line naming it (and the valid names,
its range or the expected type), exit status 2, before any work."""
import inspect
from pathlib import Path

import pytest

from processing.errors import InputError
from rtchannel import Motion, simulate, trace
from rtchannel.cli import main



def _line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: "), err
    return err


@pytest.mark.parametrize("argv,words", [
    (["simulate", "--option", "lodd=5k"], ["no option 'lodd'", "its options:"]),
    (["simulate", "--backend", "facets", "--option", "lod=5"], ["'lod' = 5", "'10k'"]),
    (["simulate", "--backend", "facets", "--option", "lod=3k"], ["'lod' = '3k'", "'auto'"]),
    (["simulate", "--backend", "facets", "--option", "trace_fps=0"], ["'trace_fps' = 0", "greater than 0"]),
    (["simulate", "--backend", "facets", "--option", "trace_fps=1e6"], ["'trace_fps'", "less than or equal to 1000"]),
    (["simulate", "--backend", "sionna", "--option", "samples_per_src=0"], ["'samples_per_src' = 0"]),
    (["simulate", "--option", "trajectories=5"], ["'trajectories'", "array"]),
    (["simulate", "--option", "scale=[x"], ["--option scale=[x", "YAML scalar"]),
    (["simulate", "--option", "body_rcs_m2=abc"], ["body_rcs_m2"]),
    (["compare", "--backends", "points,facets", "--option", "facets.lodd=1"], ["no option 'lodd'"]),
    (["compare", "--backends", "points,facets", "--option", "facets.lod=[1"], ["YAML scalar"]),
    (["bench", "--chain", "facets", "--option", "facets.trace_fps=fast"], ["trace_fps"]),
    (["bench", "--chain", "nope"], ["unknown backend 'nope'"]),
])
def test_bad_options_are_one_line_in_every_command(argv, words, tmp_path, capsys):
    out = ["--out", str(tmp_path / "o")]
    assert main(argv + out) == 2
    line = _line(capsys)
    assert all(w in line for w in words), line
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_plan_with_a_bad_option_fails_at_dry_run(tmp_path, capsys):
    plan = tmp_path / "p.yaml"
    plan.write_text("name: p\nbackend: facets\nbackend_options: {lod: 5}\n"
                    "motion: {sources: [{procedural: walk, params: {duration: 1.0}}]}\n")
    assert main(["dataset", "--config", str(plan), "--out", str(tmp_path / "d"), "--dry-run"]) == 2
    line = _line(capsys)
    assert "p.yaml" in line and "'lod' = 5" in line
    plan.write_text("name: p\nbackend_options: {gains: 1.0}\n"  # the runner sets gains itself
                    "motion: {sources: [{procedural: walk, params: {duration: 1.0}}]}\n")
    assert main(["dataset", "--config", str(plan), "--out", str(tmp_path / "d"), "--dry-run"]) == 2
    assert "no option 'gains'" in _line(capsys)


def test_api_names_the_valid_options():
    walk = Motion.procedural("walk", duration=1.0, seed=0)
    with pytest.raises(InputError, match=r"no option 'lodd' \(its options: .*body_rcs_m2"):
        simulate(walk, backend="points", lodd="5k")
    with pytest.raises(InputError, match="lod"):
        trace(walk, backend="facets", lod=5)


REPO = Path(__file__).resolve().parents[1]


def test_the_docs_table_is_generated_from_the_models():
    from rtchannel.backends.options import options_doc

    assert (REPO / "docs" / "backend_options.md").read_text() == options_doc() + "\n", \
        "docs/backend_options.md is out of date: run python scripts/backend_options_doc.py"


@pytest.mark.parametrize("backend", ["points", "facets", "sionna"])
def test_models_have_the_backend_functions_options_and_defaults(backend):
    from rtchannel.backends import backend_function
    from rtchannel.backends.options import RESERVED_OPTIONS, options_model

    params = inspect.signature(backend_function(backend)).parameters
    given = {k: p.default for k, p in params.items() if k not in ("motion", "radar", "scene") + RESERVED_OPTIONS}
    fields = {k: f.default for k, f in options_model(backend).model_fields.items()}
    assert given == fields


def test_lod_names_are_the_avatars_and_resolved_in_one_place():
    from rtchannel.backends.options import LOD_NAMES, validate_options
    from rtchannel.backends.scene_model import lod_for_wavelength, resolve_lod
    from rtchannel.body.avatar import LODS

    assert LOD_NAMES == LODS
    assert resolve_lod("auto", "room", 0.0517) == lod_for_wavelength(0.0517) and resolve_lod("5k", None, 1.0) == "5k"
    assert validate_options("sionna", {"lod": "auto"}) == {"lod": "auto"}  # sionna resolves auto the same way
    sources = {p.name: p.read_text() for p in (REPO / "rtchannel" / "backends").glob("*.py")}
    assert [n for n, s in sources.items() if "lod_for_wavelength(" in s] == ["scene_model.py"]
    assert all("resolve_lod(lod" in sources[n] for n in ("facets.py", "sionna_rt.py"))


def test_values_are_converted_and_python_objects_stay_python_only():
    import numpy as np

    from rtchannel.backends.options import validate_options

    assert validate_options("facets", {"trace_fps": 30, "walls": "auto", "seed": None}) == {
        "trace_fps": 30.0, "walls": "auto", "seed": None}
    g = np.ones(21)
    assert validate_options("points", {"gains": g})["gains"] is g
    with pytest.raises(InputError, match="'skin' = 'dry'.*SkinMaterial"):
        validate_options("facets", {"skin": "dry"})
    with pytest.raises(InputError, match="single value"):
        validate_options("facets", {"walls": ["a", "b"]})
    with pytest.raises(InputError, match="finite"):
        validate_options("points", {"body_rcs_m2": float("inf")})


def test_the_accuracy_calibration_reads_the_models():
    from pydantic import ValidationError

    from rtchannel.accuracy import CalibrationRow, shipped_tables
    from rtchannel.analysis.calibrate import CANDIDATES
    from rtchannel.backends.options import validate_options

    assert all(t.rows for _, t in shipped_tables())  # every shipped row was checked when the table loaded
    for setting, _ in CANDIDATES:
        validate_options(setting.backend, setting.options)
    with pytest.raises(ValidationError, match="trace_fps"):
        CalibrationRow(label="x", backend="facets", options={"trace_fps": -5}, s_per_sim_s=1.0, emd_m_s={})
