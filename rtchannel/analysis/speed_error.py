"""Speed against error: time every backend setting on one activity and measure its signature error
against a reference setting (Sionna RT at a high ray count and trace rate, by default).

For each setting: wall time per simulated second (median over repeats, whole chain: backend, synthesis,
DSP, all links) and, against the reference, the mean earth-mover (Wasserstein-1, m/s) and total-variation
distances of p(v,t) per time bin, the mean-velocity RMSE [m/s] and the normalised DTW
(`processing.metrics`), averaged over links. The Pareto front is drawn on the earth-mover distance:
TV saturates when Monte-Carlo floors or one-bin shifts differ, EMD measures how far the energy moved.
Writes a CSV, a Markdown table and a PNG of error against time with the Pareto front.
"""
from __future__ import annotations

import csv
import io
import json
import statistics
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from processing.atomic import savefig_atomic, write_text_atomic
from processing.metrics import signature_distances
from rtchannel.radar import RadarConfig


@dataclass
class Setting:
    """One point of the sweep: a backend, its options and a short label."""

    label: str
    backend: str
    options: dict = field(default_factory=dict)


REFERENCE = Setting("sionna 1e6 rays, every frame", "sionna", {"samples_per_src": 1_000_000})

FULL = {"trace_fps": None, "image_lod": None, "min_relative_gain_db": None}  # facets without speed knobs

# The sweep varies one knob at a time around the facets defaults (10k LOD, walls, visibility and gains
# traced at 10 fps, wall-image paths on the 2k mesh, paths below -40 dB dropped) and its full accuracy.
SWEEP: tuple[Setting, ...] = (
    Setting("points (21 scatterers)", "points"),
    Setting("facets defaults (10k)", "facets", {"lod": "10k"}),
    Setting("facets 10k, full accuracy", "facets", {"lod": "10k", **FULL}),
    Setting("facets 10k, full accuracy, PO term", "facets", {"lod": "10k", **FULL, "po": True}),
    Setting("facets 10k, no walls", "facets", {"lod": "10k", "walls": False}),
    Setting("facets full LOD", "facets", {"lod": "full"}),
    Setting("facets 5k", "facets", {"lod": "5k"}),
    Setting("facets 2k", "facets", {"lod": "2k"}),
    Setting("facets 10k, trace 30 fps", "facets", {"lod": "10k", "trace_fps": 30.0}),
    Setting("facets 10k, trace 5 fps", "facets", {"lod": "10k", "trace_fps": 5.0}),
    Setting("facets 10k, images on 10k", "facets", {"lod": "10k", "image_lod": None}),
    Setting("facets 10k, all paths (no -40 dB cut)", "facets", {"lod": "10k", "min_relative_gain_db": None}),
    Setting("sionna 1e5 rays", "sionna", {"samples_per_src": 100_000}),
    Setting("sionna 1e4 rays", "sionna", {"samples_per_src": 10_000}),
    Setting("sionna 1e6 rays, trace 30 fps", "sionna", {"samples_per_src": 1_000_000, "trace_fps": 30.0}),
    Setting("sionna 1e5 rays, depth 2", "sionna", {"samples_per_src": 100_000, "max_depth": 2}),
)

QUICK: tuple[Setting, ...] = tuple(s for s in SWEEP if s.backend != "sionna" and "full" not in s.label)


def _run(setting: Setting, motion, radar: RadarConfig, repeats: int) -> tuple[float, dict]:
    """(median wall time [s] of the whole chain, signatures {link: Signature}) of one setting."""
    from rtchannel.pipeline import simulate

    times, res = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = simulate(motion, radar, backend=setting.backend, **setting.options)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), {k: r.signature for k, r in res.links.items()}


def sweep(motion, radar: RadarConfig, settings=SWEEP, reference: Setting = REFERENCE, repeats: int = 3,
          progress=None) -> list[dict]:
    """Time each setting and measure its error against `reference` (run once, after a warm-up of each
    backend so that scene loading and kernel compilation are not timed). Returns one row per setting."""
    from dataclasses import replace

    from rtchannel.pipeline import simulate

    warmed: set[str] = set()
    n = max(int(0.3 * motion.fps), 4)
    short = replace(motion, positions=motion.positions[:n], rotations=motion.rotations[:n])

    def warm(backend: str, options: dict) -> None:
        key = f"{backend}:{options.get('lod')}"
        if key not in warmed:  # scene loading, LOD loading and kernel compilation are not timed
            simulate(short, radar, backend=backend, **options)
            warmed.add(key)

    warm(reference.backend, reference.options)
    ref_time, ref = _run(reference, motion, radar, 1)
    rows = [{"label": reference.label + " (reference)", "backend": reference.backend,
             "options": reference.options, "s_per_sim_s": ref_time / motion.duration,
             "tv": 0.0, "emd_m_s": 0.0, "rmse_m_s": 0.0, "dtw": 0.0}]
    if progress:
        progress(1)
    for s in settings:
        warm(s.backend, s.options)
        wall, sig = _run(s, motion, radar, repeats if s.backend != "sionna" else 1)
        d = [signature_distances(sig[k], ref[k]) for k in ref]
        rows.append({"label": s.label, "backend": s.backend, "options": s.options,
                     "s_per_sim_s": wall / motion.duration,
                     "tv": float(np.mean([x["tv"] for x in d])),
                     "emd_m_s": float(np.mean([x["emd"] for x in d])),
                     "rmse_m_s": float(np.mean([x["rmse"] for x in d])),
                     "dtw": float(np.mean([x["dtw"] for x in d]))})
        if progress:
            progress(1)
    return rows


def pareto_front(cost: np.ndarray, error: np.ndarray) -> np.ndarray:
    """Indices of the points no other point beats in both cost and error, sorted by cost."""
    order = np.lexsort((error, cost))
    front, best = [], np.inf
    for i in order:
        if error[i] < best:
            front.append(i)
            best = error[i]
    return np.array(front, dtype=int)


def write_outputs(rows: list[dict], out_dir: Path, meta: dict) -> list[Path]:
    """speed_error.csv, speed_error.md (README table), speed_error.png (Pareto front), speed_error.json."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    keys = ["label", "backend", "options", "s_per_sim_s", "tv", "emd_m_s", "rmse_m_s", "dtw"]
    p_csv = out_dir / "speed_error.csv"
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(keys)
    for r in rows:
        w.writerow([json.dumps(r[k]) if k == "options" else
                    (f"{r[k]:.4g}" if isinstance(r[k], float) else r[k]) for k in keys])
    write_text_atomic(p_csv, buf.getvalue())
    md = ["| setting | s per simulated s | p(v,t) EMD [m/s] | p(v,t) TV | mean-v RMSE [m/s] | DTW |",
          "|---|---|---|---|---|---|"]
    md += [f"| {r['label']} | {r['s_per_sim_s']:.3g} | {r['emd_m_s']:.3f} | {r['tv']:.3f} | {r['rmse_m_s']:.3f} "
           f"| {r['dtw']:.3f} |" for r in rows]
    p_md = out_dir / "speed_error.md"
    write_text_atomic(p_md, "\n".join(md) + "\n")
    cost = np.array([r["s_per_sim_s"] for r in rows])
    err = np.array([r["emd_m_s"] for r in rows])
    front = pareto_front(cost, err)
    fig, ax = plt.subplots(figsize=(8, 5))
    colours = {"points": "tab:green", "facets": "tab:blue", "sionna": "tab:red"}
    for r, c, e in zip(rows, cost, err):
        ax.scatter(c, e, color=colours.get(r["backend"], "k"), zorder=3)
        ax.annotate(r["label"], (c, e), fontsize=7, xytext=(4, 3), textcoords="offset points")
    ax.plot(cost[front], err[front], "k--", lw=1, label="Pareto front")
    ax.axvline(1.0, color="grey", lw=0.8, ls=":", label="real time")
    ax.set_xscale("log")
    ax.set_xlabel("wall time per simulated second [s] (2 cores)")
    ax.set_ylabel("mean p(v,t) earth-mover distance to reference [m/s]")
    ax.set_title(f"speed against error: {meta.get('activity', '')}, reference {rows[0]['label']}", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    p_png = out_dir / "speed_error.png"
    savefig_atomic(fig, p_png, dpi=120)
    plt.close(fig)
    p_json = out_dir / "speed_error.json"
    write_text_atomic(p_json, json.dumps({"meta": meta, "rows": rows, "pareto": [rows[i]["label"] for i in front]},
                                         indent=1) + "\n")
    return [p_csv, p_md, p_png, p_json]
