"""`scripts/glasgow_motion_stats.py`'s per-clip statistics on signatures whose answers are known on paper."""
import importlib.util
from pathlib import Path

import numpy as np
import pytest

_SPEC = importlib.util.spec_from_file_location(
    "glasgow_motion_stats", Path(__file__).resolve().parents[1] / "scripts" / "glasgow_motion_stats.py")
stats = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(stats)


def test_clip_stats_of_a_back_and_forth_walk():
    # mean velocity 1.2 sin(2 pi t / 5) over 10 s: 3 sign changes (t = 2.5, 5, 7.5 s); |v| > 0.3 m/s except
    # within asin(0.25) / (2 pi / 5) = 0.20 s of each zero: 3 inner zeros (2.5, 5, 7.5 s) and one side of the
    # ends (0, 10 s) -> slow share (3 x 2 x 0.20 + 2 x 0.20) / 10 = 0.16; 95th percentile of |1.2 sin| =
    # 1.2 sin(0.95 pi / 2) = 1.19 m/s.
    t = np.arange(0.0, 10.0, 0.01)
    v = np.linspace(-6, 6, 321)
    mv = 1.2 * np.sin(2 * np.pi * t / 5)
    # p(v,t): a Gaussian of sigma 0.2 m/s about the mean velocity; its -20 dB width is
    # 2 sigma sqrt(2 ln 100) = 1.21 m/s; the extent runs between grid points inside it, so it is short by up to
    # one 0.0375 m/s grid step at each edge
    p = np.exp(-0.5 * ((v[:, None] - mv[None]) / 0.2) ** 2)
    s = stats.clip_stats(p, v, mv, np.ones(t.size, bool), t)
    assert s["turns_per_10s"] == pytest.approx(3 * 10 / np.ptp(t), rel=1e-6)
    assert s["slow_share"] == pytest.approx(0.16, abs=0.01)
    assert s["v95"] == pytest.approx(1.2 * np.sin(0.95 * np.pi / 2), abs=0.01)
    width = 2 * 0.2 * np.sqrt(2 * np.log(100))
    assert width - 2 * 0.0375 <= s["ext20"] <= width
    assert s["active_s"] == pytest.approx(np.ptp(t), abs=0.3)  # moving from the first to the last second


def test_clip_stats_of_a_still_clip_have_no_motion():
    t = np.arange(0.0, 5.0, 0.01)
    v = np.linspace(-6, 6, 321)
    p = np.ones((v.size, t.size))
    s = stats.clip_stats(p, v, np.zeros(t.size), np.zeros(t.size, bool), t)
    assert (s["v95"], s["turns_per_10s"], s["active_s"], s["slow_share"]) == (0.0, 0.0, 0.0, 1.0)
    assert np.isnan(s["onset_s"])  # no activity, no onset (the summary's median skips it)


def test_lobes_of_a_stoop_and_rise():
    # a pick: +0.5 m/s for 0.8 s from 1.0 s, then -0.4 m/s for 0.8 s from 2.2 s (0.01 s bins); the 0.3 s
    # box smoothing keeps a plateau longer than 0.3 s at its value, and the first sample of each smoothed
    # plateau lies 0.15 s after the rectangle's start: peaks at 1.15 s and 2.35 s, 1.2 s apart
    t = np.arange(0.0, 5.0, 0.01)
    v = np.linspace(-6, 6, 321)
    mv = np.where((t >= 1.0) & (t < 1.8), 0.5, 0.0) + np.where((t >= 2.2) & (t < 3.0), -0.4, 0.0)
    p = np.exp(-0.5 * ((v[:, None] - mv[None]) / 0.2) ** 2)
    s = stats.clip_stats(p, v, mv, np.ones(t.size, bool), t)
    assert s["fwd"] == pytest.approx(0.5, abs=1e-9) and s["back"] == pytest.approx(0.4, abs=1e-9)
    assert s["gap"] == pytest.approx(1.2, abs=0.02)
    # onset: the 0.5 s box average of the +0.5 m/s step exceeds 0.15 m/s once 0.15 s of the step lies in the
    # box, i.e. with the box centred 0.25 - 0.15 = 0.10 s before the step: 0.90 s
    assert s["onset_s"] == pytest.approx(0.90, abs=0.015)
