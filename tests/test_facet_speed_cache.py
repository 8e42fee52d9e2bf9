"""The clutter's static work is reused exactly (issue 26): its patch gains, delays and cells per scene and radar,
the static shadows per ray-caster cell and antenna, and body rays only where a ray passes the body's box (widened
by the knife-edge's reach, issue 37) give the path sets of the brute-force formulation (every ray cast against
walls and body at every traced frame, every statically free segment's knife-edge factor evaluated); the caches
follow a moved antenna, another seed or another radar, and the Mitsuba route agrees."""
import numpy as np
import pytest
from scipy import sparse

from processing.fast_time import max_range
from processing.radar.propagation import bistatic_delay
from processing.radar.waveform import C0
from rtchannel import Motion
from rtchannel.backends import clutter, embree, visibility
from rtchannel.body.avatar import load_avatar
from rtchannel.body.skinning import skin_vertices
from rtchannel.radar import Link, RadarConfig
from rtchannel.scene.rt_scene import get_scene


def _reference(rt, radar, times, verts=None, faces=None, trace_idx=None, seed=0, batch=16):
    """clutter_paths as first written: every antenna -> patch ray cast with the body at each traced frame, and
    every segment free of static geometry given the body's knife-edge factor."""
    from rtchannel.backends.knife_edge import segment_amplitudes

    wf = radar.waveform
    patches = clutter.scene_patches(rt, wf.carrier_hz, clutter.patch_size_m(wf.range_resolution))
    f_n, k_n = len(times), len(patches.areas)
    trace_idx = np.arange(f_n) if trace_idx is None else np.asarray(trace_idx)
    antennas = np.unique(np.concatenate([[lk.tx_pos for lk in radar.links], [lk.rx_pos for lk in radar.links]]),
                         axis=0)
    v = np.broadcast_to(patches.centroids[0], (1, 3, 3)).copy() if verts is None else verts
    fc = np.array([[0, 1, 2]]) if faces is None else faces
    caster = visibility.caster_for(rt, fc, v, antennas, batch)
    free = np.ones((len(antennas), len(v), k_n))
    for s0 in range(0, len(v), batch):
        chunk = v[s0:s0 + batch]
        cells = np.repeat(np.arange(len(chunk)), k_n)
        for a, pos in enumerate(antennas):
            d = patches.centroids - pos
            dist = np.linalg.norm(d, axis=1)
            rays = (np.broadcast_to(pos, (len(cells), 3)), np.tile(d / dist[:, None], (len(chunk), 1)),
                    np.tile(dist - visibility._STOP, len(chunk)), cells)
            caster.clear()
            static = ~caster.occluded_cells(*rays).reshape(len(chunk), k_n)
            caster.load(chunk)
            hit = caster.occluded_cells(*rays).reshape(len(chunk), k_n)
            if verts is None:
                free[a, s0:s0 + len(chunk)] = ~hit
                continue
            b, k = np.nonzero(static)
            amp = np.zeros((len(chunk), k_n))
            amp[b, k] = segment_amplitudes(pos, patches.centroids[k], chunk, b, hit[b, k], radar.waveform.wavelength,
                                           fc)
            free[a, s0:s0 + len(chunk)] = amp
    if verts is None:
        free = np.broadcast_to(free[:, :1], (len(antennas), len(trace_idx), k_n))
    index = {tuple(p): i for i, p in enumerate(antennas)}
    lo = max(radar.dsp.min_range_m - 2 * wf.range_resolution, 0.0)
    hi = max_range(wf, radar.dsp) + 2 * wf.range_resolution
    out = {}
    for lk in radar.links:
        vis = free[index[tuple(lk.tx_pos)]] * free[index[tuple(lk.rx_pos)]]
        if len(trace_idx) != f_n:
            j = np.clip(np.searchsorted(trace_idx, np.arange(f_n), side="right") - 1, 0, max(len(trace_idx) - 2, 0))
            j1 = np.minimum(j + 1, len(trace_idx) - 1)
            span = np.where(j1 > j, trace_idx[j1] - trace_idx[j], 1)
            w = np.clip((np.arange(f_n) - trace_idx[j]) / span, 0.0, 1.0)[:, None]
            vis = (1 - w) * vis[j] + w * vis[j1]
        g = clutter.clutter_gains(patches, lk.tx_pos, lk.rx_pos, wf.wavelength, wf.carrier_hz, seed)
        g = g * radar.link_gain(lk, patches.centroids)
        tau_all = bistatic_delay(patches.centroids, lk.tx_pos, lk.rx_pos)
        keep = np.flatnonzero((g != 0) & (np.abs(tau_all * C0 / 2 - 0.5 * (lo + hi)) <= 0.5 * (hi - lo)))
        step = 1.0 / (clutter.CELLS_PER_RANGE_BIN * wf.bandwidth_hz)
        cells, inverse = np.unique(np.round(tau_all[keep] / step).astype(np.int64), return_inverse=True)
        w_k = g[keep] * np.exp(2j * np.pi * wf.carrier_hz * (tau_all[keep] - cells[inverse] * step))
        to_cells = sparse.csr_matrix((w_k, (np.arange(keep.size), inverse)), shape=(keep.size, len(cells)))
        out[lk.name] = (cells, cells * step, np.asarray((to_cells.T @ vis[:, keep].T).T))
    return out


def _same(got, ref):
    for name, (cells, tau, gains) in ref.items():
        ps = got[name]
        assert np.array_equal(ps.ids, clutter.CLUTTER_ID_BASE + cells)
        assert np.array_equal(ps.delays[0], tau) and (ps.delays == ps.delays[0]).all()
        assert np.array_equal(ps.gains, gains)  # the same sums in the same order


RADAR = RadarConfig(links=[Link(name="a", tx=(3.0, 0.0, 1.1)),
                           Link(name="b", tx=(0.0, -3.0, 1.1), rx=(0.3, -2.9, 1.2))])


@pytest.fixture(scope="module")
def scene_and_body():
    rt = get_scene("room", "2k", 1.75, RADAR.waveform.carrier_hz, sionna=False)
    m = Motion.procedural("walk", seed=2, duration=1.5)
    av = load_avatar("2k")
    return rt, m, av


@pytest.mark.parametrize("every, batch", [(1, 16), (6, 4), (13, 16)])
def test_clutter_equals_the_brute_force_casts(scene_and_body, every, batch):
    rt, m, av = scene_and_body
    idx = np.unique(np.concatenate([np.arange(0, m.n_frames, every), [m.n_frames - 1]]))
    verts = skin_vertices(av, m, idx)
    got = clutter.clutter_paths(rt, RADAR, m.times, verts, av.faces, idx, 3, batch)
    shadowed = _reference(rt, RADAR, m.times, verts, av.faces, idx, 3, batch)
    _same(got, shadowed)
    # the body really shadows part of the room here, and some rays near it stay free
    empty = _reference(rt, RADAR, m.times)
    assert any(not np.array_equal(shadowed[k][2], empty[k][2]) for k in empty)
    _same(clutter.clutter_paths(rt, RADAR, m.times), empty)


def test_caches_follow_antennas_radar_and_seed(scene_and_body):
    rt, m, av = scene_and_body
    idx = np.arange(0, m.n_frames, 6)
    verts = skin_vertices(av, m, idx)
    moved = RadarConfig(links=[Link(name="a", tx=(2.5, 0.8, 1.0))])
    wide = RADAR.model_copy(update={"links": [RADAR.links[0]],
                                    "dsp": RADAR.dsp.model_copy(update={"min_range_m": 2.5})})
    for radar, seed in ((RADAR, 0), (moved, 0), (RADAR, 1), (wide, 0), (RADAR, 0)):
        got = clutter.clutter_paths(rt, radar, m.times, verts, av.faces, idx, seed)
        _same(got, _reference(rt, radar, m.times, verts, av.faces, idx, seed))
    caster = visibility.caster_for(rt, av.faces, verts, np.array([[3.0, 0.0, 1.1]]), 16, purpose="clutter")
    assert len(caster.clutter_static) >= 3  # one entry per antenna position seen


def test_static_shadows_through_mitsuba_equal_embree(scene_and_body, monkeypatch):
    rt, m, av = scene_and_body
    idx = np.arange(0, m.n_frames, 10)
    verts = skin_vertices(av, m, idx)
    fast = clutter.clutter_paths(rt, RADAR, m.times, verts, av.faces, idx)
    visibility._CASTERS.pop(rt, None)
    monkeypatch.setattr(embree, "available", lambda: False)
    slow = clutter.clutter_paths(rt, RADAR, m.times, verts, av.faces, idx)  # `clear` collapses the body
    visibility._CASTERS.pop(rt, None)
    for k in fast:
        assert np.array_equal(fast[k].gains, slow[k].gains)
