"""Heat map of a classifier's robustness grid (`processing.classifier.perturb.robustness_grid`).

Top panel: one row per perturbation kind (shift, stretch, velocity, floor), its values ordered left to right
with the unperturbed accuracy (the 'none' row) in the middle column where that kind changes nothing (shift
0 s, stretch x1, velocity x1, floor 0 dB), so reading along a row shows accuracy falling off either side of
the baseline. Cells: accuracy in %, annotated with the value and the accuracy, and where the perturbation
truncated images (moved most of their motion out of the image, `perturb.motion_kept`) the accuracy on the
intact ones and the truncated share. Bottom panel (when the rows carry per-class recall): one row per
class, one column per perturbation in grid order, cells recall in %.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from processing.atomic import savefig_atomic

KIND_ORDER = ("shift", "stretch", "velocity", "floor")
_UNIT = {"shift": " s", "stretch": "", "velocity": "", "floor": " dB"}
_NEUTRAL = {"shift": 0.0, "stretch": 1.0, "velocity": 1.0, "floor": 0.0}
_CMAP = "RdYlGn"  # red = low accuracy, green = high: the eye goes to what breaks


def _label(kind: str, value: float) -> str:
    if kind in ("stretch", "velocity"):
        return f"x{value:g}"
    return f"{value:+g}{_UNIT[kind]}"


def _kind_grid(rows: list[dict]) -> tuple[list[str], np.ndarray, list[list[str]], list[list[str]]]:
    """(kinds, accuracy % [K, C] with NaN for empty cells, cell labels [K][C], cell notes [K][C] (`_note`));
    the neutral column holds 'none'."""
    base = next((r["accuracy"] for r in rows if r["kind"] == "none"), None)
    kinds = [k for k in KIND_ORDER if any(r["kind"] == k for r in rows)]
    kinds += sorted({r["kind"] for r in rows} - set(kinds) - {"none"})
    below, above = {}, {}
    for k in kinds:
        vals = sorted((float(r["value"]), r["accuracy"], _note(r)) for r in rows if r["kind"] == k)
        n0 = _NEUTRAL.get(k, 0.0)
        below[k] = [v for v in vals if v[0] < n0]
        above[k] = [v for v in vals if v[0] >= n0]
    nb = max((len(b) for b in below.values()), default=0)
    na = max((len(a) for a in above.values()), default=0)
    ncol = nb + 1 + na
    acc = np.full((len(kinds), ncol), np.nan)
    labels = [[""] * ncol for _ in kinds]
    notes = [[""] * ncol for _ in kinds]
    for i, k in enumerate(kinds):
        for j, (v, a, n) in enumerate(below[k]):
            col = nb - len(below[k]) + j
            acc[i, col], labels[i][col], notes[i][col] = 100 * a, _label(k, v), n
        if base is not None:
            acc[i, nb], labels[i][nb] = 100 * base, "none"
        for j, (v, a, n) in enumerate(above[k]):
            acc[i, nb + 1 + j], labels[i][nb + 1 + j], notes[i][nb + 1 + j] = 100 * a, _label(k, v), n
    return kinds, acc, labels, notes


def _note(row: dict) -> str:
    """Third line of a cell where the perturbation truncated images: the accuracy on the intact ones."""
    tr, ai = row.get("truncated"), row.get("accuracy_intact")
    if not tr or tr < 0.005:
        return ""
    return f"{100 * tr:.0f}% truncated" if ai is None else f"intact {100 * ai:.1f}% ({100 * tr:.0f}% trunc.)"


def _annotate(ax, values: np.ndarray, labels=None, fontsize: float = 8, notes=None) -> None:
    for (i, j), v in np.ndenumerate(values):
        if np.isnan(v):
            continue
        text = f"{v:.0f}%" if labels is None else f"{labels[i][j]}\n{v:.1f}%"
        if notes is not None and notes[i][j]:
            text += "\n" + notes[i][j]
        # dark text on the light middle of the map, white on its saturated ends
        colour = "white" if v < 20 or v > 85 else "black"
        ax.text(j, i, text, ha="center", va="center", fontsize=fontsize, color=colour)


def plot_robustness(rows: list[dict], path: str | Path, title: str | None = None) -> Path:
    """PNG heat map of robustness rows (see the module docstring); returns `path` (written atomically)."""
    kinds, acc, labels, notes = _kind_grid(rows)
    classes = [k[len("recall_"):] for k in rows[0] if k.startswith("recall_")] if rows else []
    ncol = acc.shape[1] if acc.size else 1
    top_h = 0.65 * max(len(kinds), 1) + 0.9
    bot_h = 0.4 * len(classes) + 1.6 if classes else 0.0
    width = max(1.15 * ncol + 2.2, 0.55 * len(rows) + 2.6, 7.0)
    fig = Figure(figsize=(width, top_h + bot_h + 0.6))
    FigureCanvasAgg(fig)  # Agg, whatever backend pyplot may have chosen in this process
    axes = fig.subplots(2 if classes else 1, 1, squeeze=False,
                        gridspec_kw={"height_ratios": [top_h, bot_h] if classes else [1]})[:, 0]
    ax = axes[0]
    masked = np.ma.masked_invalid(acc if acc.size else np.full((1, 1), np.nan))
    im = ax.imshow(masked, cmap=_CMAP, vmin=0, vmax=100, aspect="auto")
    ax.set_facecolor("white")
    _annotate(ax, acc, labels, notes=notes)
    if any(r["kind"] == "none" for r in rows) and kinds:  # outline the unperturbed column: the reference
        mid = next(j for j in range(acc.shape[1]) if labels[0][j] == "none")
        ax.add_patch(Rectangle((mid - 0.5, -0.5), 1, len(kinds), fill=False, edgecolor="black", lw=2))
    ax.set_yticks(np.arange(len(kinds)), kinds)
    ax.set_xticks([])
    ax.set_title("accuracy [%] under each perturbation (middle column: unperturbed)", fontsize=10)
    fig.colorbar(im, ax=ax, label="accuracy [%]", fraction=0.04, pad=0.02)
    if classes:
        ax = axes[1]
        rec = np.array([[100 * float(r[f"recall_{c}"]) for r in rows] for c in classes])
        im = ax.imshow(rec, cmap=_CMAP, vmin=0, vmax=100, aspect="auto")
        _annotate(ax, rec, fontsize=7)
        ax.set_yticks(np.arange(len(classes)), classes)
        ax.set_xticks(np.arange(len(rows)), [r["perturbation"] for r in rows], rotation=60, ha="right", fontsize=8)
        ax.set_title("recall [%] per class", fontsize=10)
        fig.colorbar(im, ax=ax, label="recall [%]", fraction=0.04, pad=0.02)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return savefig_atomic(fig, path, dpi=110)


__all__ = ["plot_robustness"]
