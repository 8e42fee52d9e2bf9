"""`rtchannel ensemble`: one model voting with the mean class probability of several trained alike
(`processing.classifier.ensemble`); `evaluate`, `robustness` and the API read it like any checkpoint."""
from __future__ import annotations

from pathlib import Path

from rtchannel.cli.common import check_output, output_file


def cmd_ensemble(args) -> int:
    from processing.classifier import load_checkpoint, save_checkpoint
    from processing.classifier.ensemble import ensemble
    from processing.errors import InputError
    from rtchannel.cli.common import UserError

    args.out = output_file(args.out, ".pt")
    check_output(args.out, "file")
    if len(set(map(Path.resolve, args.models))) != len(args.models):
        raise UserError("--models lists the same checkpoint twice (a member would count double)")
    try:
        clfs = [load_checkpoint(p) for p in args.models]
        clf = ensemble(clfs, [str(p) for p in args.models])
    except (FileNotFoundError, InputError) as e:
        raise UserError(str(e)) from None
    save_checkpoint(args.out, clf)
    seeds = ", ".join(str(m.get("seed")) for m in clf.meta["members"])
    print(f"wrote {args.out}: {len(clf.meta['members'])} members (seeds {seeds})")
    return 0


def add_ensemble(sub) -> None:
    """Register the `ensemble` subcommand."""
    p = sub.add_parser("ensemble", help="combine classifiers trained alike (other seeds) into one soft-voting model",
                       description="Write one checkpoint whose prediction is the mean class probability of the "
                       "given models (soft voting). They must share network, preprocessing, classes and links: "
                       "train the same command with --seed 0, 1, 2. Seeds of one simulated dataset disagree on "
                       "real recordings far more than on simulated validation; the vote averages that out.")
    p.add_argument("--models", required=True, nargs="+", type=Path, metavar="MODEL",
                   help="checkpoints written by `rtchannel train` (or ensembles, which are flattened)")
    p.add_argument("--out", required=True, type=Path, help="ensemble checkpoint to write (.pt)")
    p.set_defaults(func=cmd_ensemble)
