import numpy as np
import pytest

from processing.pathset import PathSet
from processing.radar.waveform import C0


def moving_point_paths(ranges: np.ndarray, times: np.ndarray, gain: complex = 1.0) -> PathSet:
    """Persistent single path whose (bistatic half-path) range follows `ranges` [m] at `times` [s]."""
    return PathSet(times=times, delays=(2 * ranges / C0)[:, None], gains=np.full((times.size, 1), gain, complex),
                   ids=np.array([0]))


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture
def shared_data():
    """Path of a third-party data file (relative path as in the data registry); skips when absent."""
    from thirdparty import data_path

    return data_path


@pytest.fixture(scope="session")
def glasgow_dir(tmp_path_factory):
    """A folder of the twelve real Glasgow test images (skips when they are not available)."""
    from thirdparty import glasgow_folder

    return glasgow_folder(tmp_path_factory.mktemp("glasgow"))


def pytest_terminal_summary(terminalreporter):
    """How many generated inputs each fuzz test accepted (tests/fuzz_tally.py)."""
    from fuzz_tally import summary

    lines = summary()
    if lines:
        terminalreporter.section("fuzz tests: accepted inputs")
        for line in lines:
            terminalreporter.write_line(line)
