"""Dataset storage (shards, index, reader, torch Dataset) and signal-layer augmentation (noise, clutter)."""
import json
import os

import h5py
import numpy as np
import pytest

from processing.io.dataset_reader import DatasetReader
from processing.io.dataset_store import (ACTIVITIES, checksum, read_jsonl, remove_orphans, scan_shards, write_index,
                                         write_shard)
from processing.errors import DatasetFormatError
from processing.dsp.signatures import DSPConfig, signatures
from processing.synthesis.augment import add_clutter, add_noise, signal_power, static_clutter
from processing.radar.waveform import Waveform


def _record(item_id, activity, direction, rng, t=20):
    links = {}
    for link in ("radar1", "radar2"):
        p = rng.random((64, t)).astype(np.float32)
        links[link] = {"p_vt": p / p.sum(0), "velocity": np.linspace(-6, 6, 64, dtype=np.float32),
                       "time": np.arange(t, dtype=np.float32), "mean_velocity": np.zeros(t, np.float32),
                       "range_distribution": rng.random((17, t)).astype(np.float32),
                       "range": np.arange(17, dtype=np.float32), "valid": np.ones(t, bool),
                       "power": np.ones(t, np.float32)}
    entry = {"item_id": item_id, "activity": activity, "label": ACTIVITIES.index(activity),
             "direction_deg": direction, "backend": "points", "group": f"g-{activity}", "source": "test",
             "params": {"x": 1}}
    return {"entry": entry, "links": links}


@pytest.fixture
def dataset(tmp_path, rng):
    recs = [_record(f"{a}-{k}", a, d, rng) for a in ("walk", "fall") for k, d in enumerate((0.0, 20.0, 40.0))]
    write_shard(tmp_path / "shards" / "a.h5", recs[:4])
    write_shard(tmp_path / "shards" / "b.h5", recs[4:])
    entries, bad = scan_shards(tmp_path)
    assert bad == []
    write_index(tmp_path, entries)
    return tmp_path, recs


def test_shards_index_and_reader_round_trip(dataset):
    root, recs = dataset
    r = DatasetReader(root)
    assert len(r) == 6
    assert [e["item_id"] for e in r.entries] == sorted(rec["entry"]["item_id"] for rec in recs)
    assert r.counts() == {"fall": 3, "walk": 3}
    assert r.counts("direction_deg") == {"0.0": 2, "20.0": 2, "40.0": 2}
    assert r.select(activity="walk", direction_deg=[0.0, 40.0]) == [3, 5]
    i = r.select(item_id="walk-1")[0]
    got = r.load(i)
    want = recs[1]["links"]
    for link in ("radar1", "radar2"):
        for k, v in want[link].items():
            np.testing.assert_array_equal(got[link][k], v)  # exact: stored losslessly
        assert got[link]["p_vt"].dtype == np.float32
    assert r.entries[i]["sha256"]["radar1"] == checksum(want["radar1"])
    assert all(r.verify(j) for j in range(len(r)))
    assert set(r.load(i, links=["radar2"])) == {"radar2"}
    with pytest.raises(KeyError, match="radar9"):
        r.load(i, links=["radar9"])
    assert "by activity: fall=3, walk=3" in r.summary()


def test_write_shard_is_atomic_and_failure_leaves_nothing(tmp_path, rng):
    bad = _record("x", "walk", 0.0, rng)
    bad["links"]["radar1"]["p_vt"] = object()  # h5py cannot store it: the write fails midway
    with pytest.raises(Exception):
        write_shard(tmp_path / "shards" / "bad.h5", [_record("ok", "walk", 0.0, rng), bad])
    assert list((tmp_path / "shards").iterdir()) == []
    (tmp_path / "shards" / "c.h5.123.tmp").write_bytes(b"partial")
    (tmp_path / "shards" / "junk.h5").write_bytes(b"not hdf5")
    assert remove_orphans(tmp_path) == 1
    entries, badnames = scan_shards(tmp_path, repair=True)
    # a foreign file is renamed, never deleted
    assert entries == [] and badnames == ["junk.h5"] and not (tmp_path / "shards" / "junk.h5").exists()
    assert (tmp_path / "shards" / "junk.h5.bad").read_bytes() == b"not hdf5"


def test_reader_tolerates_torn_index_and_duplicates(dataset):
    root, _ = dataset
    lines = (root / "index.jsonl").read_text().splitlines()
    (root / "index.jsonl").write_text("\n".join(lines + [lines[0], lines[1][:30]]) + "\n")  # dup + torn
    assert len(read_jsonl(root / "index.jsonl")) == 7
    r = DatasetReader(root)
    assert len(r) == 6 and len({e["item_id"] for e in r.entries}) == 6
    os.remove(root / "index.jsonl")  # no index at all: rebuilt from the shards in memory
    assert len(DatasetReader(root)) == 6


def test_torch_dataset_lazy(dataset):
    import torch

    root, recs = dataset
    r = DatasetReader(root)
    ds = r.torch_dataset(indices=r.select(activity="fall"))
    assert len(ds) == 3
    x, y = ds[0]
    assert isinstance(x, torch.Tensor) and x.shape == (2, 64, 20) and x.dtype == torch.float32
    assert y == ACTIVITIES.index("fall")
    np.testing.assert_array_equal(x[1].numpy(), recs[3]["links"]["radar2"]["p_vt"])
    import pickle

    back = pickle.loads(pickle.dumps(ds))
    assert len(back) == 3 and torch.equal(back[0][0], x)
    ds2 = r.torch_dataset(links=("radar1",), transform=lambda m: torch.tensor(m["radar1"].sum()))
    x2, _ = ds2[0]
    assert x2.ndim == 0 and abs(float(x2) - 20.0) < 1e-3  # 20 columns each summing to 1 (float32 sums)


def test_noise_power_matches_snr():
    rng = np.random.default_rng(0)
    iq = (3.0 * np.exp(1j * 0.01 * np.arange(400 * 128))).reshape(400, 128).astype(np.complex64)
    noisy = add_noise(iq, 10.0, rng)
    p_n = signal_power(noisy - iq)
    # 51200 complex samples: the power estimate's relative std is 1/sqrt(51200) = 0.4 %; 2 % is 5 sigma
    assert p_n == pytest.approx(9.0 / 10.0, rel=0.02)
    again = add_noise(iq, 10.0, np.random.default_rng(0))
    np.testing.assert_array_equal(noisy, again)
    assert not np.array_equal(noisy, add_noise(iq, 10.0, np.random.default_rng(1)))
    assert np.array_equal(add_noise(np.zeros_like(iq), 10.0, rng), np.zeros_like(iq))


def test_static_clutter_lands_in_its_range_bin_and_is_removed_by_dsp():
    wf = Waveform()
    row = static_clutter(wf, 1, np.array([3.0]), np.array([1.0]))[0]
    k = int(np.argmax(np.abs(np.fft.fft(row))))
    assert k == round(3.0 / wf.range_resolution)  # 3 m / 0.6 m = bin 5
    rng = np.random.default_rng(3)
    t = np.arange(512) * wf.pri_s
    tau = 2 * (2.0 - 1.0 * t) / 299_792_458.0  # a target approaching at 1 m/s
    iq = np.exp(1j * 2 * np.pi * (wf.slope * np.outer(tau, np.arange(128) / wf.fs) + wf.start_hz * tau[:, None]))
    cl, info = add_clutter(iq.astype(np.complex64), wf, rng, n_scatterers=5, csr_db=20.0, range_m=(1.0, 6.0))
    assert signal_power(cl - iq) == pytest.approx(100 * signal_power(iq), rel=1e-3)  # float32 rounding only
    assert len(info["ranges_m"]) == 5
    clean, dirty = signatures(iq.astype(np.complex64), wf), signatures(cl, wf)
    # slow-time mean removal cancels static returns up to float32 rounding of a 20 dB stronger signal
    np.testing.assert_allclose(dirty.p_vt, clean.p_vt, atol=1e-3)
    kept = signatures(cl, wf, DSPConfig(static_removal="none"))
    assert kept.p_vt[np.argmin(np.abs(kept.velocity)), 0] > 0.5  # without removal the clutter dominates v = 0


def flip_bytes_in_chunk(shard, item_id, link="radar1", key="p_vt"):
    """Overwrite 8 bytes in the middle of the (gzip) chunk of one stored array, as disk corruption would."""
    with h5py.File(shard, "r") as f:
        info = f[item_id][link][key].id.get_chunk_info(0)
    with open(shard, "r+b") as fh:
        fh.seek(info.byte_offset + info.size // 2)
        fh.write(b"\xde\xad\xbe\xef\x01\x02\x03\x04")


def test_verify_finds_corrupt_chunk_and_repair_keeps_the_rest(dataset):
    root, recs = dataset
    flip_bytes_in_chunk(root / "shards" / "a.h5", "walk-1")
    entries, bad = scan_shards(root)  # without verify the damage is invisible
    assert len(entries) == 6 and bad == []
    entries, bad = scan_shards(root, verify=True, repair=True)
    assert bad == ["a.h5"]
    assert sorted(e["item_id"] for e in entries) == ["fall-0", "fall-1", "fall-2", "walk-0", "walk-2"]
    assert (root / "shards" / "a.h5.bad").is_file()  # the damaged original is kept
    with h5py.File(root / "shards" / "a.h5", "r") as f:  # the rewritten shard holds the 3 verified items
        assert sorted(f) == ["fall-0", "walk-0", "walk-2"] and f.attrs["format"] == "rtchannel-dataset-shard/1"
    entries2, bad2 = scan_shards(root, verify=True)
    assert bad2 == [] and entries2 == entries


@pytest.mark.parametrize("line, message", [
    ('{"activity": "walk"}', r"index\.jsonl: line 3: entry lacks a valid 'item_id'"),
    ('{"item_id": "x", "shard": "a.h5", "links": [], "label": "1", "sha256": {}}',
     r"line 3: entry lacks a valid 'label'"),
    ("[1, 2]", r"line 3: expected a JSON object, got list"),
    ("{not json", r"line 3: not valid JSON"),
])
def test_bad_index_lines_name_file_and_line(dataset, line, message):
    root, _ = dataset
    lines = (root / "index.jsonl").read_text().splitlines()
    lines.insert(2, line)
    (root / "index.jsonl").write_text("\n".join(lines) + "\n")
    with pytest.raises(DatasetFormatError, match=message):
        DatasetReader(root)


def test_index_cannot_point_outside_the_shards_folder(dataset):
    root, _ = dataset
    rows = read_jsonl(root / "index.jsonl")
    rows[0]["shard"] = "../../etc/passwd"
    (root / "index.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    with pytest.raises(DatasetFormatError, match=r"shard '\.\./\.\./etc/passwd' is not a file name in shards/"):
        DatasetReader(root)


def test_reading_a_corrupt_item_is_a_one_line_error(dataset):
    root, _ = dataset
    flip_bytes_in_chunk(root / "shards" / "b.h5", "fall-1")
    r = DatasetReader(root)
    i = r.select(item_id="fall-1")[0]
    assert not r.verify(i)
    with pytest.raises(DatasetFormatError, match=r"b\.h5: item 'fall-1' cannot be read .*re-run the dataset command"):
        r.load(i)


def test_empty_or_nan_signatures_are_item_failures(rng):
    """An item shorter than one DSP window (T = 0) or with a NaN is refused before it reaches a shard."""
    from processing.io.dataset_store import check_record
    from processing.errors import InputError
    rec = _record("ok", "walk", 0.0, rng)
    assert check_record(rec) is rec
    empty = _record("short", "walk", 0.0, rng, t=0)
    with pytest.raises(InputError, match="item short: link radar1: no complete DSP window"):
        check_record(empty)
    bad = _record("nan", "walk", 0.0, rng)
    bad["links"]["radar2"]["mean_velocity"][3] = np.nan
    with pytest.raises(InputError, match="item nan: link radar2: mean_velocity holds non-finite values"):
        check_record(bad)
