"""Signature distances (paper values) and the `compare` command."""
import csv

import numpy as np
import pytest

from processing.metrics.distances import mean_velocity_rmse, normalised_dtw, pvt_tv_distance
from rtchannel.cli import main


def test_dtw_of_constant_offset_is_the_offset():
    # two constant curves c apart: every warping path has >= N steps of squared difference c^2 and the
    # diagonal has exactly N, so DTW = sqrt(N) c and the normalised value is c / scale
    a, b = np.zeros(50), np.full(50, 0.3)
    assert normalised_dtw(a, b, scale=1.5) == pytest.approx(0.2, rel=1e-12)
    assert normalised_dtw(a, b) == pytest.approx(1.0, rel=1e-12)  # default scale: peak |v| = 0.3


def test_dtw_ignores_a_time_shift_that_rmse_sees():
    t = np.linspace(0, 4, 200)
    a = np.exp(-((t - 1.5) / 0.3) ** 2)
    b = np.exp(-((t - 2.0) / 0.3) ** 2)
    assert normalised_dtw(a, b) < 0.05
    assert mean_velocity_rmse(a, b) > 0.3
    assert normalised_dtw(np.zeros(5), np.zeros(7)) == 0.0


def test_tv_distance_paper_values():
    p = np.zeros((4, 3))
    p[0] = 1.0
    q = np.zeros((4, 3))
    q[0, :2] = 1.0
    q[1, 2] = 1.0            # last column: disjoint support -> TV 1
    assert pvt_tv_distance(p, p * 7.0) == 0.0          # per-column normalisation: scale-free
    assert pvt_tv_distance(p, q) == pytest.approx(1 / 3)
    half = p.copy()
    half[1] = 1.0            # columns (1/2, 1/2) vs (1, 0): TV 1/2
    assert pvt_tv_distance(p, half) == pytest.approx(0.5)


def test_compare_command_writes_table_and_figure(tmp_path):
    out = tmp_path / "cmp"
    code = main(["compare", "--backends", "points", "points", "--activities", "walk", "sit", "--out", str(out),
                 "--option", "points.scale=seed", "--quiet"])
    assert code == 0
    rows = list(csv.reader((out / "dtw_points_vs_points.csv").open()))
    assert rows[0][1:] == ["walk", "sit"] and [r[0] for r in rows[1:]] == ["walk", "sit"]
    d = np.array([[float(x) for x in r[1:]] for r in rows[1:]])
    assert d[0, 0] == 0.0 and d[1, 1] == 0.0 and d[0, 1] > 0.1 and d[1, 0] > 0.1
    assert (out / "pvt_side_by_side.png").stat().st_size > 10_000


def test_compare_rejects_bad_input(capsys):
    assert main(["compare", "--backends", "points", "--out", "x"]) == 2
    assert main(["compare", "--backends", "points", "points", "--option", "lod=2k", "--out", "x"]) == 2
    err = capsys.readouterr().err
    assert err.count("error:") == 2 and "BACKEND.NAME=VALUE" in err


def test_pareto_front():
    from rtchannel.analysis.speed_error import pareto_front

    cost = np.array([1.0, 2.0, 3.0, 0.5, 2.5])
    err = np.array([0.5, 0.2, 0.1, 0.9, 0.3])   # (2.5, 0.3) is beaten by (2.0, 0.2)
    assert list(pareto_front(cost, err)) == [3, 0, 1, 2]


def test_earth_mover_distance_paper_values():
    from processing.metrics.distances import pvt_wasserstein

    v = np.arange(8) * 0.25                       # 0.25 m/s bins
    p = np.zeros((8, 2))
    p[2] = 1.0
    q = np.zeros((8, 2))
    q[3] = 1.0                                    # every column's line moved one bin
    assert pvt_wasserstein(p, q, v) == pytest.approx(0.25)
    assert pvt_tv_distance(p, q) == 1.0           # TV saturates at once
    half = q.copy()
    half[2, :] = 1.0                              # half the energy stays: mean shift 0.125 m/s
    assert pvt_wasserstein(p, half, v) == pytest.approx(0.125)
    assert pvt_wasserstein(p, p * 3, v) == 0.0


def test_ensemble_mean_and_half_split_error():
    """The reference's self error from two half means: K runs = truth + independent noise of s.d. sigma per
    run; each half mean has noise sigma / sqrt(K/2), their difference sqrt(2) times that, and half of it
    estimates the full mean's error sigma / sqrt(K). Checked on mean-velocity RMSE with K = 64 Gaussian
    runs of sigma = 0.1 m/s over 400 time bins: expected 0.1 / 8 = 0.0125 m/s, the estimate's relative
    spread ~ 1/sqrt(2 * 400) ~ 4 %, so +-15 % is ample."""
    from types import SimpleNamespace

    from rtchannel.analysis.speed_error import _mean_distances, ensemble_mean

    rng = np.random.default_rng(1)
    v = np.linspace(-1, 1, 16)
    truth = np.sin(np.linspace(0, 6, 400))

    def run():
        p = rng.random((16, 400))
        return {"r1": SimpleNamespace(p_vt=p, velocity=v, mean_velocity=truth + 0.1 * rng.standard_normal(400))}

    runs = [run() for _ in range(64)]
    mean = ensemble_mean(runs)
    np.testing.assert_allclose(mean["r1"].p_vt.sum(axis=0), 1.0)  # columns stay distributions
    half = _mean_distances(ensemble_mean(runs[0::2]), ensemble_mean(runs[1::2]))
    assert abs(half["rmse_m_s"] / 2 - 0.0125) < 0.15 * 0.0125, half["rmse_m_s"] / 2
    full_err = np.sqrt(np.mean((mean["r1"].mean_velocity - truth) ** 2))
    assert abs(full_err - 0.0125) < 0.15 * 0.0125, full_err


def test_dtw_is_finite_where_pruning_failed():
    """dtaidistance 2.5's pruned DTW returned inf for this pair (a flat simulated curve against a real
    Glasgow sit-down's mean velocity, 311 samples at 16 ms); the DTW of two finite curves is finite and at
    most their Euclidean distance (the diagonal is one warping path)."""
    from pathlib import Path

    from processing.metrics.distances import normalised_dtw

    b = np.load(Path(__file__).parent / "data" / "dtw_pruning_case.npy")
    a = np.zeros_like(b)  # the pruned DTW of exactly this pair is inf
    d = normalised_dtw(a, b, scale=1.0) * np.sqrt(b.size)
    assert np.isfinite(d) and d <= np.linalg.norm(a - b) + 1e-12


def test_single_realisation_floor_is_the_distance_between_two_single_reference_runs(monkeypatch):
    """Reference seeds 1..4 put all power in velocity bins 0, 1, 1, 0 (bins 0.25 m/s apart): the paired single
    runs (seeds 1-2, 3-4) are one bin apart, so the floor is an EMD of exactly 0.25 m/s, while the half-split
    self error of the mean is 0 (the even and odd runs make the same mixture)."""
    from types import SimpleNamespace

    import rtchannel.analysis.speed_error as se

    v = np.arange(8) * 0.25

    def fake_run(setting, motion, radar, repeats, seed=0):
        p = np.zeros((8, 20))
        b = (seed // 2) % 2
        p[b] = 1.0
        return 1.0, {"r1": SimpleNamespace(p_vt=p, velocity=v, mean_velocity=np.full(20, v[b]))}

    monkeypatch.setattr(se, "_run", fake_run)
    _, _, self_error = se.converged_reference(se.REFERENCE, None, None, seeds=4)
    assert self_error["single_run_emd_m_s"] == pytest.approx(0.25, abs=1e-12)
    assert self_error["emd_m_s"] == pytest.approx(0.0, abs=1e-12)


def test_a_sweep_without_repeats_is_refused_before_any_run():
    # Found by mypy: repeats=0 left no run to take the signatures of (an AttributeError on None, or a
    # StatisticsError on the empty timings), after the reference had already been simulated.
    from processing.errors import InputError
    from rtchannel.analysis.speed_error import sweep

    with pytest.raises(InputError, match="repeats must be at least 1, got 0"):
        sweep(None, None, repeats=0)
