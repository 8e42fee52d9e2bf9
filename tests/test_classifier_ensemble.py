"""Seed ensembles (soft voting): the vote is the members' mean probability, checkpoints round-trip and are
checked member by member, members trained differently are refused, and the CLI combines checkpoints."""
import numpy as np
import pytest
import torch

from processing.classifier import (Classifier, ModelConfig, PreprocessConfig, build_model, load_checkpoint,
                                   save_checkpoint)
from processing.classifier.checkpoint import ENSEMBLE_VERSION
from processing.classifier.ensemble import MAX_MEMBERS, SoftVote, ensemble
from processing.errors import CheckpointError, InputError
from processing.io.dataset_store import ACTIVITIES
from rtchannel.cli import main

CFG = ModelConfig(input_size=(16, 16), padding="same", channels=(4, 4), mlp_hidden=8)


def _clf(seed: int, cfg: ModelConfig = CFG, floor_db: float = 40.0) -> Classifier:
    torch.manual_seed(seed)
    model = build_model(cfg)
    model.eval()
    return Classifier(model=model, preprocess=PreprocessConfig(n_velocity=16, n_time=16, floor_db=floor_db),
                      classes=list(ACTIVITIES), links=["radar1", "radar2"],
                      meta={"train_config": {"seed": seed}, "train_spec": "DS", "val_accuracy": 0.9, "dsp": {"a": 1}})


def _x(n: int = 12) -> np.ndarray:
    return np.random.default_rng(0).random((n, 2, 16, 16), dtype=np.float32)


def test_vote_is_the_members_mean_probability():
    members = [_clf(s) for s in (0, 1, 2)]
    x = _x()
    want = np.mean([m.predict_proba(x) for m in members], axis=0)
    ens = ensemble(members)
    got = ens.predict_proba(x)
    # float32 softmax of log(mean p): relative rounding ~1e-7 per step
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(got.sum(axis=1), 1.0, atol=1e-6)
    # different seeds really differ, so the test above could fail
    assert np.abs(members[0].predict_proba(x) - members[1].predict_proba(x)).max() > 1e-3
    assert [m["seed"] for m in ens.meta["members"]] == [0, 1, 2] and ens.meta["dsp"] == {"a": 1}
    # two copies of one network vote exactly as that network (refused unless asked for: see the next test)
    same = ensemble([members[0], members[0]], distinct=False)
    np.testing.assert_allclose(same.predict_proba(x), members[0].predict_proba(x), rtol=1e-5, atol=1e-7)


def test_ensembles_flatten_and_refuse_members_trained_otherwise():
    pair = ensemble([_clf(0), _clf(1)], ["a.pt", "b.pt"])
    flat = ensemble([pair, _clf(2)], ["pair.pt", "c.pt"])
    assert len(flat.model.members) == 3
    # each member keeps the checkpoint it was trained into
    assert [m["source"] for m in flat.meta["members"]] == ["a.pt", "b.pt", "c.pt"]
    with pytest.raises(InputError, match="b.pt differs from a.pt in its preprocessing"):
        ensemble([_clf(0), _clf(1, floor_db=30.0)], ["a.pt", "b.pt"])
    with pytest.raises(InputError, match="in its network configuration"):
        ensemble([_clf(0), _clf(1, CFG.model_copy(update={"mlp_hidden": 9}))])
    with pytest.raises(InputError, match="2 to 16 members, got 1"):
        ensemble([_clf(0)])
    with pytest.raises(InputError, match="got 17"):
        SoftVote([_clf(0).model] * (MAX_MEMBERS + 1))


def test_ensemble_checkpoint_round_trip(tmp_path):
    ens = ensemble([_clf(0), _clf(1), _clf(2)])
    path = save_checkpoint(tmp_path / "e.pt", ens)
    assert torch.load(path, weights_only=True)["version"] == ENSEMBLE_VERSION
    back = load_checkpoint(path)
    assert isinstance(back.model, SoftVote) and len(back.model.members) == 3
    x = _x()
    np.testing.assert_array_equal(back.predict_proba(x), ens.predict_proba(x))
    assert back.meta["members"] == ens.meta["members"]


def _tampered(tmp_path, edit):
    path = save_checkpoint(tmp_path / "ok.pt", ensemble([_clf(0), _clf(1)]))
    blob = torch.load(path, weights_only=True)
    edit(blob)
    bad = tmp_path / "bad.pt"
    torch.save(blob, bad)
    return bad


@pytest.mark.parametrize("edit, message", [
    (lambda b: b["members"][1].pop("mlp.0.weight"), r"members\[1\] lacks 'mlp.0.weight'"),
    (lambda b: b["members"][0]["mlp.0.bias"].fill_(float("nan")), r"members\[0\] 'mlp.0.bias' holds non-finite"),
    (lambda b: b.update(members=b["members"][:1]), r"a list 'members' of 2 to 16 state dicts"),
    (lambda b: b.update(members="x"), r"a list 'members' of 2 to 16 state dicts"),
    (lambda b: b["members"].__setitem__(1, [1, 2]), r"members\[1\] is a list, not a dict"),
    # 16 members of a network of 3.3e6 parameters exceed 5e7 before any member beyond the first is built
    (lambda b: b.update(members=[{}] * 16, model_config={**b["model_config"], "mlp_hidden": 50_000,
                                                         "channels": [4, 4]}), r"16 members of .* exceed"),
    (lambda b: b.update(version=3), r"not a version-1 or -2 classifier checkpoint"),
])
def test_bad_ensemble_checkpoints_are_one_line_errors(tmp_path, edit, message):
    bad = _tampered(tmp_path, edit)
    with pytest.raises(CheckpointError, match=message) as exc:
        load_checkpoint(bad)
    assert "\n" not in str(exc.value) and "bad.pt" in str(exc.value)


def test_cli_ensemble(tmp_path, capsys):
    paths = [save_checkpoint(tmp_path / f"m{s}.pt", _clf(s)) for s in (0, 1)]
    assert main(["ensemble", "--models", *map(str, paths), "--out", str(tmp_path / "e")]) == 0
    assert "2 members (seeds 0, 1)" in capsys.readouterr().out
    ens = load_checkpoint(tmp_path / "e.pt")
    x = _x()
    want = np.mean([load_checkpoint(p).predict_proba(x) for p in paths], axis=0)
    np.testing.assert_allclose(ens.predict_proba(x), want, rtol=1e-5, atol=1e-7)
    other = save_checkpoint(tmp_path / "o.pt", _clf(2, floor_db=30.0))
    for args, why in (([paths[0], other], "differs from"), ([paths[0], paths[0]], "same checkpoint twice"),
                      ([paths[0], tmp_path / "none.pt"], "model file not found")):
        assert main(["ensemble", "--models", *map(str, args), "--out", str(tmp_path / "f.pt")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and why in err[0]
    assert not (tmp_path / "f.pt").exists()
