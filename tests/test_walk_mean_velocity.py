"""A walk toward Radar 1 through the whole chain: the eq.-8 mean velocity follows the pelvis, the range
distribution follows it too, and the final standing position leaves no ghost (the whole-recording mean
removal did: the issue this DSP fixes)."""
import numpy as np
import pytest

from processing.dsp.signatures import DSPConfig, signatures
from processing.synthesis.exact import synthesise
from rtchannel.motion.procedural import generate
from rtchannel.radar import Link, RadarConfig
from rtchannel.pipeline import backend_paths, simulate

RADAR1 = np.array([3.0, 0.0, 1.1])
ACTIVE_MPS = 0.5  # "walking" windows: the pelvis approaches or recedes at >= 0.5 m/s (mean speed 1.3 m/s)
MOVING_MPS = 0.2  # windows "with the person moving"


def _walk(distance=4.0, **pads):
    """`rtchannel simulate --activity walk`'s motion: procedural walk centred on the origin toward Radar 1."""
    return generate("walk", start=(-distance / 2, 0.0), distance=distance, **pads)


def _pelvis(motion, sig, window_s):
    """Pelvis (joint Hips) range at each window centre and its radial velocity (approaching > 0) averaged
    over the window [m, m/s]."""
    r = np.linalg.norm(motion.positions[:, motion.rig.index("Hips")] - RADAR1, axis=-1)
    t = motion.times
    lo, hi = sig.time - window_s / 2, sig.time + window_s / 2
    return np.interp(sig.time, t, r), -(np.interp(hi, t, r) - np.interp(lo, t, r)) / window_s, r[-1]


def _range_peak(sig):
    """Range-distribution peak with 3-point parabolic interpolation of log p' (sub-bin estimate): the argmax
    alone is quantised to +-0.3 m by the 0.6 m bins, the whole tolerance."""
    p = np.log(np.maximum(sig.range_distribution, 1e-300))
    k = np.clip(sig.range_distribution.argmax(axis=0), 1, p.shape[0] - 2)
    c = np.arange(p.shape[1])
    a, b, d = p[k - 1, c], p[k, c], p[k + 1, c]
    den = a - 2 * b + d
    off = np.where(den < 0, 0.5 * (a - d) / np.where(den < 0, den, -1.0), 0.0)
    return sig.range[k] + np.clip(off, -0.5, 0.5) * (sig.range[1] - sig.range[0])


def _check_walk(sig, motion, window_s):
    rp, vp, r_final = _pelvis(motion, sig, window_s)
    act = np.abs(vp) >= ACTIVE_MPS
    assert act.sum() > 50
    ve, vt = sig.mean_velocity[act], vp[act]
    slope = ve @ vt / (vt @ vt)  # least squares through the origin
    rmse = np.sqrt(np.mean((ve - vt) ** 2))
    assert 0.9 <= slope <= 1.1, slope
    assert rmse <= 0.25, rmse
    moving = np.abs(vp) >= MOVING_MPS
    # an FMCW radar shows a moving body at r - kappa v (range-Doppler coupling, 6 cm at 1.3 m/s here)
    from processing.radar.waveform import Waveform
    from processing.synthesis.exact import coupling_s

    err = np.abs(_range_peak(sig) - (rp - coupling_s(Waveform()) * vp))[moving]
    assert err.max() <= 0.3, err.max()
    return rp, r_final


@pytest.fixture(scope="module")
def points_walk():
    radar = RadarConfig()
    motion = _walk()
    return motion, radar, simulate(motion, radar, backend="points", keep_iq=True)


def test_points_walk_mean_velocity_and_range_follow_the_pelvis(points_walk):
    motion, radar, res = points_walk
    _check_walk(res.links["radar1"].signature, motion, radar.dsp.window_chirps * radar.waveform.pri_s)


def test_points_walk_leaves_no_ghost_at_the_final_position(points_walk):
    motion, radar, res = points_walk
    link = res.links["radar1"]
    w = radar.dsp.window_chirps * radar.waveform.pri_s
    ghost = {}
    for kind in ("moving_average", "butterworth", "mean"):
        sig = signatures(link.iq, radar.waveform, DSPConfig(static_removal=kind), t0=link.chirp_times[0])
        rp, vp, r_final = _pelvis(motion, sig, w)
        # windows while the pelvis moves and is > 1.5 m from where it stops: every scatterer (within 0.4 m of
        # the pelvis) is >= 1.1 m, i.e. >= 1.33 bins beyond the final bin's half width, so the rectangular
        # range window leaks at most 1 / (pi 1.33)^2 = 5.7 % of the power there. (Standing still before the
        # walk, the local filter leaves only receiver noise, spread evenly over the 18 bins: 1/18 = 5.6 %.)
        far = (np.abs(rp - r_final) > 1.5) & (np.abs(vp) >= MOVING_MPS)
        assert far.sum() > 50
        ib = np.argmin(np.abs(sig.range - r_final))
        ghost[kind] = sig.range_distribution[ib, far]
    assert ghost["moving_average"].max() <= 0.057
    assert ghost["butterworth"].max() <= 0.057
    # the old whole-recording mean leaves the final standing pose in every window
    assert ghost["mean"].mean() > 0.3


def test_points_walk_zero_velocity_line_is_gone(points_walk):
    motion, radar, res = points_walk
    sig = res.links["radar1"].signature
    _, vp, _ = _pelvis(motion, sig, radar.dsp.window_chirps * radar.waveform.pri_s)
    act = np.abs(vp) >= ACTIVE_MPS
    iz = np.argmin(np.abs(sig.velocity))
    # the stance foot is genuinely near 0 m/s for part of each step; the mean removal put ~half of p(v,t) there
    assert sig.p_vt[iz, act].mean() < 0.1


def test_facets_walk_mean_velocity_and_range_follow_the_pelvis():
    pytest.importorskip("mitsuba")
    radar = RadarConfig(links=[Link(name="radar1", tx=tuple(RADAR1))])
    motion = _walk(2.6, pad_before=0.2, pad_after=0.3)  # 3.5 s in all, lod 2k, free space: a few seconds
    paths = backend_paths(motion, radar, "facets", lod="2k", scene="free_space", walls=False)["radar1"]
    t, iq = synthesise(paths, radar.waveform)
    sig = signatures(iq, radar.waveform, radar.dsp, t0=t[0])
    _check_walk(sig, motion, radar.dsp.window_chirps * radar.waveform.pri_s)
