"""The gridded many-path synthesiser (`processing.synthesis.grid`) against the exact per-path tone sum."""
import math

import numpy as np
import pytest

from processing.pathset import PathSet
from processing.synthesis.exact import _fill_absent, iter_synthesis, synthesise
from processing.synthesis.grid import prepare_frames, spread_kernel
from processing.radar.waveform import C0, Waveform

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


def _within_bound(paths, grid, exact, kernel):
    # Per path and sample the grid's relative error is at most kernel.error_bound; gains are linear between
    # frames, so |a_p(t)| <= max over the two frames (frame-local: frame k fading out plus k+1 fading in).
    # The grid's IQ is stored as complex64 (2^-24 of the largest sample).
    t = np.concatenate([t for t, _ in iter_synthesis(paths, WF, method="exact")])
    k = np.clip(np.searchsorted(paths.times, t, side="right") - 1, 0, paths.n_frames - 2)
    g0, g1 = np.abs(paths.gains[k]), np.abs(paths.gains[k + 1])
    sum_a = np.maximum(g0, g1).sum(axis=1) if paths.persistent else (g0 + g1).sum(axis=1)
    err = np.abs(grid.astype(np.complex128) - exact)
    return np.all(err <= kernel.error_bound * sum_a[:, None] + 2 ** -23 * np.abs(exact).max())


@pytest.mark.parametrize("persistent", [True, False])
def test_grid_matches_exact_within_its_bound(persistent):
    paths = _random_paths(persistent)
    _, exact = synthesise(paths, WF, method="exact")
    t, grid = synthesise(paths, WF, method="grid")
    assert np.all(np.isfinite(grid)) and grid.shape == exact.shape
    assert _within_bound(paths, grid, exact, spread_kernel())
    # the bound is -115 dB; the old Taylor grid's was (pi/8)^4/24 = 1e-3
    assert spread_kernel().error_bound < 2e-6


def test_kernel_bound_shrinks_with_width():
    # A wider kernel suppresses the grid's aliases more, until the degree-5 weight polynomials limit it
    # (module docstring): the measured errors stay below each bound.
    paths = _random_paths(True, n_paths=70, seconds=0.1)
    exact = np.concatenate([iq for _, iq in iter_synthesis(paths, WF, method="exact")]).astype(np.complex128)
    bounds = {}
    for width in (2, 4, 8):
        k = spread_kernel(4, width)
        bounds[width] = k.error_bound
        import processing.synthesis.grid as sg
        from processing.synthesis.exact import grid_pieces, chirp_times

        pieces = grid_pieces(paths)
        tt = chirp_times(paths.times[0], paths.times[-1], WF.pri_s)
        grid = sg.gridded_tone_sum(tt, *pieces[:7], WF.start_hz, WF.slope, WF.fs, WF.samples_per_chirp, k)
        assert _within_bound(paths, grid.astype(np.complex64), exact, k)
    assert bounds[2] > 10 * bounds[4] > 100 * bounds[8]


def test_grid_aliases_like_an_adc_beyond_max_range():
    # a path beyond c fs / (2 gamma) wraps round the delay grid exactly as the exact sum's beat tone aliases
    r_far = WF.max_unambiguous_range * 1.3
    paths = _random_paths(True, n_paths=70, seconds=0.1, r_lo=r_far, r_hi=r_far + 2)
    with pytest.warns(UserWarning):
        _, exact = synthesise(paths, WF, method="exact")
    with pytest.warns(UserWarning):
        _, grid = synthesise(paths, WF, method="grid")
    assert _within_bound(paths, grid, exact.astype(np.complex128), spread_kernel())


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


def test_grid_chunking_changes_only_rounding():
    paths = _random_paths(True, seconds=0.2)
    _, a = synthesise(paths, WF, method="grid", chunk_chirps=37)
    _, b = synthesise(paths, WF, method="grid", chunk_chirps=4096)
    assert np.abs(a - b).max() <= 2 ** -22 * np.abs(b).max()


def test_prepared_frames_fill_gaps_like_the_exact_route():
    # the compiled gap filling is bitwise np.interp's (synthesis._fill_absent), incl. never-present paths;
    # the Nyquist check's maxima skip absent frames (NaN)
    rng = np.random.default_rng(0)
    times = np.sort(rng.uniform(0, 5, 50))
    d = rng.uniform(1e-8, 5e-8, (50, 300))
    d[rng.random(d.shape) < 0.3] = np.nan
    d[:, 5] = np.nan
    d[:3, 7] = np.nan
    d[-4:, 8] = np.nan
    rates = np.where(np.isfinite(d), rng.normal(size=d.shape) * 1e-8, np.nan)
    gains = np.where(np.isfinite(d), 1.0 + 0j, 0)
    filled, rate_max, delay_max = prepare_frames(times, d, rates, gains)
    np.testing.assert_array_equal(filled, _fill_absent(times, d))
    assert rate_max == np.nanmax(np.abs(rates)) and delay_max == np.nanmax(d)


def test_sincos_matches_libm():
    from processing.numba_math import sincos as _sincos
    import numba

    @numba.njit
    def run(x):
        s, c = np.empty_like(x), np.empty_like(x)
        for i in range(x.size):
            s[i], c[i] = _sincos(x[i])
        return s, c

    x = np.concatenate([np.linspace(-50, 50, 100001), 2 * math.pi * np.arange(-3, 4) / 4])
    s, c = run(x)
    # Cody-Waite reduction: |x| up to 50 costs ~|x| ulp of pi/2's tail; 1e-14 absolute
    assert np.abs(s - np.sin(x)).max() < 1e-14 and np.abs(c - np.cos(x)).max() < 1e-14
