"""PHASE 2 of issue 13 (hardening): radar/waveform/DSP bounds, plans and the commands' own arguments.

Cases still marked xfail wait for their fix (the reason says which); the others are regression tests. Cases that would
allocate many GiB or hang with today's code are ``run=False`` (listed, not executed). The contract is the
same as in `test_fuzz_inputs.py`: one line on stderr naming the file/field, exit status 2, before any
long work; a valid input gives finite output.

Owners: `processing/waveform.py` and `processing/dsp.py` (bounds), `rtchannel/dataset/plan.py`,
`rtchannel/radar.py`, the CLI commands' own argument checks (`rtchannel/cli/*.py`).
"""
import math

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from rtchannel.cli import main
from rtchannel.errors import USER_ERRORS

P2 = "phase 2 (issue 13): "


@pytest.fixture(autouse=True)
def no_long_work(monkeypatch):
    """Invalid input must be refused before any simulation starts: simulating here fails the case at once
    (which also keeps these xfail cases fast while they are unfixed)."""
    import rtchannel.pipeline as pipeline

    def started(*a, **k):
        raise AssertionError("the simulation started although the input is invalid")

    monkeypatch.setattr(pipeline, "simulate", started)


def _one_line_exit_2(capsys, args) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


# ---------------------------------------------------------------- radar YAML / waveform / DSP bounds
SAFE_RADAR = [
    ("waveform:\n  carrier_hz: .inf\n", "carrier_hz"),
    ("waveform:\n  carrier_hz: 1.0e300\n", "carrier_hz"),
    ("links:\n  - {name: r1, tx: [1.0e300, 0, 1]}\n", "links.0.tx"),
    ("waveform: [unclosed\n", "radar.yaml"),  # YAML syntax error: raw yaml.YAMLError today
]


@pytest.mark.parametrize("yaml_text, needle", SAFE_RADAR)
def test_radar_yaml_values(tmp_path, capsys, yaml_text, needle):
    cfg = tmp_path / "radar.yaml"
    cfg.write_text(yaml_text)
    line = _one_line_exit_2(capsys, ["simulate", "--activity", "fall", "--duration", "0.9", "--radar-config", str(cfg),
                                     "--out", str(tmp_path / "o"), "--quiet", "--no-plots"])
    assert needle in line


@pytest.mark.parametrize("yaml_text", ["waveform:\n  pri_s: 1.0e-9\n", "dsp:\n  window_chirps: 1000000000\n"])
def test_radar_sizes_refused_before_allocating(tmp_path, capsys, yaml_text):
    cfg = tmp_path / "radar.yaml"
    cfg.write_text(yaml_text)
    _one_line_exit_2(capsys, ["simulate", "--radar-config", str(cfg), "--out", str(tmp_path / "o"), "--quiet"])


def test_recording_shorter_than_one_window_before_simulating(tmp_path, capsys):
    cfg = tmp_path / "radar.yaml"
    cfg.write_text("dsp:\n  window_chirps: 4096\n")  # 2 s at 0.5 ms; the motion lasts ~1.4 s
    line = _one_line_exit_2(capsys, ["simulate", "--activity", "fall", "--duration", "0.9", "--radar-config", str(cfg),
                                     "--out", str(tmp_path / "o"), "--quiet", "--no-plots"])
    assert "window" in line and not (tmp_path / "o" / "signature.h5").exists()


number = st.one_of(st.floats(), st.integers(-2**70, 2**70), st.sampled_from([1e300, -1e300, 1e-300, 0, -1]))
value = st.one_of(number, st.none(), st.booleans(), st.text(max_size=4), st.lists(number, max_size=3))
section = st.sampled_from(["waveform", "dsp", "receiver", "antenna", "orientation_deg", "links"])
field = st.sampled_from(["carrier_hz", "bandwidth_hz", "pri_s", "samples_per_chirp", "window_chirps", "hop_chirps",
                         "max_range_m", "noise_figure_db", "tx", "rx", "name", "beamwidth_deg"])


@settings(max_examples=60, deadline=None, derandomize=True, database=None, phases=(Phase.explicit, Phase.generate),
          suppress_health_check=list(HealthCheck))
@given(doc=st.dictionaries(section, st.one_of(value, st.dictionaries(field, value, max_size=3),
                                              st.lists(st.dictionaries(field, value, max_size=3), max_size=2)),
                           max_size=3),
       garbage=st.one_of(st.none(), st.text(max_size=30)))
def test_radar_yaml_fuzz(tmp_path_factory, doc, garbage):
    import yaml

    from rtchannel.radar import RadarConfig

    p = tmp_path_factory.mktemp("r") / "radar.yaml"
    p.write_text(garbage if garbage is not None else yaml.safe_dump(doc))
    try:
        radar = RadarConfig.from_file(p)
    except USER_ERRORS:
        return
    wf = radar.waveform
    assert all(math.isfinite(v) and abs(v) < 1e15 for v in (wf.carrier_hz, wf.bandwidth_hz, wf.pri_s, wf.max_range_m))
    assert all(math.isfinite(c) and abs(c) < 1e4 for link in radar.links for c in (*link.tx, *(link.rx or ())))


# ----------------------------------------------------------------------------------------- plans
@pytest.mark.xfail(reason=P2 + "plan.py: an empty product axis runs 0 items with exit 0", strict=False)
def test_plan_with_no_directions(tmp_path, capsys):
    plan = tmp_path / "p.yaml"
    plan.write_text("name: x\nmotion: {sources: [{procedural: fall}]}\nphysical: {directions: []}\n")
    assert "directions" in _one_line_exit_2(capsys, ["dataset", "--config", str(plan), "--out", str(tmp_path / "o"),
                                                     "--workers", "1", "--quiet"])


@pytest.mark.xfail(run=False, reason=P2 + "plan.py: a 3e9-item product is expanded (hangs); count it, refuse above a limit")
def test_plan_product_counted_not_expanded(tmp_path, capsys):
    plan = tmp_path / "p.yaml"
    plan.write_text("name: x\nmotion: {sources: [{procedural: walk, variants: 100000}], heights: [1.6, 1.7, 1.8]}\n"
                    "physical: {directions: seed, angles_deg: null}\nsignal: {snr_db: [0, 5, 10, 15, 20, 25, 30, 35, 40, 45]}\n")
    _one_line_exit_2(capsys, ["dataset", "--config", str(plan), "--dry-run"])


@pytest.mark.xfail(run=False, reason=P2 + "plan.py: YAML alias bomb inside backend_options; option values must be scalars")
def test_plan_alias_bomb(tmp_path, capsys):
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"] + [f"a{k}: &a{k} [" + ", ".join([f"*a{k - 1}"] * 10) + "]"
                                                         for k in range(1, 9)]
    plan = tmp_path / "p.yaml"
    plan.write_text("name: x\nmotion: {sources: [{procedural: fall}]}\nbackend_options:\n  "
                    + "\n  ".join(lines) + "\n")
    _one_line_exit_2(capsys, ["dataset", "--config", str(plan), "--dry-run"])


@pytest.mark.xfail(reason=P2 + "plan YAML: every value validated, syntax errors as ConfigError", strict=False)
@settings(max_examples=40, deadline=None, derandomize=True, database=None, phases=(Phase.explicit, Phase.generate),
          suppress_health_check=list(HealthCheck))
@given(text=st.one_of(st.text(max_size=40), st.sampled_from(["name: [", "motion: 3", "{a: *b}", "- - -"])))
def test_plan_yaml_fuzz(tmp_path_factory, text):
    from rtchannel.dataset.plan import load_plan

    p = tmp_path_factory.mktemp("p") / "plan.yaml"
    p.write_text(text)
    try:
        load_plan(p)
    except USER_ERRORS:
        pass


# ------------------------------------------------------------------------------- command-line arguments
CLI_CASES = [
    (["simulate", "--activity", "fall", "--angle-deg", "nan"], "angle"),
    (["simulate", "--activity", "fall", "--option", "body_rcs_m2=abc"], "body_rcs_m2"),
    (["bench", "--repeats", "0"], "repeats"),
    (["evaluate", "--model", "m.pt", "--recordings", ".", "--channels", "0"], "channels"),
]


@pytest.mark.parametrize("args, needle", CLI_CASES)
def test_cli_argument_checks(tmp_path, capsys, args, needle):
    line = _one_line_exit_2(capsys, [*args, "--out", str(tmp_path / "o")])
    assert needle in line


def test_out_is_a_file_checked_before_simulating(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    _one_line_exit_2(capsys, ["simulate", "--activity", "fall", "--out", str(f), "--quiet"])
