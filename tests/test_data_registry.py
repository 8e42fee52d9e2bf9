"""The data registry: third-party files from a mirror, the cache or their origin, always checked by sha256."""
import csv
import hashlib
import http.server
import threading
from functools import partial

import pytest

from rtchannel import data_registry as reg
from rtchannel.cli import main


@pytest.fixture
def fake(tmp_path, monkeypatch):
    """A registry of two small files served over HTTP from `origin`, with an empty mirror and cache."""
    origin, mirror, cache = (tmp_path / n for n in ("origin", "mirror", "cache"))
    for d in (origin, mirror, cache):
        d.mkdir()
    files = {"mocap/a/take.bvh": b"HIERARCHY\n", "realdata/x/1P1A01R01.png": b"\x89PNG fake"}
    handler = partial(http.server.SimpleHTTPRequestHandler, directory=str(origin))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    entries = {}
    for rel, data in files.items():
        (origin / rel).parent.mkdir(parents=True, exist_ok=True)
        (origin / rel).write_bytes(data)
        url = f"http://127.0.0.1:{server.server_port}/{rel}"
        entries[rel] = reg.Entry(rel, hashlib.sha256(data).hexdigest(), len(data), url, "CC0 (test)")
    monkeypatch.setattr(reg, "registry", lambda: entries)
    monkeypatch.setenv(reg.MIRROR_ENV, str(mirror))
    monkeypatch.setenv(reg.CACHE_ENV, str(cache))
    yield origin, mirror, cache, files
    server.shutdown()


def test_packaged_registry_lists_every_origin_with_checksum_url_and_licence():
    entries = reg.registry()
    assert len(entries) >= 31 + 360  # the motion-capture takes and the Glasgow campaign-1 images
    for e in entries.values():
        assert len(e.sha256) == 64 and e.size > 0 and e.url.startswith("https://") and e.licence
    assert {"mocap/hdm05/asf/HDM_bd.asf", "realdata/glasgow848/1Dataset/6P46A06R01.png"} <= set(entries)


def test_mirror_first_and_only_with_the_right_checksum(fake):
    origin, mirror, cache, files = fake
    rel = "mocap/a/take.bvh"
    (mirror / rel).parent.mkdir(parents=True)
    (mirror / rel).write_bytes(files[rel])
    assert reg.fetch(rel, download=False) == mirror / rel
    (mirror / rel).write_bytes(b"HIERARCHX\n")  # same size, other content: not used
    with pytest.raises(reg.DataUnavailableError, match="rtchannel data fetch mocap/a/take.bvh"):
        reg.fetch(rel, download=False)


def test_fetch_downloads_into_the_cache_checked_by_sha256(fake):
    origin, mirror, cache, files = fake
    rel = "realdata/x/1P1A01R01.png"
    got = reg.fetch(rel)
    assert got == cache / rel and got.read_bytes() == files[rel]
    assert reg.status(reg.registry()[rel]) == "cache"
    (origin / "mocap/a/take.bvh").write_bytes(b"tampered")  # the origin changed: checksum refuses it
    with pytest.raises(reg.DataUnavailableError, match="download failed"):
        reg.fetch("mocap/a/take.bvh")
    assert not (cache / "mocap/a/take.bvh").exists()


def test_unregistered_path_and_empty_pattern_are_input_errors(fake):
    with pytest.raises(reg.InputError, match="not a registered data file"):
        reg.fetch("mocap/nope.bvh")
    with pytest.raises(reg.InputError, match="no registered data file matches"):
        reg.fetch_many("nothing/*")
    assert [e.path for e in reg.entries("mocap")] == ["mocap/a/take.bvh"]  # a folder prefix


def test_cli_data_list_fetch_verify(fake, capsys):
    origin, mirror, cache, files = fake
    assert main(["data", "list"]) == 0
    assert capsys.readouterr().out.count("missing") == 2
    assert main(["data", "fetch", "mocap"]) == 0
    assert "1 files present (1 fetched)" in capsys.readouterr().out
    assert main(["data", "verify"]) == 0
    (cache / "mocap/a/take.bvh").write_bytes(b"HIERARCHX\n")
    assert main(["data", "verify"]) == 1
    assert "checksum mismatch" in capsys.readouterr().out
    assert main(["data", "list", "nothing/*"]) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_plan_sources_name_registered_files(fake, tmp_path):
    from rtchannel.dataset.plan import expand, load_plan

    origin, mirror, cache, files = fake
    plan = tmp_path / "plan.yaml"
    plan.write_text("name: p\nmotion:\n  sources:\n    - files: data:mocap/a\n      activity: walk\n")
    p = load_plan(plan)  # counted from the registry: nothing fetched yet
    assert not (cache / "mocap/a/take.bvh").exists()
    items = expand(p)
    assert items and items[0].motion["path"] == str(cache / "mocap/a/take.bvh") and items[0].source == "take.bvh"


def test_registry_matches_the_mirror_origins_file():
    """The packaged registry is the project's copy of ../shared/ORIGINS.csv (checked where the mirror is)."""
    mirror = reg.mirror_dir()
    if mirror is None or not (mirror / "ORIGINS.csv").is_file():
        pytest.skip("no data mirror beside the checkout (RTCHANNEL_DATA_MIRROR)")
    with open(mirror / "ORIGINS.csv", newline="") as f:
        origins = {r["path"]: r["sha256"] for r in csv.DictReader(f)}
    assert {p: e.sha256 for p, e in reg.registry().items()} == origins


def test_fetch_folder_gathers_a_folder_split_between_mirror_and_origin(fake, monkeypatch):
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
    folder = reg.fetch_folder("realdata/x")  # one file in the mirror, one only at the origin
    assert folder == cache / "realdata/x"
    assert sorted(p.name for p in folder.iterdir()) == ["1P1A01R01.png", "2P1A02R01.png"]
    (cache / "realdata/x/2P1A02R01.png").unlink()
    (mirror / "realdata/x/2P1A02R01.png").write_bytes(data)
    assert reg.fetch_folder("realdata/x") == mirror / "realdata/x"  # all in the mirror: used in place
