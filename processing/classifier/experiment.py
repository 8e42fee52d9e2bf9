"""Training, evaluation and cross-validation of the activity classifier on datasets, as library functions.

The commands `rtchannel train`, `evaluate` and `crossval` are argument parsing and printing around these;
the same runs from Python (exported by `rtchannel`)::

    training = train_classifier("out/seed", links=["radar1", "radar2"])           # or several datasets
    training.save("out/model.pt")                                                 # checkpoint, curves, confusion
    tuned = train_classifier(["out/glasgow", "out/extra"], init="out/model.pt")   # start from its weights
    evaluation = evaluate_classifier(tuned.classifier, "out/other:direction=1")
    evaluation.save("out/eval")                                                   # confusion, metrics, predictions

Datasets are named by specs of the query language (`processing.io.dataset_query`: ``DIR[:key=v1|v2,...]``);
several specs are loaded one after another into one training set. Training calls
`processing.classifier.training.train` (split, early stopping, determinism), so a loop of calls from
Python gives what the command gives, seed for seed. User errors (a spec selecting nothing, a missing link,
data that cannot be split, a checkpoint of another architecture) are `InputError`s with one line.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from processing.classifier.dataset_loading import DEFAULT_LINKS, Dataset, load_dataset
from processing.classifier.metrics import Report, classification_report
from processing.classifier.model import ModelConfig
from processing.classifier.predictor import Classifier
from processing.classifier.preprocess import PreprocessConfig
from processing.classifier.training import TrainConfig, TrainResult, train
from processing.errors import InputError
from processing.labels import ACTIVITIES


@dataclass
class Training:
    """A trained classifier and how it was made (`train_classifier`'s result).

    Attributes:
        classifier: the trained `Classifier` (network, preprocessing, classes, links).
        result: `TrainResult` (history, split indices, best epoch, seconds).
        validation: `Report` on the held-out validation split.
        meta: what is stored with the checkpoint (specs, split sizes, train config, DSP settings, ...).
    """

    classifier: Classifier
    result: TrainResult
    validation: Report
    meta: dict = field(default_factory=dict)

    def __repr__(self) -> str:
        r = self.result
        return (f"<Training on {self.meta.get('train_spec', '?')!r}: {r.train_idx.size} train / {r.val_idx.size} "
                f"validation items, best epoch {r.best_epoch} of {len(r.history.get('train_loss', []))}, validation "
                f"accuracy {100 * self.validation.accuracy:.1f} %, {r.seconds:.1f} s>")

    def save(self, path: str | Path) -> list[Path]:
        """Write the checkpoint `path` (.pt) and beside it STEM_curves.png, STEM_val_confusion.png and
        STEM_val_confusion.csv; returns the paths written.

        Args:
            path: the checkpoint file.
        """
        from processing.classifier.checkpoint import save_checkpoint
        from processing.classifier.metrics import plot_confusion, write_confusion_csv
        from processing.plots.classifier import plot_history

        path = Path(path)
        stem = path.with_suffix("")
        save_checkpoint(path, self.classifier, history=self.result.history, extra=self.meta)
        return [path, plot_history(self.result.history, f"{stem}_curves.png", self.result.best_epoch,
                                   title=f"training history ({self.meta.get('train_spec', '')})"),
                plot_confusion(self.validation, f"{stem}_val_confusion.png"),
                write_confusion_csv(self.validation, f"{stem}_val_confusion.csv")]


def _init_classifier(init) -> Classifier | None:
    """The `Classifier` training starts from (`init`: a Classifier or a checkpoint path), never an ensemble."""
    if init is None:
        return None
    from processing.classifier.ensemble import SoftVote

    clf = init
    if not isinstance(init, Classifier):
        from processing.classifier.checkpoint import load_checkpoint

        clf = load_checkpoint(init)
    if isinstance(clf.model, SoftVote):
        raise InputError("init: an ensemble cannot initialise training; give one of its member checkpoints")
    return clf


def _differences(given, kept) -> list[str]:
    """'field given (checkpoint: kept)' for every field in which two settings models differ."""
    a, b = given.model_dump(), kept.model_dump()
    return [f"{k} {a[k]!r} (checkpoint: {b.get(k)!r})" for k in a if a[k] != b.get(k)]


def _initial_settings(clf: Classifier, links, preprocess, model_cfg):
    """(links, preprocessing, network) of a training from `clf`: the checkpoint's, refusing any given that differ
    (fine-tuning must see its inputs as the checkpoint's training did)."""
    if links is not None and list(links) != list(clf.links):
        raise InputError(f"init: the checkpoint's network has links {list(clf.links)}, not {list(links)}")
    if preprocess is not None and preprocess != clf.preprocess:
        raise InputError("init: the preprocessing differs from the checkpoint's: "
                         + "; ".join(_differences(preprocess, clf.preprocess)[:3]))
    net_cfg = clf.model.cfg
    assert isinstance(net_cfg, ModelConfig)  # every checkpoint's network is a MultiPerspectiveDCNN
    if model_cfg is not None and model_cfg != net_cfg:
        raise InputError(f"init: the checkpoint's network ({net_cfg.n_branches} links {clf.links}, input "
                         f"{tuple(net_cfg.input_size)}) differs from the one to train: "
                         + "; ".join(_differences(model_cfg, net_cfg)[:3]))
    return list(clf.links), clf.preprocess, net_cfg


def train_classifier(data, *, links=None, preprocess: PreprocessConfig | None = None,
                     model: ModelConfig | None = None, train_config: TrainConfig | None = None, init=None,
                     weights=None, labels: dict | str | Path | None = None, cache: bool = True,
                     progress: bool = False, log=None) -> Training:
    """Train the seed's multiperspective DCNN on one or several datasets.

    Args:
        data: a dataset spec ``DIR[:FILTER]``, a spec of real labelled images ``images:DIR[:FILTER]``, a sequence
            of them (loaded into one training set), or a `Dataset` from `load_dataset`.
        links: radar links, one network branch each (one link: the single-radar variant); default
            ``DEFAULT_LINKS``, or the checkpoint's with `init`.
        preprocess: input preprocessing (default `PreprocessConfig()`: 64 x 64, active span, dB; with `init` the
            checkpoint's, and a different one is refused).
        model: network settings (default: the seed's DCNN for `links` at the preprocessing's size; with `init`
            the checkpoint's, and a different one is refused).
        train_config: optimisation, split and augmentation settings (default `TrainConfig()`).
        init: start from these weights instead of a random initialisation: a `Classifier` or a checkpoint
            path (fine-tuning, transfer learning).
        weights: one weight >= 0 per spec of `data`: the share of the training draws each dataset supplies
            (mixed batches; `training.train`'s source_weights). None: one pass over all items per epoch.
        labels: labels of ``images:`` specs whose names are not Glasgow names (`load_dataset`).
        cache: use the on-disk cache of preprocessed inputs (`load_dataset`).
        progress: show progress bars.
        log: callable receiving progress lines (default: none).

    Returns:
        `Training` (save it with `Training.save(path)`). Its meta lists every real image the training (and the
        checkpoint it started from) used, as ``real_images`` [{file, sha256, folder, role}], so that an
        evaluation on real images can leave them out.
    """
    from processing.classifier.real_data import seen_images

    start = _init_classifier(init)
    if start is not None:
        links, pre, mcfg = _initial_settings(start, links, preprocess, model)
    else:
        links = list(DEFAULT_LINKS if links is None else links)
        pre = PreprocessConfig() if preprocess is None else preprocess
        mcfg = model if model is not None else ModelConfig(n_classes=len(ACTIVITIES), n_branches=len(links),
                                                           input_size=(pre.n_velocity, pre.n_time))
    tcfg = TrainConfig() if train_config is None else train_config
    state = None if start is None else {k: v.detach().clone() for k, v in start.model.state_dict().items()}
    ds = data if isinstance(data, Dataset) else load_dataset(data, links, pre, progress=progress, labels=labels,
                                                                     cache=cache)
    n_specs = 1 if ds.sources is None else int(ds.sources.max()) + 1
    if weights is not None and len(weights) != n_specs:
        raise InputError(f"give one weight per dataset: {n_specs} dataset(s), {len(weights)} weight(s)")
    if log:
        counts = ", ".join(f"{ACTIVITIES[k]}={n}" for k, n in zip(*np.unique(ds.y, return_counts=True)))
        log(f"{len(ds.y)} items from {ds.spec} ({counts}); loaded in {ds.seconds:.1f} s"
            + "".join(f"; {n} image(s) left out ({why})" for why, n in ds.left_out.items()))
    deployments = None
    if tcfg.val_split == "deployment":  # validation on held-out motion sources and deployment regions
        from processing.classifier.splits import deployment_factors

        deployments = deployment_factors(ds.entries)
    res = train(ds.x, ds.y, mcfg, tcfg, groups=ds.groups, progress=progress, log=log or None, preprocess=pre,
                init_state=state, deployments=deployments, sources=ds.sources,
                source_weights=None if weights is None else [float(w) for w in weights])
    clf = Classifier(model=res.model, preprocess=pre, classes=list(ACTIVITIES), links=links)
    va = res.val_idx
    rep = classification_report(ds.y[va], clf.predict(ds.x[va]), ACTIVITIES)
    meta = {"train_spec": ds.spec, "n_train": int(res.train_idx.size), "n_val": int(va.size),
            "best_epoch": res.best_epoch, "train_seconds": res.seconds, "load_seconds": ds.seconds,
            "train_config": tcfg.model_dump(mode="json"), "val_items": [ds.names[i] for i in va],
            "val_accuracy": rep.accuracy, "init": _describe_init(init), "holdout": res.extra.get("holdout"),
            "averaged": res.extra.get("averaged"), "weights": None if weights is None else [float(w) for w in weights],
            "real_images": seen_images(ds.entries, res.train_idx, va)
            + list((start.meta.get("real_images") or []) if start is not None else [])}
    # the DSP settings of the simulated training data, so that `evaluate --recordings` processes real IQ the same way
    dsps = {json.dumps(e.get("params", {}).get("radar", {}).get("dsp"), sort_keys=True) for e in ds.entries
            if e.get("source") != "real"}
    meta["dsp"] = json.loads(dsps.pop()) if len(dsps) == 1 else None
    if log:
        log(f"trained in {res.seconds:.1f} s ({len(res.history['train_loss'])} epochs, best {res.best_epoch}); "
            f"validation ({va.size} items):\n{rep.summary()}")
    return Training(classifier=clf, result=res, validation=rep, meta=meta)


def _describe_init(init) -> str | None:
    """What training started from, for the checkpoint's meta: a path, or a Classifier's training data."""
    if init is None or not isinstance(init, Classifier):
        return None if init is None else str(init)
    return f"a Classifier trained on {init.meta.get('train_spec', '?')}"


@dataclass
class Evaluation:
    """A classifier's predictions on labelled inputs (`evaluate_classifier`'s result).

    Attributes:
        report: accuracy, per-class precision/recall/F1, macro F1, confusion matrix.
        y: true labels [N] (indices into `classes`).
        proba: class probabilities [N, n_classes].
        names: item names [N].
        title: what was evaluated on what.
    """

    report: Report
    y: np.ndarray
    proba: np.ndarray
    names: list[str]
    title: str = ""

    def __repr__(self) -> str:
        return (f"<Evaluation {self.title!r}: {self.report.n} items, accuracy {100 * self.report.accuracy:.1f} %, "
                f"macro F1 {100 * self.report.macro_f1:.1f} %>")

    def save(self, out_dir: str | Path) -> list[Path]:
        """confusion.png, confusion.csv, metrics.json and predictions.csv into `out_dir` (created).

        Args:
            out_dir: the folder.
        """
        from processing.atomic import write_text_atomic
        from processing.classifier.metrics import plot_confusion, write_confusion_csv

        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        classes, pred = self.report.classes, self.proba.argmax(1)
        rows = ["name,true,predicted,confidence"] + [
            f"{self.names[i]},{classes[self.y[i]]},{classes[pred[i]]},{self.proba[i, pred[i]]:.4f}"
            for i in range(len(self.y))]
        metrics = json.dumps({"title": self.title, **self.report.as_dict()}, indent=1)
        return [plot_confusion(self.report, out / "confusion.png"),
                write_confusion_csv(self.report, out / "confusion.csv"),
                write_text_atomic(out / "metrics.json", metrics),
                write_text_atomic(out / "predictions.csv", "\n".join(rows) + "\n")]


def evaluate_classifier(model, data, *, names=None, title: str | None = None, progress: bool = False) -> Evaluation:
    """Predict and score a classifier on labelled data.

    Args:
        model: a `Classifier` or a checkpoint path.
        data: a dataset spec or a sequence of them (loaded with the model's links and preprocessing), a
            `Dataset`, or (x [N, n_links, V, T] float32, y [N]) arrays already preprocessed for the model.
        names: item names [N] for arrays (default their index).
        title: shown and stored (default: the model and the data).
        progress: show a progress bar while loading.

    Returns:
        `Evaluation` (write it with `Evaluation.save(out_dir)`).
    """
    clf = model
    if not hasattr(model, "predict_proba"):  # a path; anything that predicts (a Classifier) is used as it is
        from processing.classifier.checkpoint import load_checkpoint

        clf = load_checkpoint(model)
    if isinstance(data, tuple):
        x, y = np.asarray(data[0]), np.asarray(data[1])
        names = [str(i) for i in range(len(y))] if names is None else list(names)
        what = "arrays"
    else:
        ds = data if isinstance(data, Dataset) else load_dataset(data, clf.links, clf.preprocess, progress=progress)
        x, y, names, what = ds.x, ds.y, ds.names, ds.spec
    proba = clf.predict_proba(x)
    rep = classification_report(y, proba.argmax(1), clf.classes)
    if title is None:
        title = f"{Path(model).name if clf is not model else 'the model'} on {what}"
    return Evaluation(report=rep, y=np.asarray(y), proba=proba, names=list(names), title=title)


def crossval_experiments(doc, where: str = "crossval plan") -> list[dict]:
    """The experiments of a parsed cross-validation plan (``{experiments: [{name, train: SPEC, test: [SPEC, ...]}]}``).

    Args:
        doc: the plan's parsed mapping (e.g. from YAML).
        where: how errors name the plan (its file).

    Returns:
        [{"name", "train", "test": [spec, ...]}]; InputError (one line, never quoting the file) when the structure
        is wrong, a spec is not text, or a name is not a distinct file-name-safe word (it names a model file).
    """
    import re

    exps = doc.get("experiments") if isinstance(doc, dict) else None
    if not isinstance(exps, list) or not exps:
        raise InputError(f"{where}: needs a list 'experiments' of {{name, train, test}}")
    plan = []
    for k, e in enumerate(exps):
        if not isinstance(e, dict) or "train" not in e or "test" not in e:
            raise InputError(f"{where}: experiment {k + 1} needs 'train' and 'test' specs")
        tests = e["test"] if isinstance(e["test"], list) else [e["test"]]
        name = e.get("name", f"exp{k + 1}")
        # the name becomes part of a model file's name beside --out: no path, no duplicate
        if not (isinstance(name, (str, int)) and re.fullmatch(r"[A-Za-z0-9_\-]{1,64}", str(name))):
            raise InputError(f"{where}: experiment {k + 1}: name must be 1-64 letters, digits, _ or -")
        if not all(isinstance(x, str) and x for x in [e["train"], *tests]):
            raise InputError(f"{where}: experiment {k + 1}: train and test are dataset specs (text)")
        plan.append({"name": str(name), "train": e["train"], "test": list(tests)})
    names = [p["name"] for p in plan]
    if len(set(names)) != len(names):
        raise InputError(f"{where}: experiment names must be distinct (each names a model file)")
    return plan


@dataclass
class CrossValidation:
    """One row per (experiment, test spec), and each experiment's `Training`.

    Attributes:
        rows: [{"experiment", "train", "test", "n_train", "n_test", "accuracy_pct", "macro_f1_pct", "train_s",
            "note"}].
        trainings: {experiment name: Training}.
    """

    rows: list[dict]
    trainings: dict[str, Training]

    def __repr__(self) -> str:
        return f"<CrossValidation: {len(self.trainings)} trainings, {len(self.rows)} tests>"

    def markdown(self) -> str:
        """The rows as a markdown table."""
        md = ["| " + " | ".join(self.rows[0]) + " |", "|" + "---|" * len(self.rows[0])]
        return "\n".join(md + ["| " + " | ".join(str(v) for v in r.values()) + " |" for r in self.rows])

    def save(self, path: str | Path) -> list[Path]:
        """The table as CSV at `path` (.csv) and markdown beside it (.md), and every experiment's model as
        STEM_NAME.pt (with its curves and validation confusion, `Training.save`); returns the paths written.

        Args:
            path: the CSV file.
        """
        import csv
        import io

        from processing.atomic import write_text_atomic

        path = Path(path)
        out = [p for name, t in self.trainings.items() for p in t.save(path.with_name(f"{path.stem}_{name}.pt"))]
        buf = io.StringIO(newline="")
        w = csv.DictWriter(buf, fieldnames=list(self.rows[0]))
        w.writeheader()
        w.writerows(self.rows)
        return out + [write_text_atomic(path, buf.getvalue()),
                      write_text_atomic(path.with_suffix(".md"), self.markdown() + "\n")]


def crossvalidate(experiments, *, links=DEFAULT_LINKS, preprocess: PreprocessConfig | None = None,
                  model: ModelConfig | None = None, train_config: TrainConfig | None = None, progress: bool = False,
                  log=None) -> CrossValidation:
    """Train on each experiment's training spec and test on each of its test specs (a test equal to the
    training spec uses the held-out validation split).

    Args:
        experiments: [{"name", "train": spec, "test": [spec, ...]}] (e.g. `crossval_experiments` of a plan
            file, `rtchannel.read_crossval_plan`).
        links, preprocess, model, train_config: as `train_classifier`.
        progress: show progress bars.
        log: callable receiving progress lines (default: none).

    Returns:
        `CrossValidation` (write it with `CrossValidation.save(path)`).
    """
    rows, trainings = [], {}
    for exp in experiments:
        t = train_classifier(exp["train"], links=links, preprocess=preprocess, model=model, train_config=train_config,
                             progress=progress, log=log)
        trainings[exp["name"]] = t
        for test in exp["test"]:
            if test == exp["train"]:
                rep, note = t.validation, "held-out validation split"
            else:
                ev = evaluate_classifier(t.classifier, test, title=f"{exp['name']} -> {test}", progress=progress)
                rep, note = ev.report, ""
                if log:
                    log(f"{ev.title}:\n{rep.summary()}")
            rows.append({"experiment": exp["name"], "train": exp["train"], "test": test,
                         "n_train": int(t.result.train_idx.size), "n_test": rep.n,
                         "accuracy_pct": round(100 * rep.accuracy, 2), "macro_f1_pct": round(100 * rep.macro_f1, 2),
                         "train_s": round(t.result.seconds, 1), "note": note})
    return CrossValidation(rows=rows, trainings=trainings)


__all__ = ["CrossValidation", "DEFAULT_LINKS", "Dataset", "Evaluation", "Training", "crossvalidate",
           "crossval_experiments", "evaluate_classifier", "load_dataset", "train_classifier"]
