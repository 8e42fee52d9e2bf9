"""Every physical constant and the default carrier have one home (`processing.constants`): no other module
of the library writes their value as a literal, and the old names are the same objects."""
import io
import tokenize
from pathlib import Path

import pytest

from processing import constants

REPO = Path(__file__).resolve().parents[1]
HOMED = {constants.SPEED_OF_LIGHT_M_S: "SPEED_OF_LIGHT_M_S", constants.DEFAULT_CARRIER_HZ: "DEFAULT_CARRIER_HZ",
         constants.EPSILON_0_F_M: "EPSILON_0_F_M", constants.K_BOLTZMANN_J_K: "K_BOLTZMANN_J_K",
         8.8541878128e-12: "EPSILON_0_F_M (CODATA 2018)", 3e8: "SPEED_OF_LIGHT_M_S (rounded)"}


def _literals(path: Path):
    """(line, value) of every number in the code of `path` (comments and strings are not code)."""
    for tok in tokenize.generate_tokens(io.StringIO(path.read_text()).readline):
        if tok.type == tokenize.NUMBER:
            try:
                yield tok.start[0], float(tok.string.replace("_", ""))
            except ValueError:  # complex literals such as 1j
                continue


def test_no_other_module_writes_a_homed_constant():
    found = [f"{p.relative_to(REPO)}:{line}: {HOMED[v]}" for pkg in ("rtchannel", "processing")
             for p in sorted((REPO / pkg).rglob("*.py")) if p.name != "constants.py"
             for line, v in _literals(p) if v in HOMED]
    assert not found, "use processing.constants: " + "; ".join(found)


def test_the_old_names_are_the_constants():
    from processing.radar import receiver, waveform

    assert waveform.C0 is constants.C0 == 299_792_458.0
    assert receiver.K_BOLTZMANN is constants.K_BOLTZMANN_J_K and receiver.T0_K is constants.T0_K
    assert waveform.Waveform().carrier_hz == constants.DEFAULT_CARRIER_HZ


def test_values_agree_with_scipy():
    scipy_constants = pytest.importorskip("scipy.constants")
    assert constants.SPEED_OF_LIGHT_M_S == scipy_constants.c
    assert constants.EPSILON_0_F_M == scipy_constants.epsilon_0
    assert constants.K_BOLTZMANN_J_K == scipy_constants.k
