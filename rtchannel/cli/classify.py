"""`rtchannel train / evaluate / crossval`: the multiperspective DCNN activity classifier on datasets and recordings.

Datasets are named by specs of the query language in `processing.io.dataset_query` (``DIR[:key=v1|v2,...]``).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from rtchannel.cli.common import check_output, output_file, positive_int, seed_int

# the dataset query language lives in the library (usable from the API); re-exported for the commands
from processing.io.dataset_query import open_spec, parse_spec, select  # noqa: E402,F401


def _user_error():
    from rtchannel.cli.common import UserError

    return UserError


# Defaults of the preprocessing and network options. Their argparse default is None, so that `train --init` can
# tell an option the user gave (which must then equal the checkpoint's) from one left at its default.
_PRE_NET_DEFAULTS = {"size": (64, 64), "v_range": 6.2, "time_mode": "active", "window_s": 6.0, "scale": "db",
                     "floor_db": 40.0, "intensity": "p", "kernel": 3, "padding": "valid", "fusion": "concat",
                     "shared_weights": False, "links": "radar1,radar2", "time_pool": "none", "no_batch_norm": False}


def _opt(args, dest: str):
    """The value of a preprocessing/network option: given, or its default."""
    value = getattr(args, dest, None)
    return _PRE_NET_DEFAULTS[dest] if value is None else value


def _add_preprocess_model_args(p) -> None:
    g = p.add_argument_group("input preprocessing (stored in the model)")
    g.add_argument("--size", type=int, nargs=2, metavar=("V", "T"),
                   help="input image: velocity bins, time bins (default 64 64)")
    g.add_argument("--v-range", type=float, help="input velocity span +-V m/s (default 6.2; 0: "
                   "keep the recorded bins)")
    g.add_argument("--time-mode", choices=("resample", "window", "active"),
                   help="the active span only, idle standing before/after cropped (default), the whole "
                   "recording, or a fixed window around the motion")
    g.add_argument("--window-s", type=float, help="window length for --time-mode window [s] (default 6)")
    g.add_argument("--scale", choices=("db", "linear"), help="intensity scale (default db)")
    g.add_argument("--floor-db", type=float, help="dynamic range kept in dB (default 40)")
    g.add_argument("--intensity", choices=("p", "power"), help="p: the column-normalised p(v,t) "
                   "(seed eq. 7, default); power: the spectrogram p(v,t) x column power (seed eq. 6), one scale per "
                   "sample, so quiet columns stay dark")
    g = p.add_argument_group("network")
    g.add_argument("--kernel", type=int, choices=(3, 4), help="conv kernel size (seed: 3 or 4; default 3)")
    g.add_argument("--padding", choices=("valid", "same"), help="default valid")
    g.add_argument("--fusion", choices=("concat", "sum", "max", "mean"), help="default concat")
    g.add_argument("--shared-weights", action="store_true", default=None, help="one FEN for every radar")
    g.add_argument("--links", help="links (one FEN each), comma-separated; one link "
                   "gives the single-radar variant (default radar1,radar2)")
    g.add_argument("--time-pool", choices=("none", "max", "mean"),
                   help="pool each FEN's last feature map over time before flattening, so where an activity "
                   "sits in the clip matters less (default none: the seed's flatten)")
    g = p.add_argument_group("training")
    g.add_argument("--epochs", type=int, default=40, help="maximum epochs (default 40)")
    g.add_argument("--patience", type=int, default=6, help="early-stopping patience in epochs (default 6)")
    g.add_argument("--batch-size", type=int, default=32)
    g.add_argument("--lr", type=float, default=1e-3, help="Adam learning rate (default 1e-3)")
    g.add_argument("--val-fraction", type=float, default=0.2, help="validation share (default 0.2)")
    g.add_argument("--no-group-split", action="store_true",
                   help="split items freely (default: all copies of one motion source on one side)")
    g.add_argument("--val-split", choices=("groups", "deployment"), default="groups",
                   help="groups: validate on held-out motion sources (default); deployment: also on held-out tails "
                   "of the simulated deployments (radar distance, height, tilt, beam, room, body, takes), none of "
                   "which reach training, so early stopping picks what extrapolates (see processing.classifier."
                   "splits)")
    g.add_argument("--holdout-factors", type=int, default=2, help="--val-split deployment: deployment factors "
                   "with a held-out tail, drawn from the seed (default 2)")
    g.add_argument("--average", choices=("none", "window"), default="none",
                   help="window: keep the mean of the weights of the epochs around the best one whose validation "
                   "loss is within --average-tolerance of it (flat-minimum weight averaging), BatchNorm statistics "
                   "re-estimated (default none: the best epoch's weights)")
    g.add_argument("--average-tolerance", type=float, default=0.2, help="--average window: relative validation-loss "
                   "excess an averaged epoch may have (default 0.2)")
    g.add_argument("--holdout-tail", type=float, default=0.125, help="--val-split deployment: share of items in "
                   "each held-out tail (default 0.125)")
    g.add_argument("--seed", type=seed_int, default=0)
    g.add_argument("--threads", type=positive_int,
                   help="CPU threads torch uses while training (intra-op parallelism of its convolutions and "
                   "matrix products; numpy/BLAS, the DSP and the data loading are not affected). "
                   "Default 1: weights are reproducible only at a fixed thread count (1 and 2 differ)")
    g.add_argument("--no-batch-norm", action="store_true", default=None, help="the literal seed FEN without "
                   "BatchNorm")
    g.add_argument("--feature-lr-scale", type=float, default=1.0, help="learning rate of the convolutional feature "
                   "networks relative to --lr: < 1 a lower one (discriminative fine-tuning), 0 frozen (default 1)")
    g.add_argument("--epoch-samples", type=positive_int, help="items drawn per epoch when datasets are weighted "
                   "(--data-weights; default: the training set's size)")
    g.add_argument("--no-cache", action="store_true", help="preprocess the datasets again instead of reading the "
                   "cached inputs (processing.classifier.array_cache; the same arrays either way)")
    g = p.add_argument_group("augmentation of training batches (recorded in the model's train_config)")
    g.add_argument("--augment", nargs="?", const="all", choices=("all", "scale"),
                   help="all (the default when given without a value): random time shift (+-1 s), time stretch "
                   "(x0.75-1.33), velocity scale (x0.8-1.25), dB jitter (floor +-5 dB, offset +-2 dB) and receiver "
                   "noise (-40..-20 dB re the peak), each applied with probability 0.5; scale: the time stretch and "
                   "velocity scale only. Any --aug-* option implies it and overrides the set's value")
    g.add_argument("--aug-shift-s", type=float, metavar="S", help="maximum time shift either way [s] (default 1; "
                   "time modes resample/active: an image taken as 6 s wide, see --aug-width-s; 0: no shift)")
    g.add_argument("--aug-width-s", type=float, metavar="S", help="seconds an image of time mode resample/active "
                   "is taken to span when converting --aug-shift-s to columns (default 6)")
    g.add_argument("--aug-stretch", type=float, nargs=2, metavar=("LO", "HI"),
                   help="time stretch factor range, >1 slower (default 0.75 1.333; 1 1: none)")
    g.add_argument("--aug-vscale", type=float, nargs=2, metavar=("LO", "HI"),
                   help="velocity scale factor range about 0 m/s (default 0.8 1.25; 1 1: none)")
    g.add_argument("--aug-db", type=float, metavar="DB", help="the dB floor moved by up to +-DB [dB] "
                   "(default 5; must be below --floor-db)")
    g.add_argument("--aug-db-offset", type=float, metavar="DB", help="every pixel offset by up to +-DB [dB], "
                   "then clipped (default 2)")
    g.add_argument("--aug-p", type=float, metavar="P", help="probability of each transform per sample (default 0.5)")
    g.add_argument("--aug-noise-db", nargs="+", metavar="DB", help="receiver-noise level range LO HI "
                   "[dB re the peak pixel], exponential speckle per pixel (default -40 -20), or 'off'")
    p.add_argument("--quiet", action="store_true", help="no progress bars")


_AUG_ARGS = {"aug_shift_s": "shift_s", "aug_width_s": "nominal_width_s", "aug_stretch": "stretch",
             "aug_vscale": "vscale", "aug_db": "db_floor", "aug_db_offset": "db_offset", "aug_p": "p",
             "aug_noise_db": "noise_db"}


def _noise_range(values: list[str]) -> tuple[float, float] | None:
    """--aug-noise-db: 'off' -> None, two numbers -> (lo, hi) dB."""
    if [v.lower() for v in values] == ["off"]:
        return None
    try:
        lo, hi = (float(v) for v in values)
    except ValueError:
        raise _user_error()(f"--aug-noise-db takes two numbers (dB) or 'off', got {' '.join(values)}") from None
    return lo, hi


def _augment_config(args):
    from pydantic import ValidationError

    from processing.classifier.augment import PRESETS, AugmentConfig

    given = {f: getattr(args, a) for a, f in _AUG_ARGS.items() if getattr(args, a, None) is not None}
    if "noise_db" in given:
        given["noise_db"] = _noise_range(given["noise_db"])
    preset = getattr(args, "augment", None)
    if not given and not preset:
        return AugmentConfig()
    fields = {**PRESETS[preset or "all"], **{f: tuple(v) if isinstance(v, list) else v for f, v in given.items()}}
    try:
        return AugmentConfig(on=True, **fields)
    except ValidationError as e:
        err = e.errors()[0]
        name = next((a for a, f in _AUG_ARGS.items() if f in err.get("loc", ())), "augment")
        raise _user_error()(f"--{name.replace('_', '-')}: {err.get('msg', 'invalid')}") from None


def _configs(args):
    from processing.classifier import ModelConfig, PreprocessConfig, TrainConfig
    from processing.io.dataset_store import ACTIVITIES

    links = [s.strip() for s in _opt(args, "links").split(",") if s.strip()]
    size = tuple(_opt(args, "size"))
    pre = PreprocessConfig(n_velocity=size[0], n_time=size[1], v_range_mps=_opt(args, "v_range") or None,
                           time_mode=_opt(args, "time_mode"), window_s=_opt(args, "window_s"),
                           scale=_opt(args, "scale"), floor_db=_opt(args, "floor_db"),
                           intensity=_opt(args, "intensity"))
    model = ModelConfig(n_classes=len(ACTIVITIES), n_branches=len(links), input_size=size,
                        kernel_size=_opt(args, "kernel"), padding=_opt(args, "padding"), fusion=_opt(args, "fusion"),
                        shared_weights=_opt(args, "shared_weights"), batch_norm=not _opt(args, "no_batch_norm"),
                        time_pool=_opt(args, "time_pool"))
    tc = TrainConfig(epochs=args.epochs, batch_size=args.batch_size, lr=args.lr, patience=args.patience,
                     val_fraction=args.val_fraction, group_split=not args.no_group_split, seed=args.seed,
                     threads=args.threads, augment=_augment_config(args), val_split=args.val_split,
                     holdout_factors=args.holdout_factors, holdout_tail=args.holdout_tail, average=args.average,
                     average_tolerance=args.average_tolerance, feature_lr_scale=args.feature_lr_scale,
                     epoch_samples=args.epoch_samples)
    if tc.augment.enabled and tc.augment.db_floor >= pre.floor_db:
        raise _user_error()(f"--aug-db {tc.augment.db_floor:g} must be below --floor-db {pre.floor_db:g}")
    return links, pre, model, tc


# option -> (settings model, fields) it sets, for comparing given options with an --init checkpoint
_OPTION_FIELDS = {"size": ("pre", ("n_velocity", "n_time")), "v_range": ("pre", ("v_range_mps",)),
                  "time_mode": ("pre", ("time_mode",)), "window_s": ("pre", ("window_s",)),
                  "scale": ("pre", ("scale",)), "floor_db": ("pre", ("floor_db",)),
                  "intensity": ("pre", ("intensity",)),
                  "kernel": ("net", ("kernel_size",)), "padding": ("net", ("padding",)), "fusion": ("net", ("fusion",)),
                  "shared_weights": ("net", ("shared_weights",)), "time_pool": ("net", ("time_pool",)),
                  "no_batch_norm": ("net", ("batch_norm",)), "links": ("links", ())}


def _check_init_options(args, clf, links, pre, mcfg) -> None:
    """Refuse a preprocessing or network option given together with --init whose value differs from the
    checkpoint's (the options left out take the checkpoint's values)."""
    for dest, (kind, fields) in _OPTION_FIELDS.items():
        if getattr(args, dest, None) is None:
            continue
        given, kept = {"pre": (pre, clf.preprocess), "net": (mcfg, clf.model.cfg)}.get(kind, (None, None))
        if kind == "links":
            same, want, have = list(links) == list(clf.links), ",".join(links), ",".join(clf.links)
        else:
            want = " ".join(str(getattr(given, f)) for f in fields)
            have = " ".join(str(getattr(kept, f)) for f in fields)
            same = all(getattr(given, f) == getattr(kept, f) for f in fields)
        if not same:
            raise _user_error()(f"--{dest.replace('_', '-')} {want} differs from the --init checkpoint's {have}: "
                                "fine-tuning keeps the checkpoint's preprocessing and network (leave the option out)")


def train_spec(spec, args, out: Path, log=print):
    """Train on a dataset spec or a list of them (`train_classifier`; with --init from a checkpoint, with
    --data-weights mixed) and write the checkpoint, curves and validation confusion next to `out`
    (`Training.save`); returns the `Training`."""
    from processing.classifier.experiment import train_classifier

    links, pre, mcfg, tcfg = _configs(args)
    init = getattr(args, "init", None)
    if init is not None:
        _check_init_options(args, _load_model(init), links, pre, mcfg)
        links = pre = mcfg = None  # the checkpoint's
    specs = spec if isinstance(spec, (list, tuple)) else [spec]
    training = train_classifier(specs if len(specs) > 1 else specs[0], links=links, preprocess=pre, model=mcfg,
                                train_config=tcfg, init=init, weights=getattr(args, "data_weights", None),
                                labels=getattr(args, "labels", None), cache=not args.no_cache,
                                progress=not args.quiet, log=log)
    training.save(out)
    return training


def cmd_train(args) -> int:
    args.out = output_file(args.out, ".pt")
    check_output(args.out, "file")
    if args.data_weights is not None and len(args.data_weights) != len(args.data):
        raise _user_error()(f"--data-weights: give one weight per --data ({len(args.data)}), got "
                            f"{len(args.data_weights)}")
    training = train_spec(args.data, args, args.out)
    stem = args.out.with_suffix("")
    n_real = len(training.meta.get("real_images") or [])
    if n_real:
        print(f"the model saw {n_real} real image(s) in training and validation; the checkpoint lists them (sha256), "
              "and `evaluate --images` leaves them out")
    print(f"wrote {args.out}, {stem}_curves.png, {stem}_val_confusion.png, {stem}_val_confusion.csv")
    return 0


def _load_model(path: Path):
    from processing.classifier import load_checkpoint

    try:
        return load_checkpoint(path)
    except (FileNotFoundError, ValueError) as e:
        raise _user_error()(str(e)) from None


def evaluate_arrays(clf, x, y, out_dir: Path | None, title: str, names=None, log=print):
    """Predict, report and (if `out_dir`) write confusion PNG/CSV, metrics.json and predictions.csv
    (`evaluate_classifier`, `Evaluation.save`); returns the `Report`."""
    from processing.classifier.experiment import evaluate_classifier

    ev = evaluate_classifier(clf, (x, y), names=names, title=title)
    if out_dir is not None:
        ev.save(out_dir)
    log(f"{title}:\n{ev.report.summary()}")
    return ev.report


def _recording_inputs(clf, args):
    from processing.realdata.ancortek import label_from_name, recording_samples

    src = args.recordings
    if src.is_dir():
        paths = sorted(p for p in src.rglob("*") if p.suffix.lower() == ".dat")
    elif src.is_file():
        paths = [src]
    else:
        raise _user_error()(f"recordings not found: {src}")
    if not paths:
        raise _user_error()(f"no .dat files in {src}")
    if args.label is not None and args.label not in clf.classes:
        raise _user_error()(f"--label must be one of {', '.join(clf.classes)}")
    try:
        samples = recording_samples(paths, clf.links, dsp=clf.meta.get("dsp"), n_channels=args.channels,
                                    conjugate=args.conjugate, allow_partial=args.allow_partial)
    except ValueError as e:
        raise _user_error()(str(e)) from None
    names, y, keep = [], [], []
    for name, links in samples:
        label = args.label or label_from_name(name, clf.classes)
        if label is None:
            print(f"warning: skipping {name}: no activity in its name (pass --label)")
            continue
        names.append(name)
        y.append(clf.classes.index(label))
        keep.append(links)
    if not keep:
        raise _user_error()("no labelled recordings (name files after an activity or pass --label)")
    return clf.inputs(keep), np.asarray(y), names


def load_images(args):
    """(images, unreadable, title) of `args.images` filtered by --labels/--people (warnings for unreadable ones)."""
    from processing.realdata.real_images import load_real_images, parse_people, read_labels_csv

    labels = read_labels_csv(args.labels) if args.labels is not None else None
    images, bad = load_real_images(args.images, labels=labels, people=parse_people(args.people))
    for _name, why in bad:
        print(f"warning: skipping unreadable image {why}")
    title = f"{args.model.name} on images {args.images}" + (f" (people {args.people})" if args.people else "")
    return images, bad, title


def _evaluate_images(clf, args, out: Path) -> int:
    from processing.classifier.images import evaluate_images, split_seen, write_image_evaluation

    t0 = time.perf_counter()
    images, bad, title = load_images(args)
    images, seen = split_seen(clf, images)
    if seen:
        print(f"warning: {len(seen)} of the images were training data of this model (their sha256 is in the "
              "checkpoint); they are left out of the metrics")
    if seen and not any(im.activity in clf.classes for im in images):
        raise _user_error()(f"every one of the {len(seen)} images of the model's classes was training data of this "
                            "model: nothing to test")
    ev = evaluate_images(clf, images, bad)
    files = write_image_evaluation(ev, out, title, extra={"people": args.people, "seconds": time.perf_counter() - t0,
                                                          "left_out_seen_in_training": len(seen),
                                                          "seen_in_training": [im.name for im in seen]})
    left = f"\n  {len(seen)} image(s) left out: training data of the model" if seen else ""
    print(f"{title}:\n{ev.summary()}" + left)
    print("wrote " + ", ".join(str(f) for f in files))
    return 0


def cmd_evaluate(args) -> int:
    clf = _load_model(args.model)
    out = args.out or args.model.with_name(args.model.stem + "_eval")
    check_output(out, "dir")
    if args.images is None and (args.labels is not None or args.people is not None):
        raise _user_error()("--labels and --people apply to --images only")
    if args.images is not None:
        return _evaluate_images(clf, args, out)
    if args.data is not None:
        from processing.classifier.experiment import load_dataset

        ds = load_dataset(args.data, clf.links, clf.preprocess, progress=not args.quiet)
        x, y, names, title = ds.x, ds.y, ds.names, f"{args.model.name} on {args.data}"
    else:
        x, y, names = _recording_inputs(clf, args)
        title = f"{args.model.name} on recordings {args.recordings}"
    evaluate_arrays(clf, x, y, out, title, names)
    print(f"wrote {out}/confusion.png, confusion.csv, metrics.json, predictions.csv")
    return 0


def _crossval_plan(args) -> list[dict]:
    if args.plan is not None:
        from rtchannel.dataset.build import read_crossval_plan

        try:
            return read_crossval_plan(args.plan)
        except ValueError as e:
            raise _user_error()(str(e)) from None
    if not args.train or not args.test:
        raise _user_error()("give --plan YAML, or --train SPEC and --test SPEC (repeatable)")
    return [{"name": f"train{k + 1}", "train": t, "test": list(args.test)} for k, t in enumerate(args.train)]


def cmd_crossval(args) -> int:
    from processing.classifier.experiment import crossvalidate

    plan = _crossval_plan(args)
    out = output_file(args.out, ".csv")
    check_output(out, "file")
    links, pre, mcfg, tcfg = _configs(args)
    cv = crossvalidate(plan, links=links, preprocess=pre, model=mcfg, train_config=tcfg, progress=not args.quiet,
                       log=print)
    cv.save(out)
    print(cv.markdown())
    print(f"wrote {out} and {out.with_suffix('.md')}")
    return 0


def add_classifier_commands(sub) -> None:
    """Register the `train`, `evaluate` and `crossval` subcommands."""
    p = sub.add_parser("train", help="train the multiperspective DCNN activity classifier on a dataset",
                       description="Train the seed's two-branch DCNN (Sect. VII) on a dataset folder with an "
                       "80:20 stratified split (grouped by motion source), Adam and early stopping. Writes "
                       "MODEL (checkpoint with preprocessing and class names), MODEL_curves.png and the "
                       "validation confusion matrix (PNG, CSV). " + (__doc__ or "").split("\n\n")[1])
    p.add_argument("--data", required=True, action="append", help="dataset folder, optionally DIR:FILTER, or real "
                   "labelled images images:DIR[:people=P36-P45|P50,activity=walk|fall] (single-radar models; labels "
                   "from Glasgow names or --labels); repeat to train on several, mixed by --data-weights")
    p.add_argument("--data-weights", type=float, nargs="+", metavar="W", help="one weight per --data: the share of "
                   "each training epoch's draws from each dataset (drawn with replacement; default: every item once "
                   "per epoch)")
    p.add_argument("--labels", type=Path, help="images: specs: CSV file,activity[,subject] for images whose names are "
                   "not Glasgow names")
    p.add_argument("--init", type=Path, metavar="MODEL", help="start from this checkpoint's weights (fine-tuning); "
                   "its preprocessing and network are kept, and a different one given here is refused")
    p.add_argument("--out", required=True, type=Path, help="model checkpoint to write (.pt)")
    _add_preprocess_model_args(p)
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("evaluate", help="evaluate a trained classifier on a dataset or on .dat recordings",
                       description="Accuracy, per-class precision/recall, macro F1 and the confusion matrix "
                       "(the seed's Fig. 11 layout, PNG and CSV) of MODEL on a dataset, on real Ancortek "
                       ".dat recordings run through the same DSP, or on real spectrogram images (--images; "
                       "activities the model does not know, e.g. drink, are reported apart, never in accuracy).")
    p.add_argument("--model", required=True, type=Path, help="checkpoint written by `rtchannel train`")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--data", help="dataset folder, optionally DIR:FILTER (key=v1|v2,key!=v,key~text)")
    g.add_argument("--recordings", type=Path, help="a .dat file or a folder of them")
    g.add_argument("--images", type=Path, help="a folder of real spectrogram images in the Glasgow layout "
                   "(single-radar model; labels from names like 1P36A01R01.png or --labels)")
    p.add_argument("--label", help="activity of every recording (default: from the file names, e.g. "
                   "fall_01.dat or Glasgow codes 1P36A06R01.dat)")
    p.add_argument("--labels", type=Path, help="--images: CSV file,activity[,subject] for images whose names "
                   "are not Glasgow names")
    p.add_argument("--people", help="--images: only these subjects, e.g. P36-P45 or P36,P40-P42")
    p.add_argument("--channels", type=positive_int, default=1, help="interleaved receive channels per .dat file "
                   "(= number of model links: one file per sample; 1: files NAME_radar1.dat, NAME_radar2.dat)")
    p.add_argument("--conjugate", action="store_true", help="conjugate recorded IQ (opposite I/Q convention)")
    p.add_argument("--allow-partial", action="store_true", help="drop an incomplete last sweep")
    p.add_argument("--out", type=Path, help="output folder (default MODEL_eval next to the model)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("crossval", help="train on one simulation setting, test on others; one table",
                       description="Cross-validation between simulation settings: for each training spec "
                       "train a model, evaluate it on every test spec (a test equal to the training spec "
                       "uses the held-out validation split) and write one CSV plus a markdown table. "
                       "Plan YAML: experiments: [{name, train: SPEC, test: [SPEC, ...]}].")
    p.add_argument("--plan", type=Path, help="YAML listing named train/test settings")
    p.add_argument("--train", action="append", help="training dataset spec (repeatable)")
    p.add_argument("--test", action="append", help="test dataset spec (repeatable)")
    p.add_argument("--out", required=True, type=Path, help="table to write (.csv; a .md is written beside it)")
    _add_preprocess_model_args(p)
    p.set_defaults(func=cmd_crossval)
