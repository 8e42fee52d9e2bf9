"""Placement of imported motion (issue 23, item 6): an imported walk is centred like a procedural one and
simulates with the default radar; --trim and --heading change what they say; a walk into an antenna is one
line naming the options that move the person."""
import h5py
import numpy as np
import pytest

from rtchannel.cli import main
from rtchannel.motion.compose import place_take as placed_take
from rtchannel.motion.pose import Motion

TAKE = "mocap/cmu/walk/05_01_iclone.bvh"  # 4.4 m straight walk along the take's own forward axis


@pytest.fixture(scope="module")
def walk():
    from thirdparty import data_path

    return Motion.from_file(data_path(TAKE), activity="walk")


def test_imported_walk_is_centred_on_the_origin(walk):
    placed = placed_take(walk)
    hips = placed.positions[:, 0, :2]
    np.testing.assert_allclose(0.5 * (hips[0] + hips[-1]), 0.0, atol=1e-9)  # the middle of its path
    travel = hips[-1] - hips[0]
    assert np.linalg.norm(travel) > 3.0 and abs(np.degrees(np.arctan2(travel[1], travel[0]))) < 15  # toward +x


def test_heading_turns_the_walk_and_start_places_its_first_frame(walk):
    placed = placed_take(walk, heading_deg=90.0, start=(-1.0, -2.0))
    hips = placed.positions[:, 0, :2]
    np.testing.assert_allclose(hips[0], (-1.0, -2.0), atol=1e-9)
    travel = hips[-1] - hips[0]
    assert np.degrees(np.arctan2(travel[1], travel[0])) == pytest.approx(90.0, abs=15.0)  # now along +y


def test_trim_keeps_the_seconds_asked_for(walk):
    t = placed_take(walk, trim=(1.0, 2.5))
    assert t.duration == pytest.approx(1.5, abs=1.5 / t.fps)
    with pytest.raises(Exception, match="--trim"):
        placed_take(walk, trim=(2.0, 1.0))


def test_imported_walk_simulates_with_the_default_radar_and_toward_the_start_errors_name_the_options(
        tmp_path, capsys, shared_data):
    take = str(shared_data(TAKE))
    assert main(["simulate", "--motion-file", take, "--activity", "walk", "--out", str(tmp_path / "c"),
                 "--quiet", "--no-plots"]) == 0
    with h5py.File(tmp_path / "c" / "signature.h5") as f:
        assert np.median(f["radar1"]["mean_velocity"][()]) > 0.5  # it walks toward Radar 1
    assert main(["simulate", "--motion-file", take, "--activity", "walk", "--start", "0", "0",
                 "--out", str(tmp_path / "x"), "--quiet", "--no-plots"]) == 2  # from the origin into Radar 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--start X Y" in err and "--heading" in err
    assert main(["simulate", "--activity", "walk", "--trim", "0", "1", "--out", str(tmp_path / "p")]) == 2
    assert "--trim applies to --motion-file" in capsys.readouterr().err
