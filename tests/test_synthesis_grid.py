"""The gridded many-path synthesiser against the exact per-path tone sum."""
import math

import numpy as np
import pytest

from processing.pathset import PathSet
from processing.synthesis import synthesise
from processing.waveform import C0, Waveform

WF = Waveform()


def _random_paths(persistent: bool, n_paths=120, seconds=0.4, fps=60, seed=1, r_lo=1.0, r_hi=6.0):
    rng = np.random.default_rng(seed)
    times = np.arange(0, seconds + 1e-9, 1 / fps)
    r0 = rng.uniform(r_lo, r_hi, n_paths)
    v = rng.uniform(-4, 4, n_paths)                       # radial speeds within v_max = 6.2 m/s
    amp, w = rng.uniform(0, 0.05, n_paths), rng.uniform(2, 12, n_paths)
    r = r0 - v * times[:, None] + amp * np.sin(w * times[:, None])
    gains = (rng.normal(size=n_paths) + 1j * rng.normal(size=n_paths)) * (1 + 0.2 * np.cos(times[:, None]))
    gains[5:9, :20] = 0                                   # paths that vanish for a few frames
    delays = np.where(gains != 0, 2 * r / C0, np.nan)
    rates = None if persistent else 2 * (-v + amp * w * np.cos(w * times[:, None])) / C0
    return PathSet(times, delays, gains, ids=np.arange(n_paths) if persistent else None, delay_rates=rates)


# Per path, the third-order sub-grid expansion leaves at most (pi/oversample)^4/4! of its amplitude
# (module docstring); the relative error of a sum of paths cannot exceed that bound.
BOUND_8X = (math.pi / 8) ** 4 / 24


@pytest.mark.parametrize("persistent", [True, False])
def test_grid_matches_exact(persistent):
    paths = _random_paths(persistent)
    _, exact = synthesise(paths, WF, method="exact")
    t, grid = synthesise(paths, WF, method="grid")
    err = np.linalg.norm(grid - exact) / np.linalg.norm(exact)
    assert err < BOUND_8X
    assert np.all(np.isfinite(grid)) and grid.shape == exact.shape


def test_grid_error_shrinks_with_oversampling():
    from processing.synthesis import iter_synthesis

    paths = _random_paths(True, n_paths=40, seconds=0.1)
    exact = np.concatenate([iq for _, iq in iter_synthesis(paths, WF, method="exact")])
    errs = {}
    for ov in (2, 4, 8):
        grid = np.concatenate([iq for _, iq in iter_synthesis(paths, WF, method="grid", oversample=ov)])
        errs[ov] = np.linalg.norm(grid - exact) / np.linalg.norm(exact)
        assert errs[ov] < (math.pi / ov) ** 4 / 24
    # fourth-order truncation: halving the grid step divides the error by about 2^4
    assert errs[4] < errs[2] / 6 and errs[8] < errs[4] / 6


def test_grid_aliases_like_an_adc_beyond_max_range():
    # a path beyond c fs / (2 gamma) wraps round the delay grid exactly as the exact sum's beat tone aliases
    r_far = WF.max_unambiguous_range * 1.3
    paths = _random_paths(True, n_paths=70, seconds=0.1, r_lo=r_far, r_hi=r_far + 2)
    with pytest.warns(UserWarning):
        _, exact = synthesise(paths, WF, method="exact")
    with pytest.warns(UserWarning):
        _, grid = synthesise(paths, WF, method="grid")
    assert np.linalg.norm(grid - exact) / np.linalg.norm(exact) < BOUND_8X


def test_auto_uses_exact_for_few_paths_and_handles_silence():
    few = _random_paths(True, n_paths=5, seconds=0.05)
    _, a = synthesise(few, WF, method="auto")
    _, b = synthesise(few, WF, method="exact")
    np.testing.assert_array_equal(a, b)
    silent = _random_paths(True, n_paths=80, seconds=0.05)
    silent.gains[:] = 0
    _, z = synthesise(silent, WF, method="grid")
    assert np.all(z == 0)
    with pytest.raises(ValueError, match="method"):
        synthesise(few, WF, method="fast")
