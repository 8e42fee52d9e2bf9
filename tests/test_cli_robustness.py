"""`rtchannel robustness` on Glasgow-layout images the test writes and the tiny single-radar model of
tests/conftest.py (approaching line = walk, receding = fall)."""
import csv

import numpy as np
import pytest
from test_real_eval import _glasgow_like  # the model is conftest's session fixture `model_path`

from processing.classifier import load_checkpoint
from processing.classifier.perturb import QUICK_GRID, Perturbation, robustness_grid
from processing.realdata.real_images import load_real_images
from rtchannel.cli import main


@pytest.fixture(scope="module")
def images(tmp_path_factory):
    root = tmp_path_factory.mktemp("imgs")
    _glasgow_like(root / "1P01A01R01.png", 1.5)   # walk, approaching
    _glasgow_like(root / "6P02A06R01.png", -1.5)  # fall, receding
    _glasgow_like(root / "5P03A05R01.png", 0.8)   # drink: not a model class, never counted
    return root


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_robustness_cli_writes_table_csv_and_heat_map(model_path, images, tmp_path, capsys):
    out = tmp_path / "rob"
    assert main(["robustness", "--model", str(model_path), "--images", str(images), "--out", str(out),
                 "--quick", "--quiet"]) == 0
    rows = _rows(out / "robustness.csv")
    assert [r["perturbation"] for r in rows] == [p.name for p in QUICK_GRID]
    assert list(rows[0])[:7] == ["perturbation", "kind", "value", "n", "accuracy", "macro_f1", "delta_accuracy"]
    # per-class recall only for the classes that have images; drink is not a model class
    assert [k for k in rows[0] if k.startswith("recall_")] == ["recall_fall", "recall_walk"]
    for r in rows:
        assert r["n"] == "2" and 0 <= float(r["accuracy"]) <= 1
        assert float(r["accuracy"]) == pytest.approx((float(r["recall_fall"]) + float(r["recall_walk"])) / 2,
                                                     abs=2e-6)
        assert float(r["delta_accuracy"]) == pytest.approx(float(r["accuracy"]) - float(rows[0]["accuracy"]),
                                                           abs=2e-6)
    assert float(rows[0]["accuracy"]) == 1.0  # the sign of a line is what the model learned
    png = (out / "robustness.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 5000
    md = (out / "robustness.md").read_text()
    assert md.count("\n| ") == len(QUICK_GRID) + 1 and "| none | 2 | 100.0 |" in md
    printed = capsys.readouterr().out
    assert "| velocity x1.25 |" in printed and "robustness.png" in printed
    assert not list(out.glob("*.tmp"))  # atomic writes leave no temporary files


def test_library_grid_matches_direct_evaluation(model_path, images):
    clf = load_checkpoint(model_path)
    ims, bad = load_real_images(images)
    assert not bad and len(ims) == 3
    rows = robustness_grid(clf, ims, QUICK_GRID[:2])
    assert rows[0]["delta_accuracy"] == 0.0 and all(np.isfinite(r["accuracy"]) for r in rows)


def test_user_errors_are_one_line_exit_2(model_path, tmp_path, capsys):
    assert main(["robustness", "--model", str(tmp_path / "nope.pt"), "--images", str(tmp_path), "--quick"]) == 2
    assert main(["robustness", "--model", str(model_path), "--images", str(tmp_path / "none"), "--quick"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(e.startswith("error: ") for e in err)
    assert main(["robustness", "--help"]) == 0


def test_images_whose_motion_a_shift_removes_count_as_truncated(model_path, tmp_path):
    """A fall (receding line) only in the clip's first second, over a noise floor, leaves the clip under a
    -1.5 s shift: truncated, and the accuracy on intact images is the whole-clip walk's alone."""
    from processing.realdata.spectrogram_image import glasgow_layout
    from processing.realdata.spectrogram_image_writer import write_spectrogram_image

    root = tmp_path / "imgs"
    _glasgow_like(root / "1P01A01R01.png", 1.5)  # walk over the whole clip: no column is quieter than another
    v, t = np.linspace(-6, 6, 317), np.linspace(0, 5.0, 120)
    line = np.exp(-0.5 * ((v[:, None] + 1.5) / 0.3) ** 2) * (t < 1.0)
    write_spectrogram_image(root / "6P02A06R01.png", v, t, glasgow_layout(5.0), power=line + 1e-4)
    ims, bad = load_real_images(root)
    assert not bad
    clf = load_checkpoint(model_path)
    grid = (Perturbation.make("none"), Perturbation.make("shift", -1.5), Perturbation.make("shift", 1.5))
    none, early, late = robustness_grid(clf, ims, grid)
    assert none["truncated"] == 0 and none["accuracy_intact"] == none["accuracy"] == 1.0
    assert early["truncated"] == 0.5 and early["accuracy_intact"] == 1.0  # the walk, still recognised
    assert late["truncated"] == 0 and late["accuracy_intact"] == late["accuracy"]
    only = robustness_grid(clf, [im for im in ims if im.activity == "fall"], grid[:2])
    assert only[1]["truncated"] == 1.0 and only[1]["accuracy_intact"] is None
    out = tmp_path / "rob"
    assert main(["robustness", "--model", str(model_path), "--images", str(root), "--out", str(out), "--quiet"]) == 0
    rows = {r["perturbation"]: r for r in _rows(out / "robustness.csv")}
    assert float(rows["shift -1.5 s"]["truncated"]) == 0.5 and float(rows["none"]["truncated"]) == 0
    assert "| truncated % | accuracy on intact % |" in (out / "robustness.md").read_text()
