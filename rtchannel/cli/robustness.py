"""`rtchannel robustness`: accuracy of a trained single-radar classifier on real spectrogram images under
time shifts, pace changes, velocity scaling and noise-floor changes (`processing.classifier.perturb`)."""
from __future__ import annotations

import csv
import io
import time
from pathlib import Path

from rtchannel.cli.common import check_output

# CSV columns before the per-class recalls (fractions; value in s, a factor or dB by kind)
_FIRST = ("perturbation", "kind", "value", "n", "accuracy", "macro_f1", "delta_accuracy")


def _csv(rows: list[dict]) -> str:
    cols = list(_FIRST) + [k for k in rows[0] if k not in _FIRST]
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(cols)
    for r in rows:
        w.writerow(["" if r[c] is None else (f"{r[c]:.6f}" if isinstance(r[c], float) and c != "value" else r[c])
                    for c in cols])
    return buf.getvalue()


_LEGEND = ("truncated: images that keep less than half of their motion power (|v| >= {v} m/s, above the "
           "image's noise floor) inside the image under the perturbation: what left the clip cannot be "
           "recognised. accuracy on intact: the accuracy on the other images.\n")


def _markdown(rows: list[dict]) -> str:
    """Table in %: perturbation, n, accuracy, change against 'none', share of images the perturbation
    truncates and the accuracy on the others, macro F1, recall per class."""
    classes = [k[len("recall_"):] for k in rows[0] if k.startswith("recall_")]
    head = ["perturbation", "n", "accuracy %", "change (points)", "truncated %", "accuracy on intact %",
            "macro F1 %", *(f"{c} recall %" for c in classes)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        d, ai = r["delta_accuracy"], r["accuracy_intact"]
        cells = [r["perturbation"], str(r["n"]), f"{100 * r['accuracy']:.1f}", "" if d is None else f"{100 * d:+.1f}",
                 f"{100 * r['truncated']:.1f}", "" if ai is None else f"{100 * ai:.1f}",
                 f"{100 * r['macro_f1']:.1f}", *(f"{100 * r[f'recall_{c}']:.1f}" for c in classes)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def cmd_robustness(args) -> int:
    from processing.atomic import write_text_atomic
    from processing.classifier.perturb import DEFAULT_GRID, MOTION_V, QUICK_GRID, robustness_grid
    from processing.plots.robustness import plot_robustness
    from rtchannel.cli.classify import _load_model, load_images

    clf = _load_model(args.model)
    out = args.out or args.model.with_name(args.model.stem + "_robustness")
    check_output(out, "dir")
    t0 = time.perf_counter()
    images, _bad, title = load_images(args)
    grid = QUICK_GRID if args.quick else DEFAULT_GRID
    rows = robustness_grid(clf, images, grid, progress=not args.quiet)
    md = _markdown(rows)
    files = [write_text_atomic(out / "robustness.csv", _csv(rows)),
             write_text_atomic(out / "robustness.md", f"# Robustness: {title}\n\n{md}\n{_LEGEND.format(v=MOTION_V)}"),
             plot_robustness(rows, out / "robustness.png", title=title)]
    print(f"{title} ({len(grid)} perturbations, {time.perf_counter() - t0:.1f} s):\n{md}", end="")
    print("wrote " + ", ".join(str(f) for f in files))
    return 0


def add_robustness(sub) -> None:
    """Register the `robustness` subcommand."""
    p = sub.add_parser("robustness", help="accuracy on real images under time shift, pace, velocity and floor "
                       "perturbations", description="Perturb every real image whose activity the model knows "
                       "(time shift, pace stretch about the clip centre, velocity scale, noise-floor change; "
                       "entering columns are the image's own noise floor) and evaluate MODEL on each perturbed "
                       "set. Images that keep less than half of their motion power inside the clip (a fall "
                       "shifted out of it) are counted as truncated, and the accuracy on the others is reported "
                       "apart. Writes robustness.csv, robustness.md (table) and robustness.png (heat map).")
    p.add_argument("--model", required=True, type=Path, help="single-radar checkpoint written by `rtchannel train`")
    p.add_argument("--images", required=True, type=Path, help="a folder of real spectrogram images in the Glasgow "
                   "layout (labels from names like 1P36A01R01.png or --labels)")
    p.add_argument("--labels", type=Path, help="CSV file,activity[,subject] for images whose names are not Glasgow "
                   "names")
    p.add_argument("--people", help="only these subjects, e.g. P36-P45 or P36,P40-P42")
    p.add_argument("--out", type=Path, help="output folder (default MODEL_robustness next to the model)")
    p.add_argument("--quick", action="store_true", help="one value per kind (the strongest) instead of the full "
                   "grid of 18 perturbations")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=cmd_robustness)
