"""Property/fuzz tests of the file readers (issue 13): every generated input either succeeds with finite
output or raises one of `rtchannel.errors.USER_ERRORS` with a one-line message - never anything else.

Covered here (phase 1): BVH and C3D motion files, Ancortek `.dat` recordings, scene XML (sandbox),
classifier checkpoints and dataset index files. Radar YAML, dataset plans and command-line arguments are
in `test_fuzz_phase2.py` (expected to fail until their validation lands). Examples are bounded and
derandomised (same inputs every run, no example database) so the module runs in well under a minute;
RTCHANNEL_FUZZ_SCALE=20 runs 20x the examples with fresh random inputs. Each test counts the inputs it
accepted (`fuzz_tally`); a module fixture asserts the lower bounds in `MIN_ACCEPTED`.
"""
import json
import math
import os
import shutil

import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from fuzz_tally import accepted_at_least, tally
from rtchannel.errors import USER_ERRORS


SCALE = int(os.environ.get("RTCHANNEL_FUZZ_SCALE", "1"))  # e.g. 20 for a longer, randomised exploration
# about half of what the derandomised examples accept (measured: bvh 7/40, c3d semantic 2/6, c3d bytes 2/5, dat
# 3/80, scene XML 9/80, checkpoint 5/40, dataset index 7/40): a drift is tolerated, a collapse is not
MIN_ACCEPTED = {"test_bvh_fuzz": 3, "test_c3d_semantic_fuzz": 1, "test_c3d_byte_fuzz": 1, "test_dat_fuzz": 1,
                "test_scene_xml_fuzz": 4, "test_checkpoint_fuzz": 2, "test_dataset_index_fuzz": 3}


@pytest.fixture(scope="module", autouse=True)
def accepted_enough():
    """After the module: every fuzz test that ran accepted at least its share of generated inputs."""
    yield
    accepted_at_least(MIN_ACCEPTED)


def fuzz(n: int):
    return settings(max_examples=n * SCALE, deadline=None, derandomize=SCALE == 1, database=None,
                    phases=(Phase.explicit, Phase.generate),  # no shrinking: bounded time on failure too
                    suppress_health_check=list(HealthCheck))


def user_error(exc: BaseException) -> None:
    """The contract for a refused input: a user-error type with a one-line message."""
    from pydantic import ValidationError

    assert isinstance(exc, USER_ERRORS), f"{type(exc).__name__}: {exc}"
    if not isinstance(exc, ValidationError):  # the CLI turns these into one line (validation_line)
        assert "\n" not in str(exc), repr(str(exc))


def attempt(fn, *args, **kwargs):
    """fn(...) or None if it raised a user error (anything else propagates and fails the test)."""
    try:
        return fn(*args, **kwargs)
    except USER_ERRORS as e:
        user_error(e)
        return None


NASTY_NUMBERS = ["nan", "-nan", "inf", "-inf", "1e20", "-1e20", "1e308", "1e-300", "1e300", "0", "-0", "-5",
                 "2.5", "9" * 40, "0x10", "1_0", "", "abc", "1.2.3", "+", "-", "e5"]
NASTY_TEXT = ["{", "}", "MOTION", "JOINT", "End", "Site", "ROOT", "OFFSET", "CHANNELS", "Frames:", "\ufeff", "\x00",
              "é", "\t", " "]


# ----------------------------------------------------------------------------------------------- BVH
@pytest.fixture(scope="module")
def bvh_lines(tmp_path_factory):
    from test_skinning import smooth_motion

    from rtchannel.motion.bvh import write_bvh

    p = tmp_path_factory.mktemp("bvh") / "base.bvh"
    write_bvh(smooth_motion(np.arange(12) / 60.0, 1.75), p, units="cm")
    return p.read_text().splitlines()


bvh_edit = st.one_of(
    st.tuples(st.just("token"), st.integers(0, 10**6), st.integers(0, 10**3),
              st.sampled_from(NASTY_NUMBERS + NASTY_TEXT)),
    st.tuples(st.just("delete"), st.integers(0, 10**6)),
    st.tuples(st.just("duplicate"), st.integers(0, 10**6)),
    st.tuples(st.just("insert"), st.integers(0, 10**6), st.text(max_size=12)),
    st.tuples(st.just("truncate"), st.floats(0.0, 1.0)),
    st.tuples(st.just("bom"),),
)


def _apply_bvh(lines: list[str], edits) -> str:
    lines = list(lines)
    bom, cut = False, None
    for e in edits:
        if e[0] == "bom":
            bom = True
        elif e[0] == "truncate":
            cut = e[1]
        elif e[0] == "token":
            i = e[1] % len(lines)
            tok = lines[i].split() or [""]
            tok[e[2] % len(tok)] = e[3]
            lines[i] = " ".join(tok)
        elif e[0] == "delete" and len(lines) > 1:
            del lines[e[1] % len(lines)]
        elif e[0] == "duplicate":
            i = e[1] % len(lines)
            lines.insert(i, lines[i])
        elif e[0] == "insert":
            lines.insert(e[1] % (len(lines) + 1), e[2])
    text = "\n".join(lines) + "\n"
    if cut is not None:
        text = text[:int(len(text) * cut)]
    return ("\ufeff" if bom else "") + text


@fuzz(40)
@given(edits=st.lists(bvh_edit, min_size=1, max_size=3))
def test_bvh_fuzz(bvh_lines, tmp_path_factory, edits):
    from rtchannel.motion.load import load_motion

    p = tmp_path_factory.mktemp("f") / "take.bvh"
    p.write_bytes(_apply_bvh(bvh_lines, edits).encode("utf-8", "surrogatepass"))
    m = attempt(load_motion, p)
    if tally(m is not None):
        assert m.n_frames >= 2 and np.isfinite(m.positions).all() and np.isfinite(m.rotations).all()


# ----------------------------------------------------------------------------------------------- C3D
@pytest.fixture(scope="module")
def c3d_base(tmp_path_factory):
    import ezc3d

    from thirdparty import data_path

    src = ezc3d.c3d(str(data_path("mocap/cmu/stand/77_02.c3d")))
    p = tmp_path_factory.mktemp("c3d") / "base.c3d"
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [60.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = list(src["parameters"]["POINT"]["LABELS"]["value"])
    c.add_parameter("POINT", "UNITS", ["mm"])
    c["data"]["points"] = src["data"]["points"][:, :, :90].copy()
    c.write(str(p))
    return p


def _patch_c3d(raw: bytes, marker: int, frames: int, n: int, value: float, rate: float, units: bytes) -> bytes:
    """The base file with marker values, header frame rate and POINT:UNITS overwritten in place (ezc3d's own
    writer aborts the process on some of these values, so the bytes are edited directly). Float storage:
    frame f, marker m at data_start + (f * n_points + m) * 16 bytes (x, y, z, residual as float32)."""
    import struct

    b = bytearray(raw)
    n_points, = struct.unpack_from("<H", b, 2)
    first, last = struct.unpack_from("<HH", b, 6)
    start = (struct.unpack_from("<H", b, 16)[0] - 1) * 512
    for f in range(frames, min(frames + n, last - first + 1)):
        struct.pack_into("<3f", b, start + (f * n_points + marker % n_points) * 16, value, value, value)
    struct.pack_into("<f", b, 20, rate)
    k = b.find(b"RATE", 512)
    while k > 0:  # parameter record: name, int16 offset, int8 type (4 = float), int8 ndims, dims, data
        ndims = b[k + 7]
        if b[k + 6] == 4 and ndims <= 1:
            struct.pack_into("<f", b, k + 8 + ndims, rate)
        k = b.find(b"RATE", k + 4)
    k = b.find(b"UNITS", 512)
    j = b.find(b"mm", k, k + 40)
    if k > 0 and j > 0:
        b[j:j + 2] = units
    return bytes(b)


@fuzz(6)
@given(marker=st.integers(0, 40), frames=st.integers(0, 89), n=st.integers(1, 60),
       value=st.sampled_from([np.nan, np.inf, -np.inf, 1e20, 0.0, -1e6]),
       rate=st.sampled_from([60.0, 0.0, 1e9, 1e-3, np.nan]),
       units=st.sampled_from([b"mm", b"m ", b"km", b"  "]))
def test_c3d_semantic_fuzz(c3d_base, tmp_path_factory, marker, frames, n, value, rate, units):
    from rtchannel.motion.load import load_motion

    p = tmp_path_factory.mktemp("c") / "take.c3d"
    p.write_bytes(_patch_c3d(c3d_base.read_bytes(), marker, frames, n, value, rate, units))
    m = attempt(load_motion, p)
    if tally(m is not None):
        assert np.isfinite(m.positions).all() and np.isfinite(m.rotations).all()


@fuzz(5)
@given(flips=st.lists(st.tuples(st.integers(0, 3000), st.integers(0, 255)), min_size=1, max_size=12),
       cut=st.one_of(st.none(), st.integers(0, 20000)))
def test_c3d_byte_fuzz(c3d_base, tmp_path_factory, flips, cut):
    """ezc3d segfaults on some of these: the reader runs it in a child process."""
    from rtchannel.motion.load import load_motion

    b = bytearray(c3d_base.read_bytes())
    for i, v in flips:
        b[i % len(b)] = v
    p = tmp_path_factory.mktemp("b") / "take.c3d"
    p.write_bytes(bytes(b[:cut] if cut is not None else b))
    m = attempt(load_motion, p)
    if tally(m is not None):
        assert np.isfinite(m.positions).all()


# ------------------------------------------------------------------------------------------------ .dat
number_text = st.one_of(st.sampled_from(NASTY_NUMBERS),
                        st.floats(allow_nan=True, allow_infinity=True).map(repr),
                        st.integers(-10**6, 10**6).map(str))
sample_text = st.one_of(
    st.tuples(number_text, st.sampled_from(["+", "-", " + ", ""]), number_text,
              st.sampled_from(["i", "j", "I", "", " i"]))
    .map(lambda t: "".join(t)),
    st.text(max_size=8), st.just(""))
# well-formed samples (as `write_dat` writes them) in whole sweeps of the good header's 8 samples, so that valid
# recordings are generated too, not only broken ones
good_sample = st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)).map(lambda c: f"{c[0]:.8e}{c[1]:+.8e}i")
good_samples = st.integers(1, 4).flatmap(lambda k: st.lists(good_sample, min_size=8 * k, max_size=8 * k))


@fuzz(80)
@given(head=st.lists(number_text, min_size=0, max_size=5),
       samples=st.one_of(st.lists(sample_text, max_size=40), good_samples),
       good_head=st.booleans(), n_channels=st.integers(-1, 3), partial=st.booleans())
def test_dat_fuzz(tmp_path_factory, head, samples, good_head, n_channels, partial):
    from processing.realdata.ancortek import read_dat

    header = ["24.125", "0.5", "8", "250"] if good_head else head
    p = tmp_path_factory.mktemp("d") / "rec.dat"
    p.write_text("\n".join(header + samples) + "\n", encoding="utf-8", errors="surrogatepass")
    rec = attempt(read_dat, p, n_channels=n_channels, allow_partial=partial)
    if tally(rec is not None):
        assert all(np.isfinite(a).all() and a.dtype == np.complex64 and a.shape[0] >= 1 for a in rec.iq)
        wf = rec.waveform
        assert all(math.isfinite(v) and v > 0 for v in (wf.carrier_hz, wf.bandwidth_hz, wf.pri_s, wf.max_range_m))


# ------------------------------------------------------------------------------------------- scene XML
PATH_VALUES = ["../secret.txt", "{secret}", "inner.xml", "mesh.ply", "link.ply", "sub/../../secret.txt",
               "$f", "$missing", "", "/etc/passwd", "room.xml", "{scenes}/room.xml", "nested.xml"]
TAGS = ["shape", "include", "string", "default", "path", "bsdf", "ref", "texture", "float"]
ATTRS = ["filename", "value", "name", "type", "id", "file"]


@st.composite
def scene_xml(draw):
    def element(depth):
        tag = draw(st.sampled_from(TAGS))
        attrs = draw(st.dictionaries(st.sampled_from(ATTRS),
                                     st.one_of(st.sampled_from(PATH_VALUES), st.sampled_from(["filename", "f", "ply"])),
                                     max_size=3))
        inner = "".join(element(depth + 1) for _ in range(draw(st.integers(0, 2 if depth < 2 else 0))))
        a = " ".join(f'{k}="{v}"' for k, v in attrs.items())
        return f"<{tag} {a}>{inner}</{tag}>" if inner else f"<{tag} {a}/>"
    body = "".join(element(0) for _ in range(draw(st.integers(0, 4))))
    prefix = draw(st.sampled_from(["", '<?xml version="1.0"?>', '<!DOCTYPE s [<!ENTITY x "y">]>']))
    text = f'{prefix}<scene version="2.1.0">{body}</scene>'
    cut = draw(st.one_of(st.none(), st.integers(0, len(text))))
    return text if cut is None else text[:cut]


@pytest.fixture(scope="module")
def scene_folder(tmp_path_factory):
    from rtchannel.scene.rt_scene import SCENES

    base = tmp_path_factory.mktemp("sandbox")
    secret = base / "secret.txt"
    secret.write_text("TOP-SECRET\n")
    d = base / "scene"
    (d / "sub").mkdir(parents=True)
    (d / "mesh.ply").write_text("ply\n")
    (d / "link.ply").symlink_to(secret)
    (d / "inner.xml").write_text('<scene version="2.1.0"><include filename="../secret.txt"/></scene>')
    (d / "nested.xml").write_text('<scene version="2.1.0"><include filename="room.xml"/></scene>')
    shutil.copy(SCENES["room"], d / "room.xml")
    return d, secret, SCENES["room"].parent


@fuzz(80)
@given(text=scene_xml())
def test_scene_xml_fuzz(scene_folder, text):
    import xml.etree.ElementTree as ET

    from rtchannel.scene.sandbox import check_scene_file

    d, secret, scenes = scene_folder
    p = d / "fuzz.xml"
    p.write_text(text.replace("{secret}", str(secret)).replace("{scenes}", str(scenes)))
    try:
        check_scene_file(p)
    except USER_ERRORS as e:
        user_error(e)
        assert "TOP-SECRET" not in str(e)
        tally(False)
        return
    tally(True)
    # accepted: an independent look at every attribute must find no reference that resolves to the secret
    todo = [p]
    while todo:
        f = todo.pop()
        root = ET.parse(f).getroot()
        defaults = {e.get("name"): e.get("value") for e in root.iter("default")}
        for el in root.iter():
            for k, v in el.attrib.items():
                if k in ("name", "id", "type"):  # identifiers, never resolved as files by Mitsuba
                    continue
                v = defaults.get(v[1:], v) if v.startswith("$") else v
                if v:
                    target = (f.parent / v).resolve()
                    assert target != secret.resolve(), (text, v)
                    if el.tag == "include" and target.suffix == ".xml":
                        todo.append(target)


# ----------------------------------------------------------------------------------------- checkpoints
@pytest.fixture(scope="module")
def checkpoint_blob(tmp_path_factory):
    from processing.classifier import Classifier, ModelConfig, PreprocessConfig, build_model, save_checkpoint
    from processing.io.dataset_store import ACTIVITIES

    cfg = ModelConfig(input_size=(16, 16), padding="same", channels=(4, 4), mlp_hidden=8)
    torch.manual_seed(0)
    clf = Classifier(model=build_model(cfg), preprocess=PreprocessConfig(n_velocity=16, n_time=16),
                     classes=list(ACTIVITIES), links=["radar1", "radar2"])
    p = save_checkpoint(tmp_path_factory.mktemp("ck") / "m.pt", clf)
    return torch.load(p, weights_only=True)


ANY_VALUE = st.one_of(st.none(), st.booleans(), st.integers(-2**70, 2**70), st.floats(), st.text(max_size=6),
                      st.lists(st.integers(-5, 10**9), max_size=4), st.just(200_000_000), st.just([4096, 4096]))


@fuzz(40)
@given(section=st.sampled_from(["model_config", "preprocess", "top", "state", "state_shape", "bytes"]),
       key=st.integers(0, 100), value=ANY_VALUE, drop=st.booleans())
def test_checkpoint_fuzz(checkpoint_blob, tmp_path_factory, section, key, value, drop):
    import copy

    from processing.classifier import load_checkpoint

    blob = copy.deepcopy(checkpoint_blob)
    p = tmp_path_factory.mktemp("k") / "m.pt"
    target = {"model_config": blob["model_config"], "preprocess": blob["preprocess"], "top": blob,
              "state": blob["state_dict"], "state_shape": blob["state_dict"], "bytes": None}[section]
    if target is None:
        torch.save(blob, p)
        raw = bytearray(p.read_bytes())
        raw[key * 37 % len(raw)] ^= 0xFF
        p.write_bytes(bytes(raw[: len(raw) - key]))
    else:
        k = sorted(target)[key % len(target)]
        if drop:
            del target[k]
        elif section == "state_shape":
            target[k] = torch.zeros(tuple(abs(x) % 5 for x in (value if isinstance(value, list) else [3])))
        else:
            target[k] = torch.tensor(float(value)) if section == "state" and isinstance(value, float) else value
        torch.save(blob, p)
    clf = attempt(load_checkpoint, p)
    if tally(clf is not None):
        x = np.zeros((1, len(clf.links), clf.preprocess.n_velocity, clf.preprocess.n_time), np.float32)
        assert np.isfinite(clf.predict_proba(x)).all()


# ----------------------------------------------------------------------------------------- dataset index
@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory):
    from test_dataset_store import _record

    from processing.io.dataset_store import scan_shards, write_index, write_shard

    root = tmp_path_factory.mktemp("ds")
    rng = np.random.default_rng(0)
    write_shard(root / "shards" / "a.h5", [_record(f"walk-{k}", "walk", 0.0, rng) for k in range(3)])
    write_index(root, scan_shards(root)[0])
    return root


json_value = st.recursive(st.one_of(st.none(), st.booleans(), st.integers(), st.floats(allow_nan=False),
                                    st.text(max_size=5)),
                          lambda inner: (st.lists(inner, max_size=3)
                                         | st.dictionaries(st.text(max_size=5), inner, max_size=3)),
                          max_leaves=6)


@fuzz(40)
@given(pos=st.integers(0, 5), line=st.one_of(st.none(), json_value.map(json.dumps), st.text(max_size=30),
                                            st.sampled_from(['{"item_id": "x"}', '{"item_id": 3}', "{", "[]", ""])),
       field=st.one_of(st.none(), st.sampled_from(["item_id", "shard", "links", "label", "sha256"])), value=json_value)
def test_dataset_index_fuzz(small_dataset, tmp_path_factory, pos, line, field, value):
    from processing.io.dataset_reader import DatasetReader

    root = tmp_path_factory.mktemp("copy") / "ds"
    shutil.copytree(small_dataset, root)
    rows = (root / "index.jsonl").read_text().splitlines()
    edited = json.loads(rows[0])
    if field is not None:  # None: the row stays as written
        edited[field] = value
    rows[0] = json.dumps(edited)
    if line is not None:  # None: no line inserted
        rows.insert(pos % (len(rows) + 1), line)
    (root / "index.jsonl").write_text("\n".join(rows) + "\n")
    r = attempt(DatasetReader, root)
    if tally(r is not None):
        for i in range(len(r)):
            data = attempt(r.load, i)
            if data is not None:
                assert all(np.isfinite(a["p_vt"]).all() for a in data.values())
