"""Linear blend skinning: rest pose, rigid translation, velocities, heights, safe normals."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rtchannel.body.avatar import LODS, load_avatar
from rtchannel.motion.pose import Motion, avatar_rig, forward_kinematics
from rtchannel.body.skinning import face_normals_and_areas, skin, skin_velocities, skin_vertices


def rest_motion(rig, frames=3, fps=30.0):
    rot = np.tile(np.eye(3), (frames, rig.n_joints, 1, 1))
    return Motion(rig, fps, rot, np.tile(rig.rest, (frames, 1, 1)))


def smooth_motion(times, height=None):
    """Every joint swinging about its own axis with its own phase, root moving on a curve (analytic)."""
    rig = avatar_rig(height)
    j = rig.n_joints
    k = np.arange(j)
    axes = np.stack([np.cos(k), np.sin(1.7 * k), np.cos(0.3 * k + 1)], 1)
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    amp = 0.4 * np.exp(-k / 20)
    ang = amp[None] * np.sin(2 * np.pi * 1.3 * times[:, None] + k[None])
    local = Rotation.from_rotvec((ang[..., None] * axes[None]).reshape(-1, 3)).as_matrix().reshape(len(times), j, 3, 3)
    root = rig.rest[0] + np.stack([1.2 * times, 0.1 * np.sin(3 * times), 0.03 * np.cos(7 * times)], 1)
    rot, pos = forward_kinematics(rig, local, root)
    return Motion(rig, 120.0, rot, pos)


@pytest.mark.parametrize("lod", LODS)
def test_rest_pose_reproduces_rest_mesh(lod):
    av = load_avatar(lod)
    v = skin_vertices(av, rest_motion(av.rig))
    np.testing.assert_allclose(v, np.broadcast_to(av.vertices, v.shape), atol=1e-12)
    assert np.abs(skin_velocities(av, rest_motion(av.rig))).max() < 1e-12


def test_root_translation_moves_every_vertex_by_the_same_vector():
    av = load_avatar("full")
    rig = av.rig
    d = np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 0.1], [1.0, 2.0, -0.5]])
    m = Motion(rig, 30.0, np.tile(np.eye(3), (3, rig.n_joints, 1, 1)), rig.rest[None] + d[:, None])
    v = skin_vertices(av, m)
    np.testing.assert_allclose(v - av.vertices[None], np.broadcast_to(d[:, None], v.shape), atol=1e-12)


def test_velocities_match_finite_difference():
    av = load_avatar("2k")
    t = np.arange(240) / 120.0
    m = smooth_motion(t)
    v = skin_velocities(av, m)
    h = 1e-5
    fd = (skin_vertices(av, smooth_motion(t + h)) - skin_vertices(av, smooth_motion(t - h))) / (2 * h)
    inner = slice(3, -3)  # not-a-knot end conditions are less accurate at the ends
    err = np.linalg.norm(v[inner] - fd[inner], axis=-1)
    assert err.max() / np.linalg.norm(fd[inner], axis=-1).max() < 0.01
    assert np.sqrt((err ** 2).sum() / (np.linalg.norm(fd[inner], axis=-1) ** 2).sum()) < 0.01
    vc = skin_velocities(av, m, method="central")
    x = skin_vertices(av, m)
    np.testing.assert_allclose(vc[1:-1], (x[2:] - x[:-2]) * m.fps / 2, atol=1e-9)


def test_skin_subset_of_frames_and_shapes():
    av = load_avatar("5k")
    m = smooth_motion(np.arange(20) / 120.0)
    s = skin(av, m, frames=[0, 5, -1])
    assert s.vertices.shape == (3, av.n_vertices, 3) and s.velocities.shape == s.vertices.shape
    np.testing.assert_allclose(s.vertices[1], skin_vertices(av, m)[5])
    np.testing.assert_allclose(s.times, m.times[[0, 5, 19]])
    with pytest.raises(IndexError):
        skin_vertices(av, m, frames=[20])


@pytest.mark.parametrize("height", [1.52, 1.83])
def test_height_follows_the_motion_rig(height):
    av = load_avatar("10k")  # loaded at its native height: skinning rescales to the motion's rig
    v = skin_vertices(av, rest_motion(avatar_rig(height)))
    assert np.ptp(v[0, :, 2]) == pytest.approx(height, abs=0.01)
    assert v[0, :, 2].min() == pytest.approx(0.0, abs=1e-3)  # decimated soles move by < 0.1 mm
    v2 = skin_vertices(load_avatar("10k", height=1.6), smooth_motion(np.arange(4) / 120.0, height))
    v3 = skin_vertices(av, smooth_motion(np.arange(4) / 120.0, height))
    np.testing.assert_allclose(v2, v3, atol=1e-12)


def test_normals_areas_and_degenerate_triangles():
    av = load_avatar("2k")
    v = np.array(av.vertices)
    n, a, deg = face_normals_and_areas(v, av.faces)
    assert not deg.any()
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0)
    assert a.sum() == pytest.approx(1.6, rel=0.15)  # ~1.6 m^2 of skin for a 1.67 m body
    centroid = v[av.faces].mean(axis=1)
    # closed, outward-wound surface: the flux of the normals' position field is 3 x volume > 0
    assert np.sum(np.einsum("ij,ij->i", n * a[:, None], centroid)) > 0
    f0 = av.faces[0]
    v[f0[1]] = v[f0[0]]  # collapse one triangle (and distort its neighbours)
    v2 = np.stack([v, v + 1.0])
    n2, a2, deg2 = face_normals_and_areas(v2, av.faces)
    assert n2.shape == (2, av.n_faces, 3) and deg2[:, 0].all() and a2[:, 0].max() == 0
    assert np.isfinite(n2).all()
    np.testing.assert_allclose(np.linalg.norm(n2, axis=-1), 1.0)
    all_gone = face_normals_and_areas(np.zeros_like(v), av.faces)[0]
    assert np.isfinite(all_gone).all()
    nan_n, _, nan_deg = face_normals_and_areas(np.full_like(v, np.nan), av.faces)
    assert nan_deg.all()
