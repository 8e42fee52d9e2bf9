"""The per-process motion cache of the dataset items is keyed by the whole motion, not its id (issue 13:
the same seed gives the same bytes whatever ran before in the process)."""
import numpy as np

from rtchannel.dataset.items import build_motion
from rtchannel.dataset.plan import Plan, expand


def _first_motion(seed: int, height: float) -> dict:
    plan = Plan.model_validate({"seed": seed, "motion": {"sources": [{"procedural": "fall"}], "heights": [height]},
                                "physical": {"directions": [1]}})
    return expand(plan)[0].motion


def test_same_motion_id_in_two_plans_gives_each_plans_motion():
    a, b = _first_motion(3, 1.6), _first_motion(5, 1.8)
    assert a["key"] == b["key"]  # ids repeat across plans: "fall-00-0000-m00"
    ma, mb = build_motion(a), build_motion(b)
    assert ma is not mb and build_motion(a) is ma  # cached per motion, not per id
    # the 1.8 m body is taller than the 1.6 m one: the head's highest point differs by ~0.2 m
    top = lambda m: float(np.max(m.positions[..., 2]))  # noqa: E731
    assert top(mb) - top(ma) > 0.1
