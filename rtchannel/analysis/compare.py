"""Cross-backend comparison: the seed's Table I (normalised DTW of mean radial velocities for every
activity pair across two backends), spectrogram distances, and a side-by-side p(v,t) figure."""
from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from processing.atomic import savefig_atomic, write_text_atomic
from processing.metrics.distances import normalised_dtw, signature_distances
from rtchannel.motion.procedural import ACTIVITIES, generate
from rtchannel.radar import RadarConfig
from rtchannel.pipeline import simulate


def run_backends(backends: list[str], activities: list[str], radar: RadarConfig, seed: int = 0,
                 height: float = 1.75, options: dict[str, dict] | None = None, progress=None,
                 accuracy=None, calibration=None) -> dict:
    """Signatures {backend: {activity: {link: Signature}}} of procedural activities through each backend.

    `options` maps a backend name to its keyword options (e.g. {"facets": {"lod": "5k"}}); `accuracy`
    (with its `calibration` table) chooses the mesh backends' settings (`rtchannel.accuracy`).
    """
    options = options or {}
    out: dict = {}
    for b in backends:
        out[b] = {}
        for a in activities:
            # walks are centred on the origin (as the CLI does) so they stop 1 m short of a seed radar
            start: dict[str, Any] = {"start": (-2.0, 0.0)} if a == "walk" else {}
            motion = generate(a, height=height, seed=seed, **start)
            budget = ({"accuracy": accuracy, "calibration": calibration} if accuracy is not None and b != "points"
                      else {})
            res = simulate(motion, radar, backend=b, **budget, **options.get(b, {}))
            out[b][a] = {name: r.signature for name, r in res.links.items()}
            if progress is not None:
                progress(1)
    return out


def dtw_table(sigs_a: dict, sigs_b: dict) -> tuple[list[str], list[str], np.ndarray]:
    """Normalised DTW between mean velocities of activity i (rows, backend A) and activity j (columns,
    backend B), averaged over the links both share: the layout of the seed's Table I
    (`processing.metrics.distances.normalised_dtw`, scaled by the pair's peak speed)."""
    rows, cols = list(sigs_a), list(sigs_b)
    table = np.zeros((len(rows), len(cols)))
    for i, a in enumerate(rows):
        for j, b in enumerate(cols):
            links = sorted(set(sigs_a[a]) & set(sigs_b[b]))
            table[i, j] = np.mean([normalised_dtw(sigs_a[a][k].mean_velocity, sigs_b[b][k].mean_velocity)
                                   for k in links])
    return rows, cols, table


def same_activity_distances(sigs_a: dict, sigs_b: dict) -> dict[str, dict[str, float]]:
    """Per activity (present in both), DTW / p(v,t) TV / mean-velocity RMSE averaged over shared links."""
    out = {}
    for a in sorted(set(sigs_a) & set(sigs_b), key=list(sigs_a).index):
        links = sorted(set(sigs_a[a]) & set(sigs_b[a]))
        per = [signature_distances(sigs_a[a][k], sigs_b[a][k]) for k in links]
        out[a] = {m: float(np.mean([d[m] for d in per])) for m in per[0]}
    return out


def write_tables(out_dir: Path, name_a: str, name_b: str, rows, cols, table, per_activity) -> list[Path]:
    """CSV of the DTW table, CSV of per-activity distances, and a Markdown rendering of both."""
    out_dir.mkdir(parents=True, exist_ok=True)
    p_dtw = out_dir / f"dtw_{name_a}_vs_{name_b}.csv"
    write_text_atomic(p_dtw, _csv([[f"{name_a} \\ {name_b}", *cols]]
                                  + [[r, *(f"{x:.4f}" for x in row)] for r, row in zip(rows, table)]))
    p_act = out_dir / f"distances_{name_a}_vs_{name_b}.csv"
    write_text_atomic(p_act, _csv([["activity", "dtw", "tv", "emd_m_s", "rmse_m_s"]] + [
        [a, f"{d['dtw']:.4f}", f"{d['tv']:.4f}", f"{d['emd']:.4f}", f"{d['rmse']:.4f}"]
        for a, d in per_activity.items()]))
    md = [f"Normalised DTW of mean radial velocity, rows {name_a}, columns {name_b} (mean over links)", "",
          "| | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for r, row in zip(rows, table):
        md.append(f"| {r} | " + " | ".join(f"**{x:.2f}**" if r == c else f"{x:.2f}" for c, x in zip(cols, row))
                  + " |")
    md += ["", "| activity | DTW | p(v,t) TV | p(v,t) EMD [m/s] | mean-velocity RMSE [m/s] |", "|---|---|---|---|---|"]
    md += [f"| {a} | {d['dtw']:.3f} | {d['tv']:.3f} | {d['emd']:.3f} | {d['rmse']:.3f} |"
           for a, d in per_activity.items()]
    p_md = out_dir / f"table_{name_a}_vs_{name_b}.md"
    write_text_atomic(p_md, "\n".join(md) + "\n")
    return [p_dtw, p_act, p_md]


def _csv(rows) -> str:
    buf = io.StringIO(newline="")
    csv.writer(buf).writerows(rows)
    return buf.getvalue()


def plot_side_by_side(sigs: dict, path: Path, dynamic_range_db: float = 40.0) -> Path:
    """PNG grid of p(v,t): one row per activity, one column per (backend, link), dB scale."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    backends = list(sigs)
    activities = [a for a in ACTIVITIES if all(a in sigs[b] for b in backends)]
    columns = [(b, k) for b in backends for k in sorted(next(iter(sigs[b].values())))]
    fig, axes = plt.subplots(len(activities), len(columns), figsize=(2.6 * len(columns), 2.0 * len(activities)),
                             squeeze=False, sharey=True)
    for i, a in enumerate(activities):
        for j, (b, k) in enumerate(columns):
            s = sigs[b][a][k]
            p = s.p_vt / s.p_vt.max() if s.p_vt.max() > 0 else s.p_vt
            db = 10 * np.log10(np.maximum(p, 10 ** (-dynamic_range_db / 10)))
            ax = axes[i, j]
            ax.imshow(db, origin="lower", aspect="auto", cmap="jet", vmin=-dynamic_range_db, vmax=0,
                      extent=[s.time[0], s.time[-1], s.velocity[0], s.velocity[-1]])
            ax.plot(s.time, s.mean_velocity, color="w", lw=0.8)
            if i == 0:
                ax.set_title(f"{b} / {k}", fontsize=9)
            if j == 0:
                ax.set_ylabel(f"{a}\nv [m/s]", fontsize=9)
            if i == len(activities) - 1:
                ax.set_xlabel("t [s]", fontsize=8)
            ax.tick_params(labelsize=7)
    fig.tight_layout()
    savefig_atomic(fig, path, dpi=110)
    plt.close(fig)
    return path


def compare(backends: list[str], activities: list[str], radar: RadarConfig, out_dir: Path, seed: int = 0,
            height: float = 1.75, options: dict | None = None, progress=None, accuracy=None,
            calibration=None) -> list[Path]:
    """Run, tabulate (first backend against each other one) and plot; returns the files written. `accuracy`
    and `calibration` go to the mesh backends (`run_backends`)."""
    sigs = run_backends(backends, activities, radar, seed, height, options, progress, accuracy, calibration)
    written, summary = [], {}
    for other in backends[1:]:
        rows, cols, table = dtw_table(sigs[backends[0]], sigs[other])
        per = same_activity_distances(sigs[backends[0]], sigs[other])
        written += write_tables(out_dir, backends[0], other, rows, cols, table, per)
        summary[f"{backends[0]}_vs_{other}"] = {"dtw": table.tolist(), "rows": rows, "cols": cols, "per_activity": per}
    written.append(plot_side_by_side(sigs, out_dir / "pvt_side_by_side.png"))
    p = out_dir / "summary.json"
    write_text_atomic(p, json.dumps({"backends": backends, "activities": activities, "seed": seed, "height": height,
                             "options": options or {}, "accuracy": accuracy, "radar": radar.model_dump(mode="json"),
                             "comparisons": summary}, indent=1) + "\n")
    return [*written, p]
