"""Field helpers shared by the plan schema's layers (`plan_schema`, `plan_physical`): value-or-range fields,
per-activity settings and the strict base model."""
from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from processing.errors import InputError
from rtchannel.motion.procedural import ACTIVITIES

Scalar = float | tuple[float, float]  # a value, or a (low, high) range drawn uniformly per motion variant
_NAME = r"^[A-Za-z0-9_\-]+$"


def _within(v, lo: float, hi: float, name: str, unit: str = ""):
    """`v` (a value or a (low, high) range) when every value lies in [lo, hi]; ValueError naming it otherwise."""
    for x in (v if isinstance(v, tuple) else (v,)):
        if not lo <= x <= hi:
            raise InputError(f"{name} {x}{unit} outside {lo:g}-{hi:g}{unit}")
    return v


def unique_names(items, what: str):
    """`items` when their ``name`` attributes are distinct; InputError naming them (`what`: "link", ...) otherwise."""
    names = [it.name for it in items]
    if len(set(names)) != len(names):
        raise InputError(f"{what} names must be unique, got {names}")
    return items


def for_activity(v, activity: str):
    """A per-activity setting's value for `activity` ('*' for any other; None if neither), or `v` itself."""
    return v.get(activity, v.get("*")) if isinstance(v, dict) else v


def _per_activity(v: dict, name: str) -> dict:
    """`v` when its keys are activities or '*'; ValueError naming the first other key."""
    for k in v:
        if k != "*" and k not in ACTIVITIES:
            raise InputError(f"{name}: {k!r} is not an activity ({', '.join(ACTIVITIES)}) or '*'")
    return v


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
