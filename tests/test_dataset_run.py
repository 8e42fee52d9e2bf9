"""Dataset runs: resume after SIGKILL, determinism, per-item failures, Dask with 2 workers = 1 worker."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import pytest
import yaml

from processing.io.dataset_store import read_jsonl

from processing.io.dataset_reader import DatasetReader
from rtchannel.cli import main
from rtchannel.dataset.plan import expand, load_plan
from rtchannel.dataset.runner import PlanMismatchError, run_plan

REPO = Path(__file__).resolve().parents[1]
SHORT = {"pad_before": 0.2, "pad_after": 0.2}  # 1.3-1.4 s motions keep every item near 0.1 s


def _plan(tmp_path, seed=5, name="plan.yaml", directions=(1, 8), **signal):
    data = {"name": "run", "seed": seed,
            "motion": {"sources": [{"procedural": "fall", "variants": 2, "params": {"duration": 0.9, **SHORT}},
                                   {"procedural": "sit", "variants": 1, "params": {"duration": 1.0, **SHORT}}],
                       "heights": [1.6, 1.8]},
            "physical": {"directions": list(directions)},
            "signal": {"gain_sets": [{"name": "j", "perturb_db": 3.0}], "snr_db": [None, 15.0], **signal},
            "storage": {"items_per_shard": 3}}
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data))
    return p  # 3 generator variants x 2 heights x 2 directions x 2 SNRs = 24 items in 8 shards


def _checksums(root):
    return {e["item_id"]: e["sha256"] for e in DatasetReader(root).entries}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """An uninterrupted one-worker, in-process run of the 24-item plan."""
    d = tmp_path_factory.mktemp("ref")
    plan_file = _plan(d)
    s = run_plan(load_plan(plan_file), d / "ds", workers=1, progress=False)
    assert s.complete and s.done_now == 24 and not s.failed
    return plan_file, d / "ds"


def test_killed_run_resumes_without_duplicates_or_gaps(tmp_path, reference):
    plan_file, ref = reference
    out = tmp_path / "ds"
    cmd = [sys.executable, "-m", "rtchannel.cli", "dataset", "--config", str(plan_file), "--out", str(out),
           "--workers", "1", "--quiet"]
    proc = subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    t0 = time.monotonic()
    while not list((out / "shards").glob("*.h5")) if (out / "shards").exists() else True:
        assert proc.poll() is None, proc.stderr.read().decode()
        assert time.monotonic() - t0 < 60, "no shard within 60 s"
        time.sleep(0.005)
    os.killpg(proc.pid, signal.SIGKILL)
    assert proc.wait() == -signal.SIGKILL
    n_killed = len(list((out / "shards").glob("*.h5")))
    assert 1 <= n_killed < 8, "the run must be interrupted midway"  # 8 shards when complete

    assert main(["dataset", "--config", str(plan_file), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    ids = [e["item_id"] for e in read_jsonl(out / "index.jsonl")]
    assert sorted(ids) == ids and len(ids) == len(set(ids)) == 24
    assert set(ids) == {it.item_id for it in expand(load_plan(plan_file))}
    in_shards = []
    for p in (out / "shards").iterdir():
        assert p.suffix == ".h5"  # no temporary files left
        with h5py.File(p, "r") as f:
            in_shards += list(f)
    assert sorted(in_shards) == ids  # every item in exactly one shard
    assert _checksums(out) == _checksums(ref)
    # a further re-run finds nothing to do
    s = run_plan(load_plan(plan_file), out, workers=1, progress=False)
    assert s.done_now == 0 and s.done_before == 24


def test_two_dask_workers_equal_one_worker(tmp_path, reference, capsys):
    plan_file, ref = reference
    s = run_plan(load_plan(plan_file), tmp_path / "ds", workers=2, progress=False)
    assert s.complete and s.workers == 2 and s.done_now == 24
    assert _checksums(tmp_path / "ds") == _checksums(ref)
    assert main(["dataset", "--info", str(tmp_path / "ds")]) == 0
    out = capsys.readouterr().out
    assert "24 items (48 signatures)" in out and "by activity: fall=16, sit=8" in out
    assert "by direction_deg: 0.0=12, 140.0=12" in out


def test_same_config_same_signatures_other_seed_differs(tmp_path, reference):
    plan_file, ref = reference
    clutter = {"clutter": [{"n_scatterers": 3, "csr_db": 6.0}]}
    a, b = (run_plan(load_plan(_plan(tmp_path, name=f"{n}.yaml", directions=[3], **clutter)), tmp_path / n,
                     workers=1, progress=False) for n in ("a", "b"))
    assert a.complete and b.complete
    ca, cb = _checksums(tmp_path / "a"), _checksums(tmp_path / "b")
    assert ca == cb and len(ca) == 12
    other = run_plan(load_plan(_plan(tmp_path, seed=6, name="c.yaml")), tmp_path / "c", workers=1, progress=False)
    assert other.complete
    cr, cc = _checksums(ref), _checksums(tmp_path / "c")
    assert cr.keys() == cc.keys()
    assert all(cr[k]["radar1"] != cc[k]["radar1"] and cr[k]["radar2"] != cc[k]["radar2"] for k in cr)
    r = DatasetReader(tmp_path / "a")
    e = r.entries[r.select(snr_db=15.0)[0]]
    assert e["params"]["clutter_draws"]["radar1"]["ranges_m"]  # the signal layer was applied and recorded
    with pytest.raises(PlanMismatchError):
        run_plan(load_plan(_plan(tmp_path, seed=6, name="d.yaml", directions=[3])), tmp_path / "a", workers=1,
                 progress=False)


def test_bad_motion_file_is_reported_per_item_and_the_run_completes(tmp_path, capsys, shared_data):
    folder = tmp_path / "takes"
    folder.mkdir()
    good = shared_data("mocap/cmu/walk/02_01_iclone.bvh")
    (folder / "a_good.bvh").symlink_to(good)
    (folder / "b_broken.bvh").write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n")  # truncated
    data = {"name": "files", "motion": {"sources": [{"files": str(folder), "activity": "walk"},
                                                    {"procedural": "fall", "params": {"duration": 0.9, **SHORT}}]},
            "physical": {"directions": [1, 10]}, "storage": {"items_per_shard": 2}}
    plan_file = tmp_path / "files.yaml"
    plan_file.write_text(yaml.safe_dump(data))
    args = ["dataset", "--config", str(plan_file), "--out", str(tmp_path / "ds"), "--workers", "1", "--quiet",
            "--retries", "1"]
    assert main(args) == 1  # incomplete: exit status 1, not a traceback
    out = capsys.readouterr().out
    assert "4/6 items done" in out and "b_broken.bvh" in out
    r = DatasetReader(tmp_path / "ds")
    assert len(r) == 4 and r.counts("source") == {"a_good.bvh": 2, "procedural:fall": 2}
    assert len(r.errors) == 2 and all("MotionImportError" in e["error"] and "b_broken.bvh" in e["error"]
                                      and e["attempts"] == 2 for e in r.errors)
    assert main(["dataset", "--info", str(tmp_path / "ds")]) == 0
    assert "2 failed items" in capsys.readouterr().out
    assert main(args) == 1  # a re-run retries only the failed items and adds no duplicates
    assert len(DatasetReader(tmp_path / "ds")) == 4 and len(read_jsonl(tmp_path / "ds" / "errors.jsonl")) == 2
    assert json.loads((tmp_path / "ds" / "plan.json").read_text())["plan"]["name"] == "files"


def test_resume_verifies_checksums_and_recomputes_corrupted_items(tmp_path, reference):
    """Bytes flipped inside a stored p_vt chunk (issue 13): the re-run finds it, keeps the damaged shard as
    *.bad, recomputes only the failed item and ends bit-identical to the reference; a foreign .h5 is renamed."""
    import shutil

    from test_dataset_store import flip_bytes_in_chunk

    plan_file, ref = reference
    out = tmp_path / "ds"
    shutil.copytree(ref, out)
    shard = sorted((out / "shards").glob("*.h5"))[2]
    with h5py.File(shard, "r") as f:
        victim = sorted(f)[1]
    flip_bytes_in_chunk(shard, victim)
    (out / "shards" / "foreign.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 100)  # not a readable HDF5 file
    with pytest.warns(UserWarning, match="renamed to"):
        s = run_plan(load_plan(plan_file), out, workers=1, progress=False)
    assert sorted(s.quarantined) == sorted([shard.name, "foreign.h5"])
    assert s.done_before == 23 and s.done_now == 1 and s.complete
    assert (out / "shards" / (shard.name + ".bad")).is_file() and (out / "shards" / "foreign.h5.bad").is_file()
    assert not (out / "shards" / "foreign.h5").exists()
    assert _checksums(out) == _checksums(ref)
    r = DatasetReader(out)
    assert all(r.verify(i) for i in range(len(r)))
    again = run_plan(load_plan(plan_file), out, workers=1, progress=False)
    assert again.done_now == 0 and again.quarantined == []


def test_unreadable_plan_json_is_one_line(tmp_path, reference, capsys):
    plan_file, _ = reference
    out = tmp_path / "ds"
    out.mkdir()
    (out / "plan.json").write_text("{torn")
    assert main(["dataset", "--config", str(plan_file), "--out", str(out), "--workers", "1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "plan.json: unreadable" in err[0]


def test_info_reports_unreadable_index_lines_and_what_the_shards_hold(tmp_path, reference, capsys):
    """An index reduced to garbage must not read as an empty dataset: --info names the unreadable lines and
    counts what the shards hold; running the plan again rebuilds the index from the shards."""
    import shutil

    _, ref = reference
    ds = tmp_path / "ds"
    shutil.copytree(ref, ds)
    n = len(DatasetReader(ds))
    (ds / "index.jsonl").write_text("garbage line\n")  # a torn last line reads as no entries
    assert main(["dataset", "--info", str(ds)]) == 2  # reported, and a script sees the damage (issue 39)
    out, err = capsys.readouterr()
    assert "index: 1 unreadable line (first: line 1); 0 readable entries" in out
    assert len(err.strip().splitlines()) == 1 and "is damaged" in err and "index.jsonl: 1 unreadable line" in err
    assert f"shards hold {n} items" in out and f"{n} items in the shards are not in the index" in out
    lines = (ref / "index.jsonl").read_text().splitlines()
    lines[1] = "{not json"
    (ds / "index.jsonl").write_text("\n".join(lines) + "\n")
    assert main(["dataset", "--info", str(ds)]) == 2
    out = capsys.readouterr().out
    assert "cannot be read as a whole" in out and "first: line 2" in out and "1 item in the shards is not" in out
