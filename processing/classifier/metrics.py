"""Classification metrics and the seed's confusion-matrix layout (Fig. 11).

Layout: rows = true class, columns = predicted class, cell = count. An extra column holds each true
class's recall (and 1 - recall below it in the PNG), an extra row each predicted class's precision
(and 1 - precision), and the corner the overall accuracy (and error). A class never predicted has
precision 0 (scikit-learn's `zero_division=0`), a class absent from the test set recall 0; macro F1
averages the per-class F1 over the classes present in y_true or y_pred (scikit-learn's default labels).
"""
from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from processing.atomic import write_text_atomic
from processing.errors import InputError


def confusion_matrix(y_true, y_pred, n_classes: int) -> np.ndarray:
    """Counts [n_classes, n_classes]: row = true label, column = predicted label."""
    yt, yp = np.asarray(y_true, int), np.asarray(y_pred, int)
    if yt.shape != yp.shape:
        raise InputError(f"y_true and y_pred differ in length ({yt.size} vs {yp.size})")
    if yt.size and (min(yt.min(), yp.min()) < 0 or max(yt.max(), yp.max()) >= n_classes):
        raise InputError(f"labels must lie in 0..{n_classes - 1}")
    cm = np.zeros((n_classes, n_classes), np.int64)
    np.add.at(cm, (yt, yp), 1)
    return cm


@dataclass
class Report:
    """Metrics of one evaluation. Fractions in [0, 1]."""

    classes: list[str]
    confusion: np.ndarray
    accuracy: float
    precision: np.ndarray
    recall: np.ndarray
    f1: np.ndarray
    macro_f1: float
    n: int
    extra: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """JSON-ready summary."""
        return {"n": self.n, "accuracy": self.accuracy, "macro_f1": self.macro_f1,
                "classes": self.classes, "confusion": self.confusion.tolist(),
                "precision": dict(zip(self.classes, self.precision.tolist())),
                "recall": dict(zip(self.classes, self.recall.tolist())),
                "f1": dict(zip(self.classes, self.f1.tolist())), **self.extra}

    def summary(self) -> str:
        """A few human-readable lines."""
        lines = [f"n = {self.n}, accuracy = {100 * self.accuracy:.2f} %, macro F1 = {100 * self.macro_f1:.2f} %"]
        for i, c in enumerate(self.classes):
            lines.append(f"  {c:>8s}: precision {100 * self.precision[i]:6.2f} %  recall {100 * self.recall[i]:6.2f} %"
                         f"  (support {int(self.confusion[i].sum())})")
        return "\n".join(lines)


def _safe_div(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.divide(a, b, out=np.zeros_like(a, dtype=float), where=b > 0)


def classification_report(y_true, y_pred, classes) -> Report:
    """Accuracy, per-class precision/recall/F1 and macro F1 of integer labels indexing `classes`."""
    classes = list(classes)
    cm = confusion_matrix(y_true, y_pred, len(classes))
    tp = np.diag(cm).astype(float)
    precision = _safe_div(tp, cm.sum(axis=0).astype(float))
    recall = _safe_div(tp, cm.sum(axis=1).astype(float))
    f1 = _safe_div(2 * precision * recall, precision + recall)
    present = (cm.sum(axis=0) + cm.sum(axis=1)) > 0
    n = int(cm.sum())
    return Report(classes=classes, confusion=cm, accuracy=float(tp.sum() / n) if n else 0.0,
                  precision=precision, recall=recall, f1=f1,
                  macro_f1=float(f1[present].mean()) if present.any() else 0.0, n=n)


def write_confusion_csv(report: Report, path: str | Path) -> Path:
    """The seed's layout as CSV: counts, a `recall` column, a `precision` row, accuracy in the corner."""
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(["true \\ predicted", *report.classes, "recall"])
    for i, c in enumerate(report.classes):
        w.writerow([c, *report.confusion[i].tolist(), f"{report.recall[i]:.6f}"])
    w.writerow(["precision", *[f"{p:.6f}" for p in report.precision], f"{report.accuracy:.6f}"])
    return write_text_atomic(path, buf.getvalue())


def plot_confusion(report: Report, path: str | Path, title: str | None = None) -> Path:
    """PNG in the seed's Fig. 11 layout: counts, recall column and precision row (green), accuracy (white)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    k = len(report.classes)
    cm = report.confusion
    fig, ax = plt.subplots(figsize=(1.3 * (k + 1) + 1.5, 1.1 * (k + 1) + 1.2))
    total = max(cm.sum(), 1)
    for i in range(k + 1):
        for j in range(k + 1):
            if i < k and j < k:
                colour = "#8fbfe8" if i == j else ("#f4b6b0" if cm[i, j] else "#f2f2f2")
                text = f"{cm[i, j]}\n{100 * cm[i, j] / total:.1f}%"
            elif i < k:
                colour, r = "#c9e8c0", report.recall[i]
                text = f"{100 * r:.2f}%\n{100 * (1 - r):.2f}%"
            elif j < k:
                colour, p = "#c9e8c0", report.precision[j]
                text = f"{100 * p:.2f}%\n{100 * (1 - p):.2f}%"
            else:
                colour, a = "white", report.accuracy
                text = f"{100 * a:.2f}%\n{100 * (1 - a):.2f}%"
            ax.add_patch(Rectangle((j, i), 1, 1, facecolor=colour, edgecolor="grey"))
            bold = "bold" if (i == j) or i == k or j == k else "normal"
            ax.text(j + 0.5, i + 0.5, text, ha="center", va="center", fontsize=9, fontweight=bold)
    ax.set_xlim(0, k + 1)
    ax.set_ylim(k + 1, 0)
    names = [c.capitalize() for c in report.classes]
    ax.set_xticks(np.arange(k + 1) + 0.5, names + ["Recall"])
    ax.set_yticks(np.arange(k + 1) + 0.5, names + ["Precision"])
    ax.set_xlabel("Predicted class")
    ax.set_ylabel("True class")
    ax.tick_params(length=0)
    ax.set_aspect("equal")
    ax.set_title(title or f"accuracy {100 * report.accuracy:.2f} %, macro F1 {100 * report.macro_f1:.2f} % "
                 f"(n = {report.n})", fontsize=10)
    from processing.plots.classifier import save_figure

    return save_figure(fig, path)
