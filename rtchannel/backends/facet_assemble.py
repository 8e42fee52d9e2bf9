"""Gains and dense assembly of the `facets` backend (see `rtchannel.backends.facets` for the model).

`link_gains` turns one BVH batch's visibility into sparse per-link, per-kind gains (traced frame slot,
facet, complex gain); `assemble` turns them into one persistent `PathSet` per link, optionally joining
parts traced on different meshes (direct paths on the chosen LOD, image paths on a coarser one), and
fills the [frames, paths] arrays in one compiled pass.
"""
from __future__ import annotations

import numba
import numpy as np

from processing.pathset import PathSet
from processing.radar.waveform import C0
from rtchannel.backends.surface_scattering import facet_gains_indexed, wall_factor
from rtchannel.backends.wall_images import mirror


def kind_walls(kind: int, n_walls: int) -> tuple[int, int]:
    """(wall of the tx image, wall of the rx image) of a path kind, -1 for none (see `facets` for the ids):
    0 direct; 1 + 2w tx image in wall w; 2 + 2w rx image; 1 + 2W + w both in wall w (double bounce);
    1 + 3W + W w1 + w2 (w1 != w2) tx image in w1 and rx image in w2 (cross double bounce)."""
    if kind == 0:
        return -1, -1
    if kind <= 2 * n_walls:
        w = (kind - 1) // 2
        return (w, -1) if kind % 2 else (-1, w)
    if kind <= 3 * n_walls:
        return kind - 1 - 2 * n_walls, kind - 1 - 2 * n_walls
    j = kind - 1 - 3 * n_walls
    return j // n_walls, j % n_walls


def double_kind(w_tx: int, w_rx: int, n_walls: int) -> int:
    """Path kind of the double bounce with the tx image in wall w_tx and the rx image in wall w_rx."""
    return 1 + 2 * n_walls + w_tx if w_tx == w_rx else 1 + 3 * n_walls + n_walls * w_tx + w_rx


def link_gains(vis, pairs, sources, walls, slot0, cent, norm, area, mesh, material, wavelength, po,
               phases=None, direct_paths: bool = True, image_paths: bool = True, double=(),
               antennas=None, polarizations=None) -> list[dict]:
    """Per link {kind: (slot [N], facet [N], gain [N] complex)} of one batch of traced frames.

    vis: `visibility.BatchVisibility` of the batch; slot0: slot of its first frame; cent, norm [B, F, 3],
    area [B, F]: facet geometry; mesh: (vertices [B, V, 3], faces [F, 3]) of the batch (corners, with `po`);
    phases: diffuse phase factors [F] of this mesh or None; double: (tx wall, rx wall) index pairs of the
    double-bounce paths to form; antennas: per link (tx pattern, rx pattern) or None for isotropic antennas (see
    `antenna_targets`; None for every link when not given); polarizations: per link "V" or "H" (default "V")."""
    n_w = len(walls)
    antennas = [None] * len(pairs) if antennas is None else antennas
    polarizations = ["V"] * len(pairs) if polarizations is None else polarizations
    out = []
    for (s_tx, s_rx), pattern, pol in zip(pairs, antennas, polarizations):
        tx, rx = sources[s_tx], sources[s_rx]
        mono = s_tx == s_rx
        # (kind, b, f, p_a, p_b, [(wall, (source, wall index), rows of vis.images[source, wall] or None for
        # all, antenna)], monostatic twin to add)
        fams: list[tuple] = []
        if direct_paths:
            b, f = np.nonzero(vis.direct[s_tx] & vis.direct[s_rx])
            fams.append((0, b, f, tx, rx, [], False))
        for w, wall in enumerate(walls if image_paths else ()):
            for kind, s_img, s_other, ant in ((1 + 2 * w, s_tx, s_rx, tx), (2 + 2 * w, s_rx, s_tx, rx)):
                if (kind % 2 == 0 and mono) or (s_img, w) not in vis.images:
                    continue
                b, f, _ = vis.images[(s_img, w)]
                keep = np.flatnonzero(vis.direct[s_other][b, f])
                img = mirror(sources[s_img], wall)
                p_a, p_b = (img, rx) if kind % 2 else (tx, img)
                fams.append((kind, b[keep], f[keep], p_a, p_b, [(wall, (s_img, w), keep, ant)], mono and kind % 2 == 1))
        for w1, w2 in (double if image_paths else ()):
            if (mono and w2 < w1) or (s_tx, w1) not in vis.images or (s_rx, w2) not in vis.images:
                continue  # monostatic: (w2, w1) is merged into (w1, w2)
            b, f, _ = vis.images[(s_tx, w1)]
            i1 = i2 = None
            if (s_rx, w2) != (s_tx, w1):  # facets seen through both images
                b2, f2, _ = vis.images[(s_rx, w2)]
                n_f = cent.shape[1]
                _, i1, i2 = np.intersect1d(b * n_f + f, b2 * n_f + f2, assume_unique=True, return_indices=True)
                b, f = b[i1], f[i1]
            fams.append((double_kind(w1, w2, n_w), b, f, mirror(tx, walls[w1]), mirror(rx, walls[w2]),
                         [(walls[w1], (s_tx, w1), i1, tx), (walls[w2], (s_rx, w2), i2, rx)], mono and w1 != w2))
        fams = [fam for fam in fams if fam[1].size]
        found = {}
        if fams:  # one gather and one compiled call for all kinds of the link
            sizes = [fam[1].size for fam in fams]
            b, f = np.concatenate([fam[1] for fam in fams]), np.concatenate([fam[2] for fam in fams])
            p_a = np.concatenate([np.broadcast_to(fam[3], (k, 3)) for fam, k in zip(fams, sizes)])
            p_b = np.concatenate([np.broadcast_to(fam[4], (k, 3)) for fam, k in zip(fams, sizes)])
            twin = np.repeat([fam[6] for fam in fams], sizes)
            c = cent[b, f]
            ph = None if phases is None else phases[f]  # the facet's own surface phase on every path
            g, g_rev, t = _gains_and_twins(material, wavelength, cent, norm, area, mesh, b, f, p_a, p_b, po, ph, twin,
                                           pol)
            if pattern is not None:  # isotropic links skip this: their gains stay bit-identical
                at_tx, at_rx = antenna_targets([(fam[0], k) for fam, k in zip(fams, sizes)], c, walls)
                same = pattern[0] == pattern[1]  # monostatic: the same antenna at the same place
                amp_tx = antenna_gain(pattern[0], tx, at_tx)
                if mono and same:  # evaluate the receiver only where it looks elsewhere (image kinds)
                    amp_rx = amp_tx.copy()
                    d = np.flatnonzero(np.any(at_rx != at_tx, axis=1))
                    amp_rx[d] = antenna_gain(pattern[1], rx, at_rx[d])
                else:
                    amp_rx = antenna_gain(pattern[1], rx, at_rx)
                g *= amp_tx * amp_rx
                if t.size:  # reversed, the transmitter sees the receiver's target and vice versa
                    g_rev *= (amp_tx[t] * amp_rx[t] if same else
                              antenna_gain(pattern[0], tx, at_rx[t]) * antenna_gain(pattern[1], rx, at_tx[t]))
            if t.size:  # monostatic: add the reverse path (same delay and visibility)
                g[t] += g_rev
            factors = _WallFactors(vis, cent, wavelength, fams, pol)
            at = 0
            for (kind, bk, fk, _, _, via, _), k in zip(fams, sizes):
                gk = g[at:at + k]
                for wall, key, rows, ant in via:
                    gk = gk * factors(wall, key, rows, ant, c[at:at + k])
                found[kind] = (bk + slot0, fk, gk)
                at += k
        out.append(found)
    return out


def _gains_and_twins(material, wavelength, cent, norm, area, mesh, b, f, p_a, p_b, po, ph, twin, pol="V"):
    """(gains [N], reverse gains of the twins [T], twin rows [T]): `facet_gains_indexed` on p_a -> p_b, and
    on p_b -> p_a where `twin`; the Lambertian kernel evaluates both directions in one pass (same values)."""
    t = np.flatnonzero(twin)
    verts, faces = mesh
    if material.pattern != "lambertian" or not t.size:
        g = facet_gains_indexed(material, wavelength, cent, norm, area, verts, faces, b, f, p_a, p_b, po, ph, pol)
        g_rev = None if not t.size else facet_gains_indexed(material, wavelength, cent, norm, area, verts, faces, b[t],
                                                             f[t], p_b[t], p_a[t], po, None if ph is None else ph[t],
                                                             pol)
        return g, g_rev, t
    from rtchannel.backends.facet_kernels import indexed_gains
    from rtchannel.backends.surface_scattering import pol_index

    s_coef, rough = material.kernel_surface()
    d, s, d_rev, s_rev = indexed_gains(cent, norm, area, verts, faces, b, f, p_a, p_b, material.eta,
                                       material.thickness or 0.0, wavelength, s_coef, material.xpd_coefficient, po,
                                       twin, pol=pol_index(pol), rough=rough)
    g, g_rev = (d * ph, d_rev[t] * ph[t]) if ph is not None else (d.astype(complex), d_rev[t].astype(complex))
    return (g + s, g_rev + s_rev[t], t) if po else (g, g_rev, t)


class _WallFactors:
    """Wall reflection factors (`wall_factor`) of one link's paths, evaluated once per image (source, wall)
    where a double bounce uses all its facets and gathered for the single bounce's subset (the factor of a
    path depends on its own facet and image only), and once for both ends of a monostatic same-wall
    double bounce (the same reflection point twice)."""

    def __init__(self, vis, cent, wavelength, fams, pol="V"):
        self.vis, self.cent, self.wavelength, self.pol = vis, cent, wavelength, pol
        self.full = {key for fam in fams for _, key, rows, _ in fam[5] if rows is None}
        self.cache = {}

    def __call__(self, wall, key, rows, ant, c):
        if key in self.full:
            if key not in self.cache:
                b, f, cos_w = self.vis.images[key]
                self.cache[key] = self._factor(wall, cos_w, self.cent[b, f], ant)
            return self.cache[key] if rows is None else self.cache[key][rows]
        cos_w = self.vis.images[key][2]
        return self._factor(wall, cos_w if rows is None else cos_w[rows], c, ant)

    def _factor(self, wall, cos_w, c, ant):
        q_dir = mirror(c, wall) - ant  # antenna -> mirrored centroid: via the reflection point
        q_dir /= np.linalg.norm(q_dir, axis=1, keepdims=True)
        return wall_factor(wall, cos_w, q_dir, self.wavelength, self.pol)


def antenna_targets(kinds_sizes, cent, walls) -> tuple[np.ndarray, np.ndarray]:
    """Points [N, 3] (m) towards which each path leaves the transmitter and from which it reaches the
    receiver, for paths grouped in runs of (kind, count) over centroids `cent` [N, 3]: the centroid itself,
    or for an antenna mirrored in wall w the centroid's mirror image in w. (The reflection point lies on
    the segment antenna -> mirrored centroid, so the antenna sees the path in that direction; see
    `processing.radar.antenna`.)"""
    at_tx, at_rx = cent, cent  # shared until an image kind needs its own copy
    at = 0
    for kind, k in kinds_sizes:
        w_tx, w_rx = kind_walls(int(kind), len(walls))
        if w_tx >= 0:
            at_tx = at_tx.copy() if at_tx is cent else at_tx
            at_tx[at:at + k] = mirror(cent[at:at + k], walls[w_tx])
        if w_rx >= 0:
            at_rx = at_rx.copy() if at_rx is cent else at_rx
            at_rx[at:at + k] = mirror(cent[at:at + k], walls[w_rx])
        at += k
    return at_tx, at_rx


def antenna_gain(spec, position, targets) -> np.ndarray:
    """Amplitude factor sqrt(G) [N] of `spec` at `position` [3] towards `targets` [N, 3] (m); 1 for None."""
    from rtchannel.backends.facet_kernels import antenna_amplitudes

    return np.ones(len(targets)) if spec is None else antenna_amplitudes(spec, position, targets)


def merge_batches(batches: list[list[dict]], n_links: int) -> list[dict]:
    """Concatenate per-batch `link_gains` results into per link {kind: (slot, facet, gain)}."""
    out = []
    for li in range(n_links):
        kinds = sorted({k for b in batches for k in b[li]})
        out.append({k: tuple(np.concatenate([b[li][k][i] for b in batches if k in b[li]]) for i in range(3))
                    for k in kinds})
    return out


def assemble(parts, name, tx, rx, walls, times, trace_idx, id_faces, min_db, extra: PathSet | None = None) -> PathSet:
    """Dense persistent PathSet of one link.

    parts: list of (found {kind: (slot, facet, gain)}, vertices [K, V, 3], velocities [K, V, 3] or None,
    faces [T, 3]); path ids are facet + id_faces * kind (facets of every part index below id_faces).
    extra: a path set of the same link at `times` (the clutter) whose paths follow the facets' columns,
    untouched by `min_db`: the result equals `clutter.merged(facets, extra)` without copying the facets'
    arrays a second time."""
    k, n_slots = len(times), len(trace_idx)
    cols = []  # (part index, kind, facet ids [P], g_trace [slots, P])
    for pi, (found, _, _, faces) in enumerate(parts):
        for kind, (slot, f, g) in sorted(found.items()):
            present = np.zeros(len(faces), bool)
            present[f] = True
            ids = np.flatnonzero(present)
            col = np.cumsum(present) - 1
            gt = np.zeros((n_slots, ids.size), complex)
            gt[slot, col[f]] = g
            cols.append((pi, kind, ids, gt))
    if cols:
        peaks = [np.abs(gt).max(axis=0) for *_, gt in cols]
        top = max(float(p.max()) for p in peaks)
        floor = top * 10 ** (min_db / 20) if min_db is not None else 0.0
        keeps = [(p > 0) & (p >= floor) for p in peaks]
        cols = [(pi, kind, ids[m], gt[:, m]) for (pi, kind, ids, gt), m in zip(cols, keeps) if m.any()]
    if extra is not None and (extra.delays.shape[0] != k or not np.array_equal(extra.times, times)):
        raise ValueError("the extra path set must share the link's frame times")
    if not cols:  # nothing ever visible: one absent path keeps the output well-defined
        absent = PathSet(times=times, delays=np.full((k, 1), np.nan), gains=np.zeros((k, 1), complex),
                         ids=np.array([0]), delay_rates=np.zeros((k, 1)), link=name)
        if extra is None:
            return absent
        from rtchannel.backends.clutter import merged

        return merged(absent, extra)
    has_vel = all(p[2] is not None for p in parts)
    n_p = sum(c[2].size for c in cols)
    n_x = 0 if extra is None else extra.delays.shape[1]
    gains = np.empty((k, n_p + n_x), complex)
    delays = np.empty((k, n_p + n_x))
    rates = np.empty((k, n_p + n_x))
    t_tr = times[trace_idx]
    slot = np.clip(np.searchsorted(t_tr, times, side="right") - 1, 0, max(len(t_tr) - 2, 0))
    nxt = np.minimum(slot + 1, len(t_tr) - 1)
    span = np.where(nxt > slot, t_tr[nxt] - t_tr[slot], 1.0)
    wgt = np.where(nxt > slot, (times - t_tr[slot]) / span, 0.0)
    all_ids: list[np.ndarray] = []
    for pi, (_, verts, vels, faces) in enumerate(parts):
        mine = [c for c in cols if c[0] == pi]
        if not mine:
            continue
        fidx = np.concatenate([c[2] for c in mine])
        kinds = np.concatenate([np.full(c[2].size, c[1]) for c in mine])
        g_trace = np.ascontiguousarray(np.concatenate([c[3] for c in mine], axis=1))
        pa = np.broadcast_to(tx, (fidx.size, 3)).copy()  # path end points: antenna or its wall image
        pb = np.broadcast_to(rx, (fidx.size, 3)).copy()
        for kind in np.unique(kinds[kinds > 0]):
            w_tx, w_rx = kind_walls(int(kind), len(walls))
            if w_tx >= 0:
                pa[kinds == kind] = mirror(tx, walls[w_tx])
            if w_rx >= 0:
                pb[kinds == kind] = mirror(rx, walls[w_rx])
        c0 = sum(i.size for i in all_ids)
        sl = slice(c0, c0 + fidx.size)
        vel = np.asarray(vels, float) if has_vel else np.zeros((1, 1, 3))
        # written in place: each part's columns of the link's arrays (no per-part copy)
        _fill_paths(verts, vel, np.asarray(faces, np.int64), fidx, pa, pb, g_trace, slot, nxt, wgt, has_vel,
                    gains[:, sl], delays[:, sl], rates[:, sl])
        all_ids.append(fidx + id_faces * kinds)
    if extra is not None:  # its columns after the facets' (where `merged` puts them); rates 0 where it has none
        gains[:, n_p:], delays[:, n_p:] = extra.gains, extra.delays
        rates[:, n_p:] = 0.0 if extra.delay_rates is None else extra.delay_rates
        assert extra.ids is not None  # the clutter's paths carry cell ids
        all_ids.append(extra.ids)
    with_rates = has_vel or (extra is not None and extra.delay_rates is not None)  # `_fill_paths` wrote 0 without
    return PathSet(times=times, delays=delays, gains=gains, ids=np.concatenate(all_ids),
                   delay_rates=rates if with_rates else None, link=name)


@numba.njit(parallel=True, cache=True, nogil=True)
def _fill_paths(verts, vels, faces, fidx, pa, pb, g_trace, slot, nxt, w, has_vel, gains, delays, rates):
    """Per frame k and path p: gain interpolated between traced frames; centroid delay and its rate
    (NaN / 0 where the gain is 0). Fused so the [K, P] arrays are written once."""
    n_k, n_p = gains.shape
    same = np.empty(n_p, np.bool_)  # monostatic path (both ends at one point): one leg's numbers serve twice
    for p in range(n_p):
        same[p] = pa[p, 0] == pb[p, 0] and pa[p, 1] == pb[p, 1] and pa[p, 2] == pb[p, 2]
    for k in numba.prange(n_k):
        j0, j1, wk = slot[k], nxt[k], w[k]
        for p in range(n_p):
            g = (1.0 - wk) * g_trace[j0, p] + wk * g_trace[j1, p]
            gains[k, p] = g
            if g == 0:
                delays[k, p] = np.nan
                rates[k, p] = 0.0
                continue
            f = fidx[p]
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            ra2 = 0.0
            rb2 = 0.0
            dot_a = 0.0
            dot_b = 0.0
            for i in range(3):
                ci = (verts[k, a, i] + verts[k, b, i] + verts[k, c, i]) / 3.0
                da = ci - pa[p, i]
                ra2 += da * da
                if not same[p]:
                    db = ci - pb[p, i]
                    rb2 += db * db
                if has_vel:
                    vi = (vels[k, a, i] + vels[k, b, i] + vels[k, c, i]) / 3.0
                    dot_a += vi * da
                    if not same[p]:
                        dot_b += vi * db
            ra = np.sqrt(ra2)
            if same[p]:  # the same operations on the same numbers: bit for bit the two-leg result
                delays[k, p] = (ra + ra) / C0
                if has_vel:
                    x = dot_a / ra
                    rates[k, p] = (x + x) / C0
                else:
                    rates[k, p] = 0.0
                continue
            rb = np.sqrt(rb2)
            delays[k, p] = (ra + rb) / C0
            rates[k, p] = (dot_a / ra + dot_b / rb) / C0 if has_vel else 0.0
