"""`rtchannel transfer`: how many real recordings the simulation saves, as a learning curve with subject-grouped
folds (`processing.classifier.transfer_run.run_transfer`)."""
from __future__ import annotations

import argparse
from pathlib import Path

from rtchannel.cli.common import UserError, check_output, positive_int, seed_int


def _shot(text: str):
    if text == "all":
        return "all"
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a count >= 0 or 'all', got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a count >= 0 or 'all', got {value}")
    return value


def cmd_transfer(args) -> int:
    from processing.classifier.transfer import TransferConfig
    from processing.classifier.transfer_run import run_transfer

    check_output(args.out, "dir")
    given = {k: getattr(args, k) for k in ("folds", "batch_size", "real_steps", "real_min_steps",
                                           "finetune_steps", "mixed_steps", "lr",
                                           "finetune_lr", "feature_lr_scale", "real_share")
             if getattr(args, k) is not None}
    if args.real_passes is not None:
        given["real_passes"] = None if args.real_passes == 0 else args.real_passes
    if args.shots is not None:
        given["shots"] = tuple(args.shots)
    if args.seeds is not None:
        given["seeds"] = tuple(args.seeds)
    if args.arms is not None:
        given["arms"] = tuple(args.arms)
    cfg = TransferConfig(**given)
    if args.pretrained and len(args.pretrained) != len(cfg.seeds):
        raise UserError(f"--pretrained: give one checkpoint per seed ({len(cfg.seeds)}), got {len(args.pretrained)}")
    study = run_transfer(args.sim, args.images, args.out, cfg, labels=args.labels, pretrained=args.pretrained,
                         workers=args.workers, progress=not args.quiet, log=None if args.quiet else print)
    print((args.out / "transfer.md").read_text(), end="")
    print(f"{len(study.rows)} runs, {study.seconds / 60:.1f} min; wrote " + ", ".join(str(f) for f in study.files))
    return 0


def add_transfer(sub) -> None:
    """Register the `transfer` subcommand."""
    p = sub.add_parser("transfer", help="learning curve on real recordings: real only, sim-pretrained then "
                       "fine-tuned, sim and real mixed; what the simulation is worth in recordings",
                       description="Subject-grouped cross-validation on real labelled images: for every shot count "
                       "(real images per class from the training folds), fold and seed, train from scratch on the "
                       "real images, fine-tune the simulation-pretrained network on them, and continue it on "
                       "batches mixing real and simulated items; test on the held-out people. Writes transfer.csv, "
                       "transfer.md, transfer.png (accuracy against real recordings per class, with bands) and "
                       "transfer.json, and states the real recordings per class the simulation is worth. "
                       "Resumes an interrupted study in the same --out.")
    p.add_argument("--sim", required=True, help="simulated dataset (DIR[:FILTER]) for pretraining and mixing")
    p.add_argument("--images", required=True, help="folder of real labelled spectrogram images (Glasgow names or "
                   "--labels with a subject column), or images:DIR[:people=...]")
    p.add_argument("--labels", type=Path, help="CSV file,activity,subject for images whose names are not Glasgow names")
    p.add_argument("--out", required=True, type=Path, help="output folder (an earlier run of the same study resumes)")
    p.add_argument("--shots", type=_shot, nargs="+", metavar="K", help="real images per class, 0 = simulation only, "
                   "'all' = every training-fold image (default 0 1 2 5 10 20 all)")
    p.add_argument("--folds", type=positive_int, help="subject-grouped folds (default 4)")
    p.add_argument("--seeds", type=seed_int, nargs="+", help="training seeds (default 0)")
    p.add_argument("--arms", nargs="+", choices=("real", "finetune", "mixed"), help="default: all three")
    p.add_argument("--pretrained", type=Path, nargs="+", metavar="MODEL", help="simulation-only single-radar "
                   "checkpoints, one per seed, instead of pretraining on --sim (their preprocessing is used)")
    p.add_argument("--workers", type=positive_int, default=2, help="worker processes, one torch thread each "
                   "(default 2)")
    g = p.add_argument_group("trainings on real images (fixed step counts, no validation on real images)")
    g.add_argument("--real-steps", type=positive_int, help="most steps of the real-only arm (default 150)")
    g.add_argument("--real-passes", type=float, help="real-only arm: steps to draw each image about this many "
                   "times, at least --real-min-steps, at most --real-steps (default 50; 0: always --real-steps)")
    g.add_argument("--real-min-steps", type=positive_int, help="fewest steps of the real-only arm (default 60)")
    g.add_argument("--finetune-steps", type=positive_int, help="steps of the fine-tuning arm (default 50)")
    g.add_argument("--mixed-steps", type=positive_int, help="steps of the mixed arm (default 50)")
    g.add_argument("--batch-size", type=positive_int, help="default 32")
    g.add_argument("--lr", type=float, help="learning rate from scratch (default 1e-3)")
    g.add_argument("--finetune-lr", type=float, help="learning rate of the fine-tuning and mixed arms (default 1e-4)")
    g.add_argument("--feature-lr-scale", type=float, help="their convolutions' rate relative to --finetune-lr "
                   "(0 frozen; default 1)")
    g.add_argument("--real-share", type=float, help="mixed arm: share of real images in each batch (default 0.5)")
    p.add_argument("--quiet", action="store_true", help="no progress bar or lines")
    p.set_defaults(func=cmd_transfer)
