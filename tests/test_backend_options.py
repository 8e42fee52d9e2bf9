"""One validation of backend options (names, types) for every command, dataset plans and the API: a bad
option is one line naming it (and the valid names or the expected type), exit status 2, before any work."""
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
    (["simulate", "--backend", "facets", "--option", "lod=5"], ["'lod' = 5", "string"]),
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
