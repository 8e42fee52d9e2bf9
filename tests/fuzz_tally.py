"""How many generated inputs each fuzz test accepted: a generator that ends up rejecting everything (a
strategy drifting away from valid inputs, or a validator refusing too much) tests only the error paths, so
every fuzz test counts its accepted inputs (`tally`) and its module asserts a lower bound per test
(`accepted_at_least`, in a module-scoped fixture after the module's tests ran). The counts are printed in
the terminal summary (tests/conftest.py)."""
from __future__ import annotations

import os

COUNTS: dict[str, list[int]] = {}  # test id -> [generated, accepted]


def _current() -> str:
    return os.environ.get("PYTEST_CURRENT_TEST", "?").rsplit(" (", 1)[0]


def tally(accepted: bool) -> bool:
    """Count one generated input of the running test; returns `accepted`."""
    c = COUNTS.setdefault(_current(), [0, 0])
    c[0] += 1
    c[1] += bool(accepted)
    return accepted


def accepted_at_least(minimums: dict[str, int]) -> None:
    """Assert that each test named in `minimums` (its function name) that ran accepted at least that many of
    its generated inputs (its parametrised cases together)."""
    for test, least in minimums.items():
        runs = [c for k, c in COUNTS.items() if k.split("::")[-1].split("[")[0] == test]
        if not runs:  # deselected
            continue
        generated, accepted = (sum(c[i] for c in runs) for i in (0, 1))
        assert accepted >= least, (f"{test}: {accepted} of {generated} generated inputs accepted, expected at least "
                                   f"{least}: the generator no longer reaches the paths that accept input")


def summary() -> list[str]:
    """One line per fuzz test that ran: accepted of generated."""
    return [f"{k}: accepted {a} of {g} generated inputs" for k, (g, a) in sorted(COUNTS.items())]
