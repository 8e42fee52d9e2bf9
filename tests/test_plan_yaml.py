"""Plan files read safely and sized before expansion (`rtchannel.dataset.plan_yaml`, issue 13)."""
from pathlib import Path

import pytest
import yaml

from rtchannel.dataset.plan import expand, load_plan
from rtchannel.dataset.plan_yaml import MAX_PLAN_BYTES, MAX_YAML_NODES, read_plan_yaml
from rtchannel.errors import ConfigError

REPO = Path(__file__).resolve().parents[1]
FALL = "name: x\nmotion: {sources: [{procedural: fall}]}\n"


def _plan(tmp_path, text, name="p.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize("spec", ["seed", REPO / "examples" / "dataset_small.yaml"])
def test_counted_items_equal_expanded_items(spec):
    from rtchannel.dataset.plan import _motion_files
    from rtchannel.dataset.plan_yaml import count_items

    plan = load_plan(spec)  # counted and expanded without fetching: the seed preset names registered takes
    assert count_items(plan, lambda s: len(_motion_files(s, fetch=False)), "p") == len(expand(plan, fetch=False)) > 0


def test_file_sources_are_counted(tmp_path):
    folder = tmp_path / "takes"
    folder.mkdir()
    for name in ("a.bvh", "b.bvh", "c.txt"):
        (folder / name).write_text("x")
    p = _plan(tmp_path, f"name: x\nmotion: {{sources: [{{files: {folder}, activity: walk}}], heights: [1.7, 1.8]}}\n"
              "physical: {directions: [1, 2, 3]}\n")
    from rtchannel.dataset.plan import _motion_files
    from rtchannel.dataset.plan_yaml import count_items

    assert count_items(load_plan(p), lambda s: len(_motion_files(s)), "p") == 2 * 2 * 3  # the .txt is no motion


def test_aliases_are_allowed_within_the_limit(tmp_path):
    # a reused link set: aliases have uses, only their expanded size is limited
    p = _plan(tmp_path, FALL + "physical:\n  link_sets:\n    - &ls {name: a, links: [{name: r1, tx: [3, 0, 1.1]}]}\n"
              "    - {name: b, links: [{name: r1, tx: [3, 0, 1.1]}]}\n  directions: [1]\n"
              "storage: &st {items_per_shard: 4}\n")
    plan = load_plan(p)
    assert [s.name for s in plan.physical.link_sets] == ["a", "b"] and len(expand(plan)) == 2


def test_expanded_size_limit_is_exact(tmp_path):
    # {a: &x [m scalars], b: *x} is 1 root + 2 keys + 2 (1 + m) nodes once expanded = 5 + 2 m; the file
    # itself holds only m + 4 nodes, so only alias-aware counting puts the limit where it is
    m = (MAX_YAML_NODES - 5) // 2
    def doc(n):
        return "a: &x [" + ", ".join(["0"] * n) + "]\nb: *x\n"
    assert 5 + 2 * m <= MAX_YAML_NODES < 5 + 2 * (m + 1)
    assert len(read_plan_yaml(_plan(tmp_path, doc(m), "ok.yaml"))["b"]) == m
    with pytest.raises(ConfigError, match="aliases are expanded"):
        read_plan_yaml(_plan(tmp_path, doc(m + 1), "over.yaml"))


@pytest.mark.parametrize("text, needle", [
    ("a: &a [*a]\n", "line 1: recursive YAML alias"),
    ("a: " + "[" * 100 + "]" * 100 + "\n", "nested deeper than 64"),
    ("a: b\n  c: [\n", "line 2: not valid YAML"),
    ("\x07", "not valid YAML"),
    ("[1, 2]\n", "expected a mapping at the top level, got a list"),
    ("a: 2001-02-30\n", "not valid YAML"),
])
def test_bad_yaml_is_one_line_with_the_file(tmp_path, text, needle):
    p = _plan(tmp_path, text)
    with pytest.raises(ConfigError) as e:
        read_plan_yaml(p)
    assert str(e.value).startswith(f"plan {p}: ") and needle in str(e.value) and "\n" not in str(e.value)


def test_oversized_and_binary_files(tmp_path):
    big = tmp_path / "big.yaml"
    big.write_text("# " + "x" * MAX_PLAN_BYTES + "\n")
    with pytest.raises(ConfigError, match="bytes, more than"):
        read_plan_yaml(big)
    binary = tmp_path / "bin.yaml"
    binary.write_bytes(b"name: \xff\xfe\n")
    with pytest.raises(ConfigError, match="not UTF-8"):
        read_plan_yaml(binary)


def test_empty_axes_and_nested_options_are_refused_for_programmatic_plans_too():
    from rtchannel.dataset.plan import Plan

    plan = Plan.model_validate(yaml.safe_load(FALL + "physical: {directions: []}\n"))
    with pytest.raises(ConfigError, match="physical.directions: empty list"):
        expand(plan)
    plan = Plan.model_validate(yaml.safe_load(FALL + "backend_options: {lod: [1, 2]}\n"))
    with pytest.raises(ConfigError, match="backend_options.lod: expected a single value"):
        expand(plan)


def test_backend_option_values(tmp_path):
    ok = load_plan(_plan(tmp_path, FALL + "backend: facets\nbackend_options: {batch_frames: 8, "
                                          "min_relative_gain_db: -40.5, lod: 5k, walls: true, trace_fps: null}\n"))
    assert ok.backend_options == {"batch_frames": 8, "min_relative_gain_db": -40.5, "lod": "5k", "walls": True,
                                  "trace_fps": None}
    for value in ("[1]", "{x: 1}", ".inf", "!!binary aGk="):
        with pytest.raises(ConfigError, match="backend_options.lod:"):
            load_plan(_plan(tmp_path, FALL + f"backend: facets\nbackend_options: {{walls: true, lod: {value}}}\n"))
    with pytest.raises(ConfigError, match="no option 'a'"):  # names and types: the check every command makes
        load_plan(_plan(tmp_path, FALL + "backend_options: {a: 1}\n"))


def test_radar_file_alias_bomb_is_one_line(tmp_path, capsys):
    """Radar files go through the same bounded reader: a billion-laughs file is refused without expanding."""
    from rtchannel.cli import main

    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [*a{i - 1}, *a{i - 1}, *a{i - 1}, *a{i - 1}, *a{i - 1}, *a{i - 1}, *a{i - 1}, *a{i - 1}, "
              f"*a{i - 1}, *a{i - 1}]" for i in range(1, 9)]
    p = tmp_path / "radar.yaml"
    p.write_text("\n".join(lines) + "\n")
    assert main(["simulate", "--radar-config", str(p), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "radar config" in err and "alias" in err
