"""The seed's Table I against real recordings: normalised DTW between simulated and real mean-velocity
curves, activity x activity (rows simulated, columns real, as in the seed).

A cell is the mean of `processing.metrics.distances.normalised_dtw` (RMS difference along the optimal warping path
per time bin, over the pair's peak |v|: the same normalisation as the backend-vs-backend Table I of
`rtchannel compare`) over every (simulated curve, real curve) pair of the two activities; the standard
deviation and pair count are written beside it. Before DTW both curves are resampled (linear
interpolation) to one time step `dt_s`, because the normalisation divides by the number of samples:
real Glasgow columns are 13 or 26.5 ms apart (5 s or 10 s over 383 or 377 px), simulated windows 16 ms.

Curves come from `signature.h5` files or a dataset (one link), and from real images
(`processing.realdata.real_images`: mean velocity 0 in noise-only columns, as in simulated signatures).
"""
from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from processing.atomic import savefig_atomic, write_text_atomic
from processing.errors import InputError
from processing.metrics.distances import normalised_dtw

DEFAULT_DT_S = 0.016  # the seed's STFT hop (32 chirps of 0.5 ms)
ORDER = ("fall", "walk", "stand", "sit", "pick", "drink")  # the seed's Table I order, then drink


@dataclass
class Curve:
    """One mean-velocity curve: `v` [T] m/s at times `t` [T] s, labelled."""

    name: str
    activity: str
    t: np.ndarray
    v: np.ndarray


def resample(curve: Curve, dt_s: float) -> np.ndarray:
    """The curve's mean velocity [m/s] on a uniform grid of step `dt_s` [s] over its own time span."""
    t, v = np.asarray(curve.t, float), np.asarray(curve.v, float)
    if t.size < 2 or not np.all(np.isfinite(v)):
        raise InputError(f"{curve.name}: mean-velocity curve needs 2 or more finite samples")
    n = int(np.floor((t[-1] - t[0]) / dt_s)) + 1
    return np.interp(t[0] + np.arange(n) * dt_s, t, v)


def curves_from_signature_files(paths, link: str) -> list[Curve]:
    """Curves of link `link` of `signature.h5` files (activity from the file's `activity` attribute)."""
    from processing.io.signature_file import read_signature_file

    out = []
    for p in paths:
        attrs, sigs = read_signature_file(p)
        if link not in sigs:
            raise InputError(f"{p}: no link {link!r} (has {', '.join(sigs)})")
        s = sigs[link]
        out.append(Curve(str(p), str(attrs.get("activity", "")), s.time, s.mean_velocity))
    return out


def curves_from_dataset(reader, indices, link: str) -> list[Curve]:
    """Curves of link `link` of dataset entries (activity from the entry)."""
    out = []
    for i in indices:
        e = reader.entries[i]
        a = reader.load(i, links=[link])[link]
        out.append(Curve(e["item_id"], str(e.get("activity", "")), a["time"], a["mean_velocity"]))
    return out


def curves_from_images(images) -> list[Curve]:
    """Curves of `processing.realdata.real_images.RealImage`s."""
    return [Curve(im.name, im.activity, im.signature.time, im.signature.mean_velocity) for im in images]


def _activities(curves: list[Curve]) -> list[str]:
    acts = {c.activity for c in curves}
    return [a for a in ORDER if a in acts] + sorted(acts - set(ORDER))


@dataclass
class DTWTable:
    """Mean, std and pair count [rows, cols] of normalised DTW, rows/cols = activities."""

    rows: list[str]
    cols: list[str]
    mean: np.ndarray
    std: np.ndarray
    n: np.ndarray
    dt_s: float
    scale: float | None = None


def dtw_activity_table(row_curves: list[Curve], col_curves: list[Curve], dt_s: float = DEFAULT_DT_S,
                       scale: float | None = None) -> DTWTable:
    """Normalised DTW between every row curve and every column curve, averaged per activity pair.

    `scale` [m/s]: None divides each pair by its larger peak |v| (as `rtchannel compare`); a number
    (e.g. v_max) divides every pair by the same speed."""
    if not row_curves or not col_curves:
        raise InputError("the DTW table needs curves on both sides")
    if not (np.isfinite(dt_s) and 1e-4 <= dt_s <= 10) or (scale is not None and not (np.isfinite(scale) and scale > 0)):
        raise InputError(f"DTW time step must be 0.1 ms to 10 s (got {dt_s:g} s) and the scale positive")
    rows, cols = _activities(row_curves), _activities(col_curves)
    rs = [(c.activity, resample(c, dt_s)) for c in row_curves]
    cs = [(c.activity, resample(c, dt_s)) for c in col_curves]
    d = np.array([[normalised_dtw(a, b, scale) for _, b in cs] for _, a in rs])
    ra, ca = np.array([a for a, _ in rs]), np.array([a for a, _ in cs])
    mean, std, n = (np.zeros((len(rows), len(cols))) for _ in range(3))
    for i, r in enumerate(rows):
        for j, c in enumerate(cols):
            block = d[np.ix_(ra == r, ca == c)]
            mean[i, j], std[i, j], n[i, j] = block.mean(), block.std(), block.size
    return DTWTable(rows, cols, mean, std, n.astype(int), dt_s, scale)


def _csv(rows) -> str:
    buf = io.StringIO(newline="")
    csv.writer(buf).writerows(rows)
    return buf.getvalue()


def write_dtw_table(table: DTWTable, out_dir: str | Path, row_name: str = "simulated", col_name: str = "real",
                    title: str | None = None) -> list[Path]:
    """dtw_<rows>_vs_<cols>.csv (matrix of means), ..._pairs.csv (mean, std, n per cell), .md and a
    heatmap PNG (rows = `row_name`, columns = `col_name`); returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stem = f"dtw_{row_name}_vs_{col_name}"
    files = [write_text_atomic(out / f"{stem}.csv", _csv(
        [[f"{row_name} \\ {col_name}", *table.cols]]
        + [[r, *(f"{x:.4f}" for x in row)] for r, row in zip(table.rows, table.mean)]))]
    files.append(write_text_atomic(out / f"{stem}_pairs.csv", _csv(
        [[row_name, col_name, "dtw_mean", "dtw_std", "n_pairs"]]
        + [[r, c, f"{table.mean[i, j]:.4f}", f"{table.std[i, j]:.4f}", int(table.n[i, j])]
           for i, r in enumerate(table.rows) for j, c in enumerate(table.cols)])))
    md = [title or f"Normalised DTW of mean radial velocity, rows {row_name}, columns {col_name} "
          f"(mean over curve pairs, resampled to {1000 * table.dt_s:g} ms, scale "
          f"{'pair peak |v|' if table.scale is None else f'{table.scale:g} m/s'})", "",
          "| | " + " | ".join(table.cols) + " |", "|---" * (len(table.cols) + 1) + "|"]
    for i, r in enumerate(table.rows):
        best = int(np.argmin(table.mean[i]))
        md.append(f"| {r} | " + " | ".join(f"**{x:.2f}**" if j == best else f"{x:.2f}"
                                            for j, x in enumerate(table.mean[i])) + " |")
    files.append(write_text_atomic(out / f"{stem}.md", "\n".join(md) + "\n"))
    files.append(plot_dtw_table(table, out / f"{stem}.png", row_name, col_name))
    return files


def plot_dtw_table(table: DTWTable, path: Path, row_name: str, col_name: str) -> Path:
    """Heatmap of the mean DTW with the values written in the cells (row minimum in bold)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(1.0 * len(table.cols) + 2.2, 0.8 * len(table.rows) + 1.6))
    im = ax.imshow(table.mean, cmap="viridis_r", vmin=0)
    for i in range(len(table.rows)):
        best = int(np.argmin(table.mean[i]))
        for j in range(len(table.cols)):
            x = table.mean[i, j]
            ax.text(j, i, f"{x:.2f}", ha="center", va="center", fontsize=9,
                    fontweight="bold" if j == best else "normal",
                    color="white" if x > 0.6 * table.mean.max() else "black")
    ax.set_xticks(range(len(table.cols)), table.cols)
    ax.set_yticks(range(len(table.rows)), table.rows)
    ax.set_xlabel(col_name)
    ax.set_ylabel(row_name)
    fig.colorbar(im, ax=ax, label="normalised DTW")
    ax.set_title("mean-velocity DTW (row minimum bold)", fontsize=10)
    fig.tight_layout()
    savefig_atomic(fig, path, dpi=110)
    plt.close(fig)
    return path
