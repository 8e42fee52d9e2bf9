"""Sim-to-real evaluation of a trained classifier on real spectrogram images (one radar per image).

Each image's p(v,t) (read on its pixel grid by `processing.realdata.real_images`) goes through the model's own
`PreprocessConfig` exactly as a simulated signature does (`Classifier.inputs` -> `preprocess_links`):
same velocity grid and crop, same time handling, same dB scale; the noise-aware `valid` mask plays the
role of the simulated signature's `valid`. The image is the model's only link, so the model must have
one branch.

Images of an activity the model does not know (drink, for the five-class seed model) are never counted
in accuracy: they are reported separately as how many were given each predicted class.

Output files (`write_image_evaluation`): confusion.png / confusion.csv (the seed's Fig. 11 layout),
metrics.json (with a report per sub-folder under "by_folder"), metrics_by_folder.csv when the images
lie in several sub-folders, predictions.csv (file: its path relative to the image folder, subject, true,
predicted, one probability column per class) and,
if there are unknown-class images, unknown_predictions.csv (same columns) and unknown_counts.csv (one
row per unknown activity, one column per predicted class).
"""
from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from processing.atomic import write_text_atomic
from processing.classifier.metrics import Report, classification_report, plot_confusion, write_confusion_csv
from processing.realdata.real_images import RealImage, RealImageError


def image_inputs(clf, images: list[RealImage]) -> np.ndarray:
    """Model inputs X [N, 1, V, T] of real images, preprocessed as the model's training data was."""
    if len(clf.links) != 1:
        raise RealImageError(f"an image is one radar but the model has {len(clf.links)} branches "
                             f"({', '.join(clf.links)}): use a single-radar model (train --links radar1)")
    link = clf.links[0]
    samples = [{link: {"p_vt": im.signature.p_vt, "velocity": im.signature.velocity, "time": im.signature.time,
                       "valid": im.signature.valid, "power": im.signature.power}} for im in images]
    return clf.inputs(samples) if samples else np.zeros((0, 1, clf.preprocess.n_velocity, clf.preprocess.n_time),
                                                         np.float32)


@dataclass
class ImageEvaluation:
    """Result of `evaluate_images`. Probabilities [N, n_classes] in the model's class order."""

    classes: list[str]
    report: Report | None  # None when no image is of a known class
    known: list[RealImage]
    known_proba: np.ndarray
    unknown: list[RealImage]
    unknown_proba: np.ndarray
    unreadable: list[tuple[str, str]] = field(default_factory=list)

    def unknown_counts(self) -> dict[str, dict[str, int]]:
        """{unknown activity: {predicted class: count}} (every class listed, zeros included)."""
        out: dict[str, dict[str, int]] = {}
        for im, p in zip(self.unknown, self.unknown_proba):
            row = out.setdefault(im.activity, {c: 0 for c in self.classes})
            row[self.classes[int(p.argmax())]] += 1
        return out

    def by_folder(self) -> dict[str, Report]:
        """{sub-folder of the image folder ('.' for its top): report on its known-class images}."""
        groups: dict[str, list[int]] = {}
        for i, im in enumerate(self.known):
            groups.setdefault(str(Path(im.name).parent), []).append(i)
        out = {}
        for folder, idx in sorted(groups.items()):
            y = np.array([self.classes.index(self.known[i].activity) for i in idx])
            out[folder] = classification_report(y, self.known_proba[idx].argmax(1), self.classes)
        return out

    def summary(self) -> str:
        """Human-readable lines: the report on known classes (and per sub-folder when there are several),
        then the unknown-class predictions."""
        lines = [self.report.summary() if self.report else "no images of a class the model knows"]
        folders = self.by_folder()
        if len(folders) > 1:
            lines += [f"  {f}: n = {r.n}, accuracy = {100 * r.accuracy:.2f} %" for f, r in folders.items()]
        for act, counts in self.unknown_counts().items():
            n = sum(counts.values())
            lines.append(f"  {act} (not a model class, {n} images, not in accuracy) predicted as: "
                         + ", ".join(f"{c} {k}" for c, k in counts.items() if k))
        if self.unreadable:
            n = len(self.unreadable)
            lines.append(f"  {n} image{'s' if n > 1 else ''} skipped, unreadable or with a self-contradicting name "
                         f"(first: {self.unreadable[0][1]})")
        return "\n".join(lines)


def split_seen(clf, images: list[RealImage]) -> tuple[list[RealImage], list[RealImage]]:
    """(unseen, seen): `images` split by whether the model was trained or validated on them, by the sha256 of
    the file against those its checkpoint records (``meta["real_images"]``, written by `train_classifier`
    when real images were training data). A model trained on simulation alone has seen none."""
    from processing.classifier.real_data import file_sha256

    known = {r.get("sha256") for r in (getattr(clf, "meta", None) or {}).get("real_images") or []}
    if not known:
        return list(images), []
    seen = [file_sha256(im.path) in known for im in images]
    return [im for im, s in zip(images, seen) if not s], [im for im, s in zip(images, seen) if s]


def evaluate_images(clf, images: list[RealImage], unreadable=()) -> ImageEvaluation:
    """Predict every image; metrics over the images whose activity is one of the model's classes."""
    known = [im for im in images if im.activity in clf.classes]
    unknown = [im for im in images if im.activity not in clf.classes]
    n_cls = len(clf.classes)
    kp = clf.predict_proba(image_inputs(clf, known)) if known else np.zeros((0, n_cls))
    up = clf.predict_proba(image_inputs(clf, unknown)) if unknown else np.zeros((0, n_cls))
    rep = None
    if known:
        y = np.array([clf.classes.index(im.activity) for im in known])
        rep = classification_report(y, kp.argmax(1), clf.classes)
    return ImageEvaluation(list(clf.classes), rep, known, kp, unknown, up, list(unreadable))


def _prediction_rows(classes, images, proba) -> str:
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(["file", "subject", "true", "predicted", *(f"p_{c}" for c in classes)])
    for im, p in zip(images, proba):
        w.writerow([im.name, "" if im.subject is None else f"P{im.subject}", im.activity, classes[int(p.argmax())],
                    *(f"{x:.6f}" for x in p)])
    return buf.getvalue()


def write_image_evaluation(ev: ImageEvaluation, out_dir: str | Path, title: str, extra: dict | None = None
                           ) -> list[Path]:
    """Write the evaluation files (see the module docstring) into `out_dir`; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    if ev.report is not None:
        files += [plot_confusion(ev.report, out / "confusion.png", title=None),
                  write_confusion_csv(ev.report, out / "confusion.csv")]
    files.append(write_text_atomic(out / "predictions.csv", _prediction_rows(ev.classes, ev.known, ev.known_proba)))
    counts = ev.unknown_counts()
    if ev.unknown:
        files.append(write_text_atomic(out / "unknown_predictions.csv",
                                       _prediction_rows(ev.classes, ev.unknown, ev.unknown_proba)))
        buf = io.StringIO(newline="")
        w = csv.writer(buf)
        w.writerow(["true \\ predicted", *ev.classes, "n"])
        for act, row in counts.items():
            w.writerow([act, *row.values(), sum(row.values())])
        files.append(write_text_atomic(out / "unknown_counts.csv", buf.getvalue()))
    folders = ev.by_folder()
    if len(folders) > 1:
        buf = io.StringIO(newline="")
        w = csv.writer(buf)
        w.writerow(["folder", "n", "accuracy", "macro_f1"])
        for f, r in folders.items():
            w.writerow([f, r.n, f"{r.accuracy:.6f}", f"{r.macro_f1:.6f}"])
        files.append(write_text_atomic(out / "metrics_by_folder.csv", buf.getvalue()))
    doc = {"title": title, **(ev.report.as_dict() if ev.report else {"n": 0}),
           "by_folder": {f: r.as_dict() for f, r in folders.items()},
           "unknown_classes": {a: {"n": sum(r.values()), "predicted": r} for a, r in counts.items()},
           "n_unknown": len(ev.unknown), "unreadable": [{"file": n, "error": e} for n, e in ev.unreadable],
           **(extra or {})}
    files.append(write_text_atomic(out / "metrics.json", json.dumps(doc, indent=1) + "\n"))
    return files
