"""Results are nouns (DESIGN.md): public objects print a short summary, save and load as pairs returning the
same type, expose labelled arrays and plot onto an ``ax=`` the caller gives."""
import dataclasses

import numpy as np
import pytest

from processing.errors import InputError
from rtchannel import Motion


def test_motion_is_immutable_and_replace_validates():
    m = Motion.procedural("fall", seed=0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.positions = m.positions[:, :5]  # another shape: once passed silently
    with pytest.raises(ValueError, match="read-only"):
        m.positions[0, 0, 0] = 1.0
    with pytest.raises(InputError, match="shapes disagree"):
        dataclasses.replace(m, positions=m.positions[:, :5])
    other = dataclasses.replace(m, activity="sit")
    assert other.activity == "sit" and m.activity == "fall"
    np.testing.assert_array_equal(other.positions, m.positions)
    mine = np.zeros((2, 31, 3))
    Motion(m.rig, 60.0, np.tile(np.eye(3), (2, 31, 1, 1)), mine)
    mine[0, 0, 0] = 1.0  # the caller's own array stays writeable
