"""Issue 41 (the time a user waits): each faster route of the chain equals the plain route it replaced.

The STFT (chunked, only the kept velocity bins reordered), the knife-edge kernel (a blocked segment's outline
one direction at a time), the clutter patches (one numpy expression) and the dataset items (the scene cached
per motion, no range-Doppler maps) are compared with a plain evaluation of the same definitions in this file.
Where the plain route does the same floating-point operations the comparison is exact; the knife-edge
reference re-derives each segment's plane with numpy (other rounding), so its nu agree to 1e-12.
"""
from __future__ import annotations

import numpy as np
import pytest

from processing.dsp.config import DSPConfig
from processing.dsp.mti import mti_filter
from processing.dsp.signatures import _doppler_taper, _normalise, signatures
from processing.fast_time import doppler_band, project
from processing.radar.waveform import Waveform
from rtchannel.radar import GLASGOW_WAVEFORM, glasgow_dsp


def _iq(wf: Waveform, seconds: float, seed: int = 0) -> np.ndarray:
    """Raw IQ [C, N] of three point targets moving at 0.4, -1.3 and 2.9 m/s from 2-3 m, plus white noise."""
    rng = np.random.default_rng(seed)
    n_c = int(seconds / wf.pri_s)
    t = np.arange(n_c)[:, None] * wf.pri_s + np.arange(wf.samples_per_chirp)[None, :] / wf.fs
    iq = np.zeros(t.shape, complex)
    for r0, v, a in ((2.0, 0.4, 1.0), (2.5, -1.3, 0.5), (3.0, 2.9, 0.2)):
        tau = 2 * (r0 - v * t) / 299792458.0
        iq += a * np.exp(2j * np.pi * (wf.carrier_hz * tau + wf.slope * tau * (t % wf.pri_s)))
    return iq + 1e-3 * (rng.normal(size=t.shape) + 1j * rng.normal(size=t.shape))


def _plain_pvt_power(iq, wf: Waveform, cfg: DSPConfig) -> np.ndarray:
    """p(v,t) x window power [V, T] of the range bins' magnitude (or coherent) sum, window by window: each window's
    whole FFT, every bin put in velocity order, then the crop (the route before issue 41)."""
    proj = project(iq, wf, cfg)
    prf, w, hop, nfft = 1.0 / wf.pri_s, cfg.window_chirps, cfg.hop_chirps, cfg.nfft
    order = (nfft // 2 - np.arange(nfft)) % nfft
    taper = _doppler_taper(cfg)
    if cfg.range_sum == "coherent":
        x, f_ref = mti_filter(proj.coherent, prf, wf.carrier_hz, cfg)[:, None], proj.coherent_carrier_hz
    else:
        band = doppler_band(proj.range, wf, cfg)
        x, f_ref = mti_filter(proj.profiles, prf, wf.carrier_hz, cfg)[:, band], wf.carrier_hz
    cols = []
    for s in range(0, x.shape[0] - w + 1, hop):
        spec = np.fft.fft(x[s:s + w].T * taper, n=nfft, axis=-1)[:, order]  # [R, nfft]
        cols.append(np.abs(spec).sum(axis=0) ** 2 if cfg.range_sum == "magnitude" else
                    (np.abs(spec) ** 2).sum(axis=0))
    velocity = (np.arange(nfft) - nfft // 2) * 299792458.0 / (2 * f_ref * nfft * wf.pri_s)
    keep = np.ones(nfft, bool) if cfg.velocity_crop_mps is None else \
        np.abs(velocity) <= cfg.velocity_crop_mps * (1 + 1e-12)
    return np.array(cols).T[keep]


@pytest.mark.parametrize("which", ["glasgow", "seed"])
def test_stft_route_equals_the_plain_windows(which):
    # Glasgow: magnitude sum of 800-point FFTs of 200-chirp windows, cropped to +-6 m/s (about half the bins);
    # seed: coherent sum, 64-point windows, no crop. p(v,t) and the window power the same bit for bit.
    wf, cfg = (GLASGOW_WAVEFORM, glasgow_dsp()) if which == "glasgow" else (Waveform(), DSPConfig())
    iq = _iq(wf, 1.2 if which == "glasgow" else 0.4)
    sig = signatures(iq, wf, cfg)
    plain = _plain_pvt_power(iq, wf, cfg)
    p_vt, _, total = _normalise(np.ascontiguousarray(plain), cfg.empty_floor, 0.0)
    assert sig.p_vt.shape == plain.shape and plain.shape[1] > 10
    np.testing.assert_array_equal(sig.power, total)
    np.testing.assert_array_equal(sig.p_vt, p_vt)


def test_stft_chunking_does_not_change_the_signatures(monkeypatch):
    import processing.dsp.signatures as dsp

    wf, cfg = GLASGOW_WAVEFORM, glasgow_dsp()
    iq = _iq(wf, 1.0, seed=3)
    small = signatures(iq, wf, cfg)
    monkeypatch.setattr(dsp, "_CHUNK", 1 << 26)  # every window in one chunk
    whole = signatures(iq, wf, cfg)
    for name in ("p_vt", "power", "mean_velocity", "range_distribution", "range_doppler"):
        np.testing.assert_array_equal(getattr(small, name), getattr(whole, name))


def _plain_nu(pos, targets, verts, frame, hit, lam, faces):
    """`knife_edge.shadow_nu` segment by segment in numpy, from its module docstring and the same window."""
    from rtchannel.backends import knife_edge as ke

    d = verts - pos
    bearing = np.arctan2(d[..., 1].mean(axis=1), d[..., 0].mean(axis=1))
    az = np.angle(np.exp(1j * (np.arctan2(d[..., 1], d[..., 0]) - bearing[:, None])))
    az = np.where(ke.silhouette(pos, verts, faces), az, np.inf)
    dist = np.linalg.norm(d, axis=-1)
    el = np.arcsin(np.clip(d[..., 2] / dist, -1, 1))
    cap, clear = ke.NU_MAX / np.sqrt(2.0), -ke.NU_CLEAR / np.sqrt(2.0)
    angles = 2 * np.pi * np.arange(ke.N_DIRECTIONS) / ke.N_DIRECTIONS
    out = []
    for tgt, b, blocked in zip(targets, frame, hit):
        u = tgt - pos
        length = np.linalg.norm(u)
        u = u / length
        hn = np.hypot(u[0], u[1])
        e1 = np.array([-u[1] / hn, u[0] / hn, 0.0])
        e2 = np.cross(u, e1)
        t_az = np.angle(np.exp(1j * (np.arctan2(tgt[1] - pos[1], tgt[0] - pos[0]) - bearing[b])))
        t_el = np.arcsin(np.clip((tgt[2] - pos[2]) / length, -1, 1))
        reach = cap if blocked else clear
        s0 = min(max(dist[b].min(), 1e-3), length)
        half_el = 1.1 * reach * np.sqrt(lam * max(length - s0, 0.0) / (s0 * length)) + 1e-6
        half = min(half_el / max(hn, 1e-3), np.pi)
        s = d[b] @ u
        sel = (np.abs(az[b] - t_az) <= half) & (np.abs(el[b] - t_el) <= half_el) & (s > 0) & (s < length)
        s = s[sel]
        w = d[b][sel] - s[:, None] * u
        r1 = np.sqrt(lam * s * (length - s) / length)
        x, y = (w @ e1) / r1, (w @ e2) / r1
        if blocked:
            along = x[:, None] * np.cos(angles) + y[:, None] * np.sin(angles)
            inside = (along >= 0) & (np.abs(y[:, None] * np.cos(angles) - x[:, None] * np.sin(angles)) < ke.STRIP)
            sup = np.where(inside, along, -1.0).max(axis=0, initial=-1.0)
            out.append(min(np.sqrt(2.0) * min(cap, np.where(sup >= 0, sup, cap).min()), ke.NU_MAX))
        else:
            out.append(-np.sqrt(2.0) * np.sqrt((x * x + y * y).min()) if x.size else ke.NU_CLEAR - 1.0)
    return np.array(out)


def test_knife_edge_kernel_equals_its_plain_definition():
    # A 0.3 m sphere in two frames near 3 m long segments at 5.8 GHz (r1 up to 0.2 m: wide windows), to targets
    # on a plane behind it; which segments are blocked is given as a ray cast would find them (closer than the
    # radius to the centre). nu of blocked and clear segments as the plain evaluation, within rounding (1e-12).
    from rtchannel.backends.knife_edge import shadow_nu
    from rtchannel.backends.rcs import sphere_mesh

    lam = 299792458.0 / 5.8e9
    v, f = sphere_mesh(0.3, 3)
    centres = np.array([[1.5, 0.0, 1.0], [1.5, 0.1, 1.05]])
    verts = np.stack([v + c for c in centres])
    pos = np.array([0.0, 0.0, 1.0])
    rng = np.random.default_rng(7)
    targets = np.column_stack([np.full(400, 3.0), rng.uniform(-0.8, 0.8, 400), rng.uniform(0.2, 1.8, 400)])
    frame = rng.integers(0, 2, 400)
    u = (targets - pos) / np.linalg.norm(targets - pos, axis=1, keepdims=True)
    off = centres[frame] - pos
    miss = np.linalg.norm(off - (off * u).sum(axis=1, keepdims=True) * u, axis=1)
    hit = miss < 0.29
    assert 50 < hit.sum() < 350
    nu = shadow_nu(pos, targets, verts, frame, hit, lam, f)
    np.testing.assert_allclose(nu, _plain_nu(pos, targets, verts, frame, hit, lam, f), rtol=0, atol=1e-12)


def test_clutter_subdivision_equals_the_barycentric_loop():
    # n^2 congruent sub-triangles in the loop's order, each with 1/n^2 of the triangle's area
    from rtchannel.backends.clutter import _subdivide

    a, b, c = np.array([0.3, -1.0, 0.0]), np.array([2.1, 0.4, 0.0]), np.array([0.0, 1.7, 2.5])
    for n in (1, 2, 5, 13):
        pts = lambda i, j: a + (b - a) * (i / n) + (c - a) * (j / n)  # noqa: E731 - the loop it replaced
        want = []
        for i in range(n):
            for j in range(n - i):
                want.append((pts(i, j), pts(i + 1, j), pts(i, j + 1)))
                if i + j < n - 1:
                    want.append((pts(i + 1, j), pts(i + 1, j + 1), pts(i, j + 1)))
        got = _subdivide(a, b, c, n)
        np.testing.assert_array_equal(got, np.array(want))
        area = 0.5 * np.linalg.norm(np.cross(got[:, 1] - got[:, 0], got[:, 2] - got[:, 0]), axis=1)
        np.testing.assert_allclose(area, 0.5 * np.linalg.norm(np.cross(b - a, c - a)) / n ** 2, rtol=1e-12)


def _tiny_glasgow_items(backend: str = "points"):
    from rtchannel.dataset.plan import Plan, expand

    plan = Plan.model_validate({
        "name": "tiny", "seed": 5, "backend": backend, "chair": "auto",
        "motion": {"fps": 30, "sources": [{"procedural": "sit", "params": {"duration": 1.5, "pad_before": 0.0}}],
                   "clip_s": {"*": 5.0}},
        "physical": {"radar": "glasgow", "angles_deg": [0],
                     "link_sets": [{"name": "a", "links": [{"name": "radar1", "tx": [2.5, 0.0, 1.0]}]},
                                   {"name": "b", "links": [{"name": "radar1", "tx": [0.0, 2.0, 1.0]}]}]},
        "storage": {"image_layout": "glasgow"}})
    return expand(plan)


def test_dataset_items_without_range_doppler_store_the_same(monkeypatch):
    import rtchannel.dataset.items as items

    it = _tiny_glasgow_items()[0]
    fast = items.run_item(it)
    monkeypatch.setattr(items, "_without_range_doppler", lambda radar: radar)
    plain = items.run_item(it)
    assert plain["links"].keys() == fast["links"].keys()
    for link in fast["links"]:
        for name, a in fast["links"][link].items():
            np.testing.assert_array_equal(a, plain["links"][link][name])
    timing = ("seconds", "cpu_seconds", "stage_seconds")
    assert {k: v for k, v in fast["entry"].items() if k not in timing} == \
        {k: v for k, v in plain["entry"].items() if k not in timing}
    stages = fast["entry"]["stage_seconds"]
    assert set(stages) == {"setup", "backend", "synthesis", "dsp", "image"} and min(stages.values()) >= 0
    assert sum(stages.values()) <= fast["entry"]["seconds"] + 5e-4  # parts of the item's own time (4-decimal rounding)


def test_item_scene_is_made_once_per_motion():
    # the two placements of one sit-down share their room and fitted chair: one object, equal to a fresh fit
    from rtchannel.dataset.items import build_motion, item_scene
    from rtchannel.scene.spec import Scene

    a, b = _tiny_glasgow_items("facets")[:2]
    assert a.motion == b.motion and a.link_set != b.link_set
    motion = build_motion(a.motion)
    scene = item_scene(a, motion)
    assert item_scene(b, build_motion(b.motion)) is scene
    fresh = Scene.for_motion(motion, Scene(a.room) if a.room is not None else None, "auto")
    assert scene == fresh and scene.furniture and scene.furniture[0].name == "chair"
