"""`rtchannel bench`: speed of the simulation chain, and speed against error across backend settings."""
from __future__ import annotations

import json
import sys
from pathlib import Path


def cmd_bench(args) -> int:
    from rtchannel.analysis.chain_bench import bench_chain, exact_duration_walk
    from rtchannel.cli.common import UserError, check_output, checked_options

    check_output(args.out, "dir")
    if args.calibrate or args.validate_accuracy:
        from rtchannel.cli.bench_accuracy import cmd_calibrate, cmd_validate_accuracy

        return cmd_calibrate(args) if args.calibrate else cmd_validate_accuracy(args)

    if args.chain:
        from rtchannel.backends import BACKENDS

        if args.chain not in BACKENDS:
            raise UserError(f"--chain: unknown backend '{args.chain}'; choose one of {', '.join(BACKENDS)}")
        options = checked_options(args.option, [args.chain]).get(args.chain, {})
        result = bench_chain(args.chain, repeats=args.repeats, duration=args.duration, keep_iq=args.keep_iq,
                             **options)
        text = json.dumps(result, indent=2)
        print(text)
        if args.out:
            from processing.atomic import write_text_atomic

            write_text_atomic(args.out / f"bench_{args.chain}.json", text + "\n")
        return 0
    from tqdm import tqdm

    from rtchannel.radar import RadarConfig
    from rtchannel.analysis.speed_error import QUICK, QUICK_REFERENCE, REFERENCE, SWEEP, sweep, write_outputs

    if args.out is None:
        raise UserError("the speed/error sweep needs --out DIR")
    settings = QUICK if args.quick else SWEEP
    reference = QUICK_REFERENCE if args.quick else REFERENCE
    motion = exact_duration_walk(args.duration)
    radar = RadarConfig()
    with tqdm(total=len(settings) + 1, unit="setting", disable=args.quiet or None) as bar:
        rows, summary = sweep(motion, radar, settings, reference, repeats=args.repeats, progress=bar.update,
                              reference_seeds=args.reference_seeds or 8)
    meta = {"activity": f"{args.duration:g} s walk, 2 monostatic radars", "repeats": args.repeats,
            "reference": reference.label, **summary}
    for p in write_outputs(rows, args.out, meta):
        print(f"wrote {p}")
    print((args.out / "speed_error.md").read_text())
    if not summary["converged"]:
        print(f"warning: the settings' error spread is only {summary['spread_to_self_error']:.1f}x the reference's "
              f"own error; raise --reference-seeds", file=sys.stderr)
    return 0


def add_bench(sub) -> None:
    """Register the `bench` subcommand."""
    from rtchannel.cli.common import finite_float, positive_int

    p = sub.add_parser("bench", help="speed against error of backend settings (or time one chain)",
                       description="Default: sweep backend settings (backend, LOD, trace rate, rays, depth, "
                       "walls) on a procedural walk with the two seed radars, measure wall time per simulated "
                       "second and the error of p(v,t) and mean velocity against a Sionna RT reference; "
                       "writes speed_error.{csv,md,png,json}. The reference is the mean over --reference-seeds runs. "
                       "With --chain BACKEND: time one backend's "
                       "whole chain (medians, per-stage split) as JSON.")
    p.add_argument("--chain", metavar="BACKEND", help="time only this backend's chain (points, facets, sionna)")
    p.add_argument("--option", action="append", metavar="BACKEND.NAME=VALUE", help="backend option for --chain")
    p.add_argument("--keep-iq", action="store_true",
                   help="with --chain: time the raw-IQ route (keep_iq) instead of the default signature-only route")
    p.add_argument("--quick", action="store_true",
                   help="sweep without Sionna (reference: facets on the full mesh); minutes instead of an hour")
    p.add_argument("--reference-seeds", type=positive_int,
                   help="runs (ray or diffuse-phase seeds) averaged into the reference (default 8; 4 with "
                   "--calibrate and --validate-accuracy)")
    p.add_argument("--repeats", type=positive_int, default=3, help="timed repeats per setting (default 3)")
    p.add_argument("--duration", type=finite_float, default=5.0, help="simulated walk length [s] (default 5)")
    p.add_argument("--calibrate", action="store_true",
                   help="measure the accuracy budget's calibration table (speed and error of facets settings per "
                   "activity) for --radar and write calibration.{json,md,png} to --out")
    p.add_argument("--validate-accuracy", action="store_true",
                   help="check the budgets (fast, balanced, exact, --budget) against a converged reference on "
                   "motions not used to calibrate; writes accuracy_validation.{csv,md,png} to --out")
    p.add_argument("--radar", default="seed", help="with --calibrate/--validate-accuracy: seed, glasgow or a "
                   "radar YAML file (default seed)")
    p.add_argument("--calibration", type=Path, help="with --validate-accuracy: the table to check (default: the "
                   "shipped one of the radar)")
    p.add_argument("--budget", action="append", metavar="EMD", type=finite_float,
                   help="with --validate-accuracy: also check this numeric budget [m/s] (repeatable)")
    p.add_argument("--motion-seeds", default="0",
                   help="with --calibrate: comma-separated generator seeds; each activity is calibrated on one "
                   "motion per seed, and a setting must meet a budget on all of them (default 0)")
    p.add_argument("--merge-into", type=Path, metavar="TABLE",
                   help="with --calibrate: add this run's motions to an existing calibration.json of the same "
                   "settings (its costs are kept)")
    p.add_argument("--seeds", type=positive_int, default=2,
                   help="with --calibrate: diffuse-phase seeds per setting and activity (default 2)")
    p.add_argument("--activities", help="with --calibrate/--validate-accuracy: comma-separated activities "
                   "(default all five)")
    p.add_argument("--out", type=Path, help="output folder")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_bench)
