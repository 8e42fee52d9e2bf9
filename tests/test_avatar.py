"""The avatar mesh, its levels of detail and skinning weights, and the skin scatterers."""
import numpy as np
import pytest
import trimesh

from rtchannel.body.avatar import LOD_TARGETS, LODS, build_lod, load_avatar
from rtchannel.body.scatterers import SCATTERER_NAMES, seed_scatterers
from rtchannel.motion.pose import REST_HEIGHT_M, Motion, avatar_rig
from rtchannel.body.skin_markers import skin_markers, skin_scatterer_trajectories


def test_full_body_group():
    av = load_avatar("full")
    assert av.n_faces == 26_756 and av.n_vertices == 13_380
    mesh = trimesh.Trimesh(av.vertices, av.faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.euler_number == 2
    assert mesh.volume > 0  # outward winding
    lo, hi = av.vertices.min(axis=0), av.vertices.max(axis=0)
    assert lo[2] == pytest.approx(0.0, abs=1e-9)
    assert hi[2] - lo[2] == pytest.approx(REST_HEIGHT_M, abs=1e-4)


def test_frame_convention_faces_plus_x_left_on_plus_y():
    av = load_avatar("full")
    w = av.dense_weights()
    r = av.rig
    left_hand = w[:, r.index("LeftHand")] > 0.5
    head = w[:, r.index("Head")] > 0.5
    assert av.vertices[left_hand, 1].min() > 0.3
    nose = av.vertices[head][np.argmax(av.vertices[head, 0])]
    assert nose[0] > 0.1 and abs(nose[1]) < 0.02  # the face is the front (+x) of the head


@pytest.mark.parametrize("lod", LODS)
def test_lod_counts_weights_and_closed(lod):
    av = load_avatar(lod)
    if lod != "full":
        assert abs(av.n_faces - LOD_TARGETS[lod]) <= 0.02 * LOD_TARGETS[lod]
    w = av.weights
    assert w.shape == (av.n_vertices, av.rig.n_joints)
    assert (w.data >= 0).all()
    np.testing.assert_allclose(np.asarray(w.sum(axis=1)).ravel(), 1.0, atol=1e-9)
    assert np.diff(w.indptr).max() <= 8
    mesh = trimesh.Trimesh(av.vertices, av.faces, process=False)
    assert mesh.is_watertight and mesh.volume > 0
    assert mesh.area_faces.min() > 1e-9
    assert np.isfinite(av.vertices).all() and av.faces.max() < av.n_vertices


def test_cached_lod_matches_a_fresh_build():
    cached, fresh = load_avatar("2k"), build_lod("2k")
    np.testing.assert_array_equal(cached.faces, fresh.faces)
    np.testing.assert_allclose(cached.vertices, fresh.vertices, atol=1e-12)
    assert abs(cached.weights - fresh.weights).max() < 1e-12


def test_lod_weights_follow_the_body_parts():
    full, low = load_avatar("full"), load_avatar("2k")
    dom_full = np.asarray(full.weights.argmax(axis=1)).ravel()
    dom_low = np.asarray(low.weights.argmax(axis=1)).ravel()
    from scipy.spatial import cKDTree
    _, nn = cKDTree(full.vertices).query(low.vertices)
    assert np.mean(dom_low == dom_full[nn]) > 0.9


@pytest.mark.parametrize("height", [1.52, 1.83])
def test_height_scaling(height):
    av = load_avatar("5k", height=height)
    assert av.rig.height == height
    assert np.ptp(av.vertices[:, 2]) == pytest.approx(height, abs=0.01)
    np.testing.assert_allclose(av.rig.rest, avatar_rig(height).rest)


def test_skin_markers_on_the_surface_near_their_bones():
    for lod in ("full", "2k"):
        av = load_avatar(lod)
        mk = skin_markers(av)
        assert mk.names == SCATTERER_NAMES and len(mk.faces) == 21
        assert (mk.bary >= -1e-9).all()
        np.testing.assert_allclose(mk.bary.sum(axis=1), 1.0)
        bone = seed_scatterers(av.rig).rest_points
        d = np.linalg.norm(mk.rest_points(av) - bone, axis=1)
        assert d.max() < 0.2
        # front-facing trunk points really sit on the front of the body
        front = [SCATTERER_NAMES.index(n) for n in ("head", "chest", "abdomen", "pelvis")]
        assert (mk.rest_points(av)[front, 0] > bone[front, 0] + 0.05).all()
        w = mk.weights(av)
        np.testing.assert_allclose(np.asarray(w.sum(axis=1)).ravel(), 1.0, atol=1e-9)


def test_skin_scatterers_move_with_the_body():
    rig = avatar_rig(1.83)
    f = 5
    rot = np.tile(np.eye(3), (f, rig.n_joints, 1, 1))
    shift = np.linspace(0, 1, f)[:, None] * np.array([1.0, 0.5, 0.0])
    motion = Motion(rig, 10.0, rot, rig.rest[None] + shift[:, None])
    av = load_avatar("10k")
    pos, vel = skin_scatterer_trajectories(av, motion, velocities=True)
    assert pos.shape == (f, 21, 3)
    rest = skin_markers(av).rest_points(av) * 1.83 / av.height
    np.testing.assert_allclose(pos, rest[None] + shift[:, None], atol=1e-12)
    np.testing.assert_allclose(vel, np.broadcast_to([2.5, 1.25, 0.0], vel.shape), atol=1e-9)


def test_render_smoke(tmp_path):
    # the set-up (make env) installs libLLVM >= 16, so its absence is a failure, not a skip
    from PIL import Image
    from rtchannel.scene.render import render_scene
    rig = avatar_rig(1.7)
    motion = Motion(rig, 30.0, np.tile(np.eye(3), (2, rig.n_joints, 1, 1)), np.tile(rig.rest, (2, 1, 1)))
    out = render_scene(motion, [0], [[3.0, 0.0, 1.1]], tmp_path / "scene.png", lod="2k", size=(96, 72), spp=2)
    img = np.asarray(Image.open(out).convert("RGB"), float)
    assert img.shape == (72, 96, 3) and img.std() > 5
    # the body and the radar (red > blue, unlike the grey floor and the sky) are in view
    assert ((img[..., 0] - img[..., 2]) > 40).mean() > 0.005


def test_sole_asset_file_is_the_avatars_soles():
    """Retargeting reads the soles from meshes/avatar/soles.npz (the motion layer never loads the body):
    the file must equal what the avatar gives now (regenerate with body.avatar.sole_asset if it changes)."""
    from rtchannel.assets import avatar_dir
    from rtchannel.body.avatar import sole_asset

    fresh = sole_asset()
    with np.load(avatar_dir() / "soles.npz") as f:
        assert set(f.files) == set(fresh)
        for k, v in fresh.items():
            assert np.array_equal(f[k], v), k
