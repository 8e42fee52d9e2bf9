"""The transfer study's tables: accuracy per arm and shot count over folds and seeds, what the simulation is
worth in real recordings, and the files `rtchannel transfer` writes (CSV, markdown, PNG, JSON)."""
from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np

_ORDER = {"sim": 0, "real": 1, "finetune": 2, "mixed": 3}
_FIELDS = ["arm", "shots", "shots_per_class", "runs", "accuracy_pct_mean", "accuracy_pct_std", "accuracy_pct_min",
           "accuracy_pct_max", "macro_f1_pct_mean", "macro_f1_pct_std", "n_test_per_run"]


def _shot_key(s) -> float:
    return np.inf if s == "all" else float(s)


def summarise(rows: list[dict]) -> list[dict]:
    """One row per (arm, shots): runs (folds x seeds), mean real images per class, accuracy [%] mean, standard
    deviation (ddof 0), minimum and maximum over the runs, macro F1 [%] mean and standard deviation."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        if r.get("arm") in _ORDER:
            groups.setdefault((r["arm"], r["shots"]), []).append(r)
    out = []
    for (arm, shots), rs in sorted(groups.items(), key=lambda kv: (_ORDER[kv[0][0]], _shot_key(kv[0][1]))):
        acc = 100 * np.array([r["accuracy"] for r in rs])
        f1 = 100 * np.array([r["macro_f1"] for r in rs])
        out.append({"arm": arm, "shots": shots, "shots_per_class": float(np.mean([r["shots_per_class"] for r in rs])),
                    "runs": len(rs), "accuracy_pct_mean": float(acc.mean()), "accuracy_pct_std": float(acc.std()),
                    "accuracy_pct_min": float(acc.min()), "accuracy_pct_max": float(acc.max()),
                    "macro_f1_pct_mean": float(f1.mean()), "macro_f1_pct_std": float(f1.std()),
                    "n_test_per_run": float(np.mean([r["n_test"] for r in rs]))})
    return out


def simulation_worth(summary: list[dict]) -> dict:
    """The real recordings per class at which the real-only curve (mean accuracy) reaches the simulation-only
    accuracy, interpolated linearly between the measured shot counts.

    Returns {"sim_accuracy_pct", "per_class" (None when not bracketed), "bound" ('within', 'below' the first
    shot count, 'above' the last), "text"}; None when the study has no sim-only or no real-only rows.
    """
    sim = [r for r in summary if r["arm"] == "sim"]
    real = sorted((r for r in summary if r["arm"] == "real"), key=lambda r: r["shots_per_class"])
    if not sim or not real:
        return {"sim_accuracy_pct": None, "per_class": None, "bound": None,
                "text": "needs the simulation-only point (shots 0) and the real-only arm"}
    a = sim[0]["accuracy_pct_mean"]
    x = [0.0] + [r["shots_per_class"] for r in real]
    y = [None] + [r["accuracy_pct_mean"] for r in real]
    if a <= y[1]:
        return {"sim_accuracy_pct": a, "per_class": None, "bound": "below",
                "text": f"simulation only ({a:.1f} %) is worth less than {x[1]:g} real recording(s) per class "
                        f"({y[1]:.1f} %)"}
    for k in range(1, len(x) - 1):
        if y[k] < a <= y[k + 1]:
            w = x[k] + (a - y[k]) / (y[k + 1] - y[k]) * (x[k + 1] - x[k])
            return {"sim_accuracy_pct": a, "per_class": float(w), "bound": "within",
                    "text": f"simulation only ({a:.1f} %) is worth about {w:.1f} real recordings per class (real only "
                            f"reaches {y[k]:.1f} % with {x[k]:g} and {y[k + 1]:.1f} % with {x[k + 1]:g} per class)"}
    return {"sim_accuracy_pct": a, "per_class": None, "bound": "above",
            "text": f"simulation only ({a:.1f} %) beats real only with every real recording of the training folds "
                    f"({x[-1]:g} per class, {y[-1]:.1f} %)"}


def markdown(summary: list[dict], worth: dict, header: str = "") -> str:
    """The summary as a markdown table (accuracy mean +- std and range, macro F1), with the worth line."""
    lines = [header, ""] if header else []
    lines += ["| arm | real per class | runs | accuracy % mean +- std | min-max | macro F1 % |",
              "|---|---|---|---|---|---|"]
    for r in summary:
        lines.append(f"| {r['arm']} | {r['shots']} ({r['shots_per_class']:g}) | {r['runs']} | "
                     f"{r['accuracy_pct_mean']:.1f} +- {r['accuracy_pct_std']:.1f} | {r['accuracy_pct_min']:.1f}-"
                     f"{r['accuracy_pct_max']:.1f} | {r['macro_f1_pct_mean']:.1f} +- {r['macro_f1_pct_std']:.1f} |")
    return "\n".join(lines + ["", worth["text"] + ".", ""])


def write_report(out: str | Path, rows: list[dict], meta: dict, title: str = "transfer study") -> list[Path]:
    """transfer.csv (the summary), transfer.md, transfer.png and transfer.json (summary, worth, `meta`) in `out`."""
    from processing.atomic import write_text_atomic
    from processing.plots.transfer import plot_transfer

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    summary = summarise(rows)
    worth = simulation_worth(summary)
    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=_FIELDS)
    w.writeheader()
    w.writerows([{k: (round(v, 3) if isinstance(v, float) else v) for k, v in r.items()} for r in summary])
    png = out / "transfer.png"
    plot_transfer(summary, png, title=title)
    return [write_text_atomic(out / "transfer.csv", buf.getvalue()),
            write_text_atomic(out / "transfer.md", markdown(summary, worth, f"# {title}")), png,
            write_text_atomic(out / "transfer.json", json.dumps({"summary": summary, "worth": worth, **meta},
                                                                indent=1, default=str) + "\n")]


__all__ = ["markdown", "simulation_worth", "summarise", "write_report"]
