"""Box rooms of any size (`room:X0,X1,Y0,Y1,H`): the walls where the name puts them, normals into the room, the
8 x 8 x 3 m room identical to scenes/room.xml, bad names one line; a dataset plan draws one room per motion
around the person and every antenna."""
import numpy as np
import pytest

from rtchannel.scene.rooms import room_bounds, room_name
from rtchannel.scene.rt_scene import get_scene


def _walls(scene):
    return {w.name: w for w in get_scene(scene, "2k", 1.75, 5.8e9).walls}


def test_generated_room_equals_the_shipped_room():
    ref, gen = _walls("room"), _walls(room_name(-4, 4, -4, 4, 3))
    assert set(ref) == set(gen)
    for name in ref:
        np.testing.assert_allclose(gen[name].point, ref[name].point, atol=1e-5)
        np.testing.assert_allclose(gen[name].normal, ref[name].normal, atol=1e-6)
        assert gen[name].area == pytest.approx(ref[name].area, rel=1e-5)
        assert gen[name].relative_permittivity == pytest.approx(ref[name].relative_permittivity)


def test_off_centre_room_walls_and_areas():
    """[-1.5, 5.5] x [-2, 1.5] m, 2.6 m high: walls at x = -1.5 and 5.5 (areas 3.5 x 2.6), y = -2 and 1.5 (7 x 2.6),
    floor 7 x 3.5 = 24.5 m^2; every normal points to the room's centre (the side where images are valid)."""
    w = _walls(room_name(-1.5, 5.5, -2, 1.5, 2.6))
    centre = np.array([2.0, -0.25, 1.3])
    expect = {"floor": (0.0, (0, 0, 1), 24.5), "wall_xp": (5.5, (-1, 0, 0), 9.1), "wall_xn": (-1.5, (1, 0, 0), 9.1),
              "wall_yp": (1.5, (0, -1, 0), 18.2), "wall_yn": (-2.0, (0, 1, 0), 18.2)}
    for name, (coord, normal, area) in expect.items():
        axis = int(np.flatnonzero(normal)[0])
        assert w[name].point[axis] == pytest.approx(coord, abs=1e-5)
        np.testing.assert_allclose(w[name].normal, normal, atol=1e-6)
        assert w[name].area == pytest.approx(area, rel=1e-5)
        assert (centre - w[name].point) @ w[name].normal > 0
    assert np.ptp(w["wall_xp"].polygon[:, 2]) == pytest.approx(2.6, abs=1e-5)


@pytest.mark.parametrize("name", ["room:1,2,3", "room:0,0.5,0,4,3", "room:0,4,0,4,30", "room:a,b,c,d,e"])
def test_bad_room_names_are_one_line(name):
    with pytest.raises(ValueError, match="room") as e:
        room_bounds(name)
    assert "\n" not in str(e.value)
