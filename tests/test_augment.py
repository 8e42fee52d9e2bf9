"""Motion-layer augmentation: height, time warp, mirror, heading, start, trim, seeds."""
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial import cKDTree

from rtchannel.body.avatar import load_avatar
from rtchannel.motion.augment import augment, mirror, mirror_index
from rtchannel.body.skinning import skin_vertices
from test_skinning import smooth_motion


@pytest.fixture(scope="module")
def walk():
    return replace(smooth_motion(np.arange(240) / 120.0, 1.7), activity="walk")


def hips_xy(m):
    return m.positions[:, 0, :2]


@pytest.mark.parametrize("height", [1.52, 1.83, 2.1])
def test_height_retargets_onto_a_scaled_rig(walk, height):
    out = augment(walk, height=height)
    assert out.rig.height == height
    av = load_avatar("2k")
    rest = type(out)(out.rig, out.fps, np.tile(np.eye(3), (2, 31, 1, 1)), np.tile(out.rig.rest, (2, 1, 1)))
    assert np.ptp(skin_vertices(av, rest)[0, :, 2]) == pytest.approx(height, abs=0.01)
    s = height / walk.rig.height
    np.testing.assert_allclose(np.diff(hips_xy(out), axis=0), s * np.diff(hips_xy(walk), axis=0), atol=1e-12)
    np.testing.assert_allclose(out.rotations, walk.rotations)
    np.testing.assert_allclose(out.positions[:, :, 2], s * walk.positions[:, :, 2])  # floor stays at 0


def test_time_warp(walk):
    slow = augment(walk, time_scale=2.0)
    assert slow.fps == walk.fps
    assert slow.duration == pytest.approx(2 * walk.duration, abs=1 / walk.fps)
    every_other = slow.positions[::2]
    np.testing.assert_allclose(every_other[:walk.n_frames], walk.positions[:len(every_other)], atol=1e-9)
    v0 = np.linalg.norm(hips_xy(walk)[-1] - hips_xy(walk)[0]) / walk.duration
    v1 = np.linalg.norm(hips_xy(slow)[-1] - hips_xy(slow)[0]) / slow.duration
    assert v1 == pytest.approx(v0 / 2, rel=0.01)
    fast = augment(walk, time_scale=0.8)
    assert fast.duration == pytest.approx(0.8 * walk.duration, abs=1 / walk.fps)


def test_mirror_swaps_sides_and_reflects(walk):
    idx = mirror_index(walk.rig.names)
    assert walk.rig.names[idx[walk.rig.index("LeftHand")]] == "RightHand"
    assert walk.rig.names[idx[walk.rig.index("LThumb")]] == "RThumb"
    assert walk.rig.names[idx[0]] == "Hips"
    m = augment(walk, mirror=True)
    np.testing.assert_allclose(m.positions, walk.positions[:, idx] * [1, -1, 1], atol=1e-12)
    twice = mirror(mirror(walk))
    np.testing.assert_allclose(twice.positions, walk.positions, atol=1e-12)
    np.testing.assert_allclose(twice.rotations, walk.rotations, atol=1e-12)
    av = load_avatar("5k")
    a = skin_vertices(av, walk, [100])[0] * [1, -1, 1]
    b = skin_vertices(av, m, [100])[0]
    d, _ = cKDTree(b).query(a)
    assert np.median(d) < 0.01 and np.percentile(d, 99) < 0.03  # the mesh is nearly symmetric


def test_heading_start_and_trim(walk):
    out = augment(walk, heading_deg=90.0, start=(2.0, -1.0), trim=(0.5, 1.5))
    assert out.duration == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_allclose(hips_xy(out)[0], [2.0, -1.0])
    d0 = hips_xy(walk)[int(1.5 * walk.fps)] - hips_xy(walk)[int(0.5 * walk.fps)]
    d1 = hips_xy(out)[-1] - hips_xy(out)[0]
    np.testing.assert_allclose(d1, [-d0[1], d0[0]], atol=1e-9)  # turned +90 deg
    np.testing.assert_allclose(out.positions[:, :, 2], walk.positions[60:181, :, 2], atol=1e-12)
    with pytest.raises(ValueError):
        augment(walk, trim=(1.0, 1.001))


def test_params_recorded_and_seeded(walk):
    kw = dict(height=(1.52, 1.83), time_scale=(0.8, 1.2), mirror=0.5, heading_deg=(-180, 180))
    a = augment(walk, seed=7, **kw)
    b = augment(walk, seed=7, **kw)
    c = augment(walk, seed=8, **kw)
    np.testing.assert_array_equal(a.positions, b.positions)
    assert a.params["augment"] == b.params["augment"] and a.params["augment"] != c.params["augment"]
    rec = a.params["augment"][-1]
    assert 1.52 <= rec["height"] <= 1.83 and 0.8 <= rec["time_scale"] <= 1.2 and rec["seed"] == 7
    assert a.rig.height == rec["height"] and isinstance(rec["mirror"], bool)
    assert rec["requested"]["height"] == [1.52, 1.83]
    chained = augment(a, heading_deg=10.0)
    assert len(chained.params["augment"]) == 2 and chained.activity == "walk"
    import json
    json.dumps(chained.params)
    with pytest.raises(ValueError, match="seed"):
        augment(walk, height=(1.5, 1.8))
    unchanged = augment(walk)
    np.testing.assert_allclose(unchanged.positions, walk.positions)
