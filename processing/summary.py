"""Short summaries of settings models for `repr` (the project's objects print a summary, never whole arrays).

`settings_repr(model)` writes a pydantic model as its class name and the fields that differ from their
defaults (nested models the same way), cut to `MAX_REPR` characters: ``DSPConfig(window_chirps=128)``.
"""
from __future__ import annotations

MAX_REPR = 600  # no repr of a public object is longer (tests/test_result_nouns.py)


def settings_repr(model, limit: int = MAX_REPR) -> str:
    """`Name(field=value, ...)` of the fields of the pydantic `model` that are not at their defaults, with
    nested models summarised the same way and the whole cut to `limit` characters (ending in "...)")."""
    parts = []
    for name, info in type(model).model_fields.items():
        value = getattr(model, name)
        if not info.is_required() and value == info.get_default(call_default_factory=True):
            continue
        text = settings_repr(value, limit) if hasattr(type(value), "model_fields") else repr(value)
        parts.append(f"{name}={text}")
    out = f"{type(model).__name__}({', '.join(parts)})"
    return out if len(out) <= limit else out[:limit - 4] + "...)"
