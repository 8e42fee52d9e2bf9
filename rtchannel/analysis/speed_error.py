"""Speed against error: time every backend setting on one activity and measure its signature error
against a converged reference.

For each setting: wall time per simulated second (median over repeats, whole chain: backend, synthesis,
DSP, all links) and, against the reference, the mean earth-mover (Wasserstein-1, m/s) and total-variation
distances of p(v,t) per time bin, the mean-velocity RMSE [m/s] and the normalised DTW
(`processing.metrics.distances`), averaged over links. The Pareto front is drawn on the earth-mover distance:
TV saturates when Monte-Carlo floors or one-bin shifts differ, EMD measures how far the energy moved.
Writes a CSV, a Markdown table and a PNG of error against time with the Pareto front.

The reference is an ensemble mean. One run of Sionna RT samples rays randomly and one run of the facets
model draws one diffuse-phase pattern (the rough skin's speckle); either way a single run sits a fixed
Monte-Carlo distance from the expected signature (0.18 m/s EMD between two Sionna runs at 1e6 rays), and
against such a reference every setting looks equally wrong. The reference setting is therefore run with
`reference_seeds` seeds (option `seed`: Sionna's ray-sampling seed, facets' diffuse-phase seed) and the
column-normalised p(v,t) and the mean-velocity curves are averaged. Its own error is estimated by
splitting the runs into two halves: the distance between the half means is about twice the distance of
the full mean from the expectation (the half means' errors are independent, each sqrt(2) times the
full mean's). The sweep reports it and the ratio of the settings' error spread (worst - best) to it,
which must be >= 3 for the ranking to mean something (`converged`).
"""
from __future__ import annotations

import csv
import io
import json
import statistics
import time
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from processing.atomic import savefig_atomic, write_text_atomic
from processing.errors import InputError
from processing.metrics.distances import signature_distances
from rtchannel.radar import RadarConfig


@dataclass
class Setting:
    """One point of the sweep: a backend, its options, a short label and the knob it turns."""

    label: str
    backend: str
    options: dict = field(default_factory=dict)
    knob: str = "backend"


REFERENCE = Setting("sionna 1e6 rays, every frame", "sionna", {"samples_per_src": 1_000_000}, "reference")
REFERENCE_SEEDS = 8  # runs averaged into the reference; see the module docstring

FULL = {"trace_fps": None, "image_lod": None, "min_relative_gain_db": None}  # facets without speed knobs
QUICK_REFERENCE = Setting("facets full LOD, full accuracy", "facets", {"lod": "full", **FULL}, "reference")

# The sweep varies one knob at a time around the facets defaults (10k LOD, PO on, floor double bounce,
# walls, visibility and gains traced at 10 fps, wall-image paths on the 2k mesh, paths below -50 dB
# dropped) and its full accuracy.
SWEEP: tuple[Setting, ...] = (
    Setting("points (21 scatterers)", "points"),
    Setting("facets defaults (10k)", "facets", {"lod": "10k"}),
    Setting("facets 10k, full accuracy", "facets", {"lod": "10k", **FULL}, "accuracy"),
    Setting("facets 10k, no PO term", "facets", {"lod": "10k", "po": False}, "physics"),
    Setting("facets 10k, double bounce via every wall", "facets", {"lod": "10k", "double_bounce": True}, "physics"),
    Setting("facets 10k, no walls", "facets", {"lod": "10k", "walls": False}, "physics"),
    Setting("facets full LOD", "facets", {"lod": "full"}, "LOD"),
    Setting("facets 5k", "facets", {"lod": "5k"}, "LOD"),
    Setting("facets 2k", "facets", {"lod": "2k"}, "LOD"),
    Setting("facets 10k, trace 30 fps", "facets", {"lod": "10k", "trace_fps": 30.0}, "trace rate"),
    Setting("facets 10k, trace 5 fps", "facets", {"lod": "10k", "trace_fps": 5.0}, "trace rate"),
    Setting("facets 10k, trace 2.5 fps", "facets", {"lod": "10k", "trace_fps": 2.5}, "trace rate"),
    Setting("facets 10k, images on 10k", "facets", {"lod": "10k", "image_lod": None}, "image LOD"),
    Setting("facets 10k, all paths (no -50 dB cut)", "facets", {"lod": "10k", "min_relative_gain_db": None},
            "gain cut"),
    Setting("facets 10k, -30 dB cut", "facets", {"lod": "10k", "min_relative_gain_db": -30.0}, "gain cut"),
    Setting("sionna 1e5 rays", "sionna", {"samples_per_src": 100_000}, "rays"),
    Setting("sionna 1e4 rays", "sionna", {"samples_per_src": 10_000}, "rays"),
    Setting("sionna 1e6 rays, one seed", "sionna", {"samples_per_src": 1_000_000}, "rays"),
    Setting("sionna 1e6 rays, trace 30 fps", "sionna", {"samples_per_src": 1_000_000, "trace_fps": 30.0},
            "trace rate"),
    Setting("sionna 1e5 rays, depth 2", "sionna", {"samples_per_src": 100_000, "max_depth": 2}, "physics"),
)

QUICK: tuple[Setting, ...] = tuple(s for s in SWEEP if s.backend != "sionna" and s.options.get("lod") != "full")


def _run(setting: Setting, motion, radar: RadarConfig, repeats: int, **extra) -> tuple[float, dict]:
    """(median wall time [s] of the whole chain, signatures {link: Signature}) of one setting."""
    from rtchannel.pipeline import simulate

    times, res = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = simulate(motion, radar, backend=setting.backend, **{**setting.options, **extra})
        times.append(time.perf_counter() - t0)
    assert res is not None  # repeats >= 1 (sweep checks it)
    return statistics.median(times), {k: r.signature for k, r in res.links.items()}


def _column_normalised(p_vt: np.ndarray) -> np.ndarray:
    total = p_vt.sum(axis=0)
    return np.where(total > 0, p_vt / np.where(total > 0, total, 1.0), 0.0)


def ensemble_mean(runs: list[dict]) -> dict:
    """Per link, the mean of several runs' signatures: column-normalised p(v,t) and mean velocity averaged
    over runs (objects with `p_vt`, `velocity`, `mean_velocity`, as `signature_distances` takes)."""
    out = {}
    for k in runs[0]:
        n_t = min(r[k].p_vt.shape[1] for r in runs)
        p = np.mean([_column_normalised(np.asarray(r[k].p_vt, float)[:, :n_t]) for r in runs], axis=0)
        v = np.mean([np.asarray(r[k].mean_velocity, float)[:n_t] for r in runs], axis=0)
        out[k] = SimpleNamespace(p_vt=p, velocity=runs[0][k].velocity, mean_velocity=v)
    return out


def _mean_distances(sig: dict, ref: dict) -> dict[str, float]:
    d = [signature_distances(sig[k], ref[k]) for k in ref]
    return {"tv": float(np.mean([x["tv"] for x in d])), "emd_m_s": float(np.mean([x["emd"] for x in d])),
            "rmse_m_s": float(np.mean([x["rmse"] for x in d])), "dtw": float(np.mean([x["dtw"] for x in d]))}


def converged_reference(reference: Setting, motion, radar: RadarConfig, seeds: int) -> tuple[float, dict, dict]:
    """(median wall time [s] of one run, ensemble-mean signatures, self error) of `reference` averaged over
    `seeds` seeds. The self error is half the distance between the means of the even and odd runs
    (module docstring); with one seed it is unknown (NaN)."""
    runs, times = [], []
    for s in range(seeds):
        t, sig = _run(reference, motion, radar, 1, seed=s + 1)  # the settings themselves run with seed 0
        runs.append(sig)
        times.append(t)
    ref = ensemble_mean(runs)
    if seeds >= 2:
        half = _mean_distances(ensemble_mean(runs[0::2]), ensemble_mean(runs[1::2]))
        self_error = {k: v / 2 for k, v in half.items()}
        # one draw's speckle: two single reference runs with different seeds differ by this much, so a
        # single run of any setting cannot be told from the reference closer than that (averaged over pairs)
        pairs = [_mean_distances(runs[i], runs[i + 1]) for i in range(0, seeds - 1, 2)]
        self_error["single_run_emd_m_s"] = float(np.mean([d["emd_m_s"] for d in pairs]))
    else:
        self_error = {k: float("nan") for k in ("tv", "emd_m_s", "rmse_m_s", "dtw", "single_run_emd_m_s")}
    return statistics.median(times), ref, self_error


def sweep(motion, radar: RadarConfig, settings=SWEEP, reference: Setting = REFERENCE, repeats: int = 3,
          progress=None, reference_seeds: int = REFERENCE_SEEDS) -> tuple[list[dict], dict]:
    """Time each setting and measure its error against the converged `reference` (run once per seed,
    after a warm-up of each backend so that scene loading and kernel compilation are not timed).
    Returns one row per setting (the reference's row carries its self error) and a summary:
    `reference_self_emd_m_s`, `spread_emd_m_s` (worst - best setting), their ratio and `converged`
    (ratio >= 3)."""
    from dataclasses import replace

    from rtchannel.pipeline import simulate

    if repeats < 1:
        raise InputError(f"repeats must be at least 1, got {repeats}")
    warmed: set[str] = set()
    n = max(int(0.3 * motion.fps), 4)
    short = replace(motion, positions=motion.positions[:n], rotations=motion.rotations[:n])

    def warm(backend: str, options: dict) -> None:
        key = f"{backend}:{options.get('lod')}"
        if key not in warmed:  # scene loading, LOD loading and kernel compilation are not timed
            simulate(short, radar, backend=backend, **options)
            warmed.add(key)

    warm(reference.backend, reference.options)
    ref_time, ref, self_error = converged_reference(reference, motion, radar, reference_seeds)
    floor = self_error.pop("single_run_emd_m_s")
    rows = [{"label": f"{reference.label}, mean of {reference_seeds} seeds (reference)", "backend": reference.backend,
             "knob": "reference", "options": reference.options, "s_per_sim_s": ref_time / motion.duration,
             **self_error}]
    if progress:
        progress(1)
    for s in settings:
        warm(s.backend, s.options)
        wall, sig = _run(s, motion, radar, repeats if s.backend != "sionna" else 1)
        rows.append({"label": s.label, "backend": s.backend, "knob": s.knob, "options": s.options,
                     "s_per_sim_s": wall / motion.duration, **_mean_distances(sig, ref)})
        if progress:
            progress(1)
    emd = [r["emd_m_s"] for r in rows[1:]]
    spread = max(emd) - min(emd) if emd else 0.0
    ratio = spread / self_error["emd_m_s"] if self_error["emd_m_s"] > 0 else float("inf")
    summary = {"reference_self_emd_m_s": self_error["emd_m_s"], "single_run_floor_emd_m_s": floor,
               "spread_emd_m_s": spread,
               "spread_to_self_error": ratio, "converged": bool(ratio >= 3.0), "reference_seeds": reference_seeds}
    return rows, summary


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
    keys = ["label", "backend", "knob", "options", "s_per_sim_s", "tv", "emd_m_s", "rmse_m_s", "dtw"]
    p_csv = out_dir / "speed_error.csv"
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(keys)
    for r in rows:
        w.writerow([json.dumps(r[k]) if k == "options" else
                    (f"{r[k]:.4g}" if isinstance(r[k], float) else r[k]) for k in keys])
    write_text_atomic(p_csv, buf.getvalue())
    floor = meta.get("single_run_floor_emd_m_s", float("nan"))
    md = [f"Single-realisation floor (EMD between two reference runs with different seeds): {floor:.3f} m/s; a "
          "setting at or below it cannot be told from the reference by one run.",
          f"Reference: {rows[0]['label']}; its own error (half-split) is the first row. Spread of the settings' "
          f"EMD / reference error = {meta.get('spread_to_self_error', float('nan')):.1f} "
          f"({'converged' if meta.get('converged') else 'NOT converged: the ranking is within the reference noise'}).",
          "",
          "| setting | s per simulated s | p(v,t) EMD [m/s] | p(v,t) TV | mean-v RMSE [m/s] | DTW |",
          "|---|---|---|---|---|---|"]
    md += [f"| {r['label']} | {r['s_per_sim_s']:.3g} | {r['emd_m_s']:.3f} | {r['tv']:.3f} | {r['rmse_m_s']:.3f} "
           f"| {r['dtw']:.3f} |" for r in rows]
    p_md = out_dir / "speed_error.md"
    write_text_atomic(p_md, "\n".join(md) + "\n")
    cost = np.array([r["s_per_sim_s"] for r in rows])
    err = np.array([r["emd_m_s"] for r in rows])
    front = 1 + pareto_front(cost[1:], err[1:])  # the reference row carries its own error, not a distance
    fig, ax = plt.subplots(figsize=(11, 6))
    colours = {"points": "tab:green", "facets": "tab:blue", "sionna": "tab:red"}
    markers = {"reference": "*", "backend": "o", "accuracy": "D", "LOD": "s", "trace rate": "^", "rays": "v",
               "image LOD": "P", "gain cut": "X", "physics": "h"}
    seen = set()
    for r, c, e in zip(rows, cost, err):
        knob = r.get("knob", "backend")
        ax.scatter(c, e if np.isfinite(e) else 0.0, color=colours.get(r["backend"], "k"),
                   marker=markers.get(knob, "o"), s=60 if knob == "reference" else 30, zorder=3)
        seen.add(knob)
        ax.annotate(r["label"], (c, e if np.isfinite(e) else 0.0), fontsize=7, xytext=(4, 3),
                    textcoords="offset points")
    for knob in markers:  # legend proxies: marker = knob, colour = backend
        if knob in seen:
            ax.scatter([], [], color="grey", marker=markers[knob], label=f"knob: {knob}")
    for b in sorted({r["backend"] for r in rows}):
        ax.scatter([], [], color=colours.get(b, "k"), marker="o", label=b)
    if np.isfinite(err[0]) and err[0] > 0:
        ax.axhline(err[0], color="tab:red", lw=0.8, ls="-.", label="reference's own error (half-split)")
    floor = meta.get("single_run_floor_emd_m_s", float("nan"))
    if np.isfinite(floor) and floor > 0:  # below it a single run is indistinguishable from the reference
        ax.axhspan(0.0, floor, color="tab:orange", alpha=0.12, zorder=0,
                   label="single-realisation floor: two reference runs, different seeds")
    ax.plot(cost[front], err[front], "k--", lw=1, label="Pareto front")
    ax.axvline(1.0, color="grey", lw=0.8, ls=":", label="real time")
    ax.set_xscale("log")
    ax.set_xlabel("wall time per simulated second [s] (2 cores)")
    ax.set_ylabel("mean p(v,t) earth-mover distance to reference [m/s]")
    ref_label = rows[0]["label"].replace(" (reference)", "")
    ax.set_title(f"speed against error: {meta.get('activity', '')}\nreference: {ref_label}", fontsize=9)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    p_png = out_dir / "speed_error.png"
    savefig_atomic(fig, p_png, dpi=120)
    plt.close(fig)
    p_json = out_dir / "speed_error.json"
    write_text_atomic(p_json, json.dumps({"meta": meta, "rows": rows, "pareto": [rows[i]["label"] for i in front]},
                                         indent=1) + "\n")
    return [p_csv, p_md, p_png, p_json]
