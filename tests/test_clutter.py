"""Static clutter of the mesh backends (issue 24): the room's walls and floor are synthesised, the MTI removes
them to the noise floor once it has settled, leaves its start-up transient before, and the body shadows them."""
import numpy as np
import pytest

from processing.pathset import PathSet
from rtchannel import Motion, Radar
from rtchannel.backends.clutter import clutter_paths, scene_patches
from rtchannel.pipeline import process_paths
from rtchannel.scene.rt_scene import get_scene

RADAR = Radar.glasgow(height_m=1.0, distance_m=3.0)  # its DSP: causal 4th-order Butterworth MTI at rest


@pytest.fixture(scope="module")
def room():
    return get_scene("room", "2k", 1.75, RADAR.waveform.carrier_hz, sionna=False)


def _power_db(paths):
    sig = process_paths(paths, RADAR)["radar1"].signature
    return np.asarray(sig.time), 10 * np.log10(np.asarray(sig.power))


def test_patches_tile_the_room_and_are_at_most_half_a_range_bin(room):
    p = scene_patches(room, RADAR.waveform.carrier_hz, 0.18)
    assert p.areas.sum() == pytest.approx(4 * 8 * 3 + 8 * 8, rel=1e-6)  # four 8 x 3 m walls and the floor
    edges = np.linalg.norm(p.corners - np.roll(p.corners, 1, axis=1), axis=2)
    assert edges.max() <= 0.18 + 1e-9


def test_empty_room_clutter_is_removed_to_the_noise_floor_after_the_mti_settles(room):
    """Noise-only columns are the reference: after 1.5 s (the filter at 3.75 Hz has decayed by > 100 dB; its
    slowest pole's time constant is ~0.1 s) every column is within 3 dB of them; in the first 0.2 s the
    start-up transient stands > 40 dB above them, as in real recordings."""
    times = np.arange(0.0, 4.0, 1 / 60)
    clutter = clutter_paths(room, RADAR, times)
    empty = {"radar1": PathSet(times=times, delays=np.full((times.size, 1), 2e-8),
                               gains=np.zeros((times.size, 1), complex), ids=np.array([0]), link="radar1")}
    t, with_clutter = _power_db(clutter)
    _, noise = _power_db(empty)
    settled = t > 1.5
    assert np.abs(with_clutter[settled] - noise[settled]).max() < 3.0
    assert (with_clutter[t < 0.2] - noise[t < 0.2]).min() > 40.0


def test_the_body_shadows_the_clutter_it_stands_in_front_of(room):
    """The wall behind a person standing between radar and wall loses the patches the body hides."""
    m = Motion.procedural("stand", seed=0)
    from rtchannel.body.avatar import load_avatar
    from rtchannel.body.skinning import skin_vertices

    av = load_avatar("2k")
    idx = np.array([0, m.n_frames - 1])
    verts = skin_vertices(av, m, idx)
    shadowed = clutter_paths(room, RADAR, m.times, verts, av.faces, idx)["radar1"]
    free = clutter_paths(room, RADAR, m.times)["radar1"]
    assert np.array_equal(shadowed.delays, free.delays)
    lost = np.abs(free.gains[0]) - np.abs(shadowed.gains[0])
    assert lost.max() > 0 and (np.abs(shadowed.gains[0]) <= np.abs(free.gains[0]) + 1e-15).mean() > 0.5


def test_facets_in_the_room_carry_the_clutter_and_free_space_none():
    from rtchannel.backends.facets import facet_paths

    m = Motion.procedural("fall", seed=3, duration=1.0)
    with_c = facet_paths(m, RADAR, scene="room", lod="2k")["radar1"]
    without = facet_paths(m, RADAR, scene="room", lod="2k", clutter=False)["radar1"]
    free = facet_paths(m, RADAR, scene="free_space", lod="2k")["radar1"]
    from rtchannel.backends.clutter import CLUTTER_ID_BASE

    assert (with_c.ids >= CLUTTER_ID_BASE).sum() > 50 and not (without.ids >= CLUTTER_ID_BASE).any()
    # the clutter's columns follow the body's, which are the clutter-free run's bit for bit
    n = without.n_paths
    assert not (with_c.ids[:n] >= CLUTTER_ID_BASE).any() and (with_c.ids[n:] >= CLUTTER_ID_BASE).all()
    for field in ("delays", "gains", "delay_rates", "ids"):
        assert np.array_equal(getattr(with_c, field)[..., :n], getattr(without, field), equal_nan=True)
    assert not (free.ids >= CLUTTER_ID_BASE).any()
