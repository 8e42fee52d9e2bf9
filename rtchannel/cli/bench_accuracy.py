"""`rtchannel bench --calibrate` and `--validate-accuracy`: the accuracy budget's table and its check."""
from __future__ import annotations

import json


def bench_radar(name: str):
    """(radar, name) of --radar: the seed's 2x2 system, the Glasgow preset, or a radar YAML file."""
    from pathlib import Path

    from rtchannel.cli.common import UserError
    from rtchannel.radar import RadarConfig

    if name == "seed":
        return RadarConfig(), "seed 2x2 (24.125 GHz)"
    if name == "glasgow":
        return RadarConfig.glasgow(), "Radar.glasgow (5.8 GHz)"
    path = Path(name)
    if not path.is_file():
        raise UserError(f"--radar: expected seed, glasgow or a radar YAML file, got {name!r}")
    return RadarConfig.from_file(path), path.stem


def _activities(args) -> tuple[str, ...]:
    from processing.labels import ACTIVITIES
    from rtchannel.cli.common import UserError

    if not args.activities:
        return ACTIVITIES
    acts = tuple(a.strip() for a in args.activities.split(",") if a.strip())
    bad = [a for a in acts if a not in ACTIVITIES]
    if bad or not acts:
        raise UserError(f"--activities: unknown activity {bad[0] if bad else ''!r}; "
                        f"choose from {', '.join(ACTIVITIES)}")
    return acts


def cmd_calibrate(args) -> int:
    from tqdm import tqdm

    from rtchannel.accuracy import load_table
    from rtchannel.analysis.calibrate import (CANDIDATES, calibrate, calibration_motions, merge_tables, run_count,
                                             write_calibration)
    from rtchannel.cli.common import UserError

    if args.out is None:
        raise UserError("--calibrate needs --out DIR")
    radar, name = bench_radar(args.radar)
    try:
        motion_seeds = tuple(int(s) for s in str(args.motion_seeds).split(","))
    except ValueError:
        raise UserError(f"--motion-seeds: expected comma-separated integers, got {args.motion_seeds!r}") from None
    base = load_table(args.merge_into) if args.merge_into else None
    if base is not None and [r.label for r in base.rows] != [c.label for c, _ in CANDIDATES]:
        raise UserError(f"--merge-into {args.merge_into}: its settings are not this version's calibration "
                        "settings; recalibrate without --merge-into")  # checked before the run, not after it
    motions = calibration_motions(_activities(args), motion_seeds)
    with tqdm(total=run_count(motions), unit="run", disable=args.quiet or None) as bar:
        table = calibrate(radar, name, tuple(motions), seeds=args.seeds, reference_seeds=args.reference_seeds or 4,
                          motions=motions, progress=bar.update)
    if base is not None:
        try:
            table = merge_tables(base, table)
        except ValueError as e:
            raise UserError(f"--merge-into {args.merge_into}: {e}") from None
    for p in write_calibration(table, args.out):
        print(f"wrote {p}")
    print((args.out / "calibration.md").read_text())
    return 0


def cmd_validate_accuracy(args) -> int:
    from tqdm import tqdm

    from rtchannel.accuracy import table_for
    from rtchannel.analysis.accuracy_validation import held_out_motions, summary, validate, write_validation
    from rtchannel.cli.common import UserError

    if args.out is None:
        raise UserError("--validate-accuracy needs --out DIR")
    radar, name = bench_radar(args.radar)
    table, source = table_for(radar, args.calibration)
    motions = held_out_motions(_activities(args))
    # exact is the reference's own setting: its error is the single-run floor by construction (not re-measured)
    budgets = ("fast", "balanced", *(args.budget or ()))
    with tqdm(total=len(motions) * (len(budgets) + 1), unit="run", disable=args.quiet or None) as bar:
        rows = validate(radar, table, motions, budgets, seeds=args.seeds, reference_seeds=args.reference_seeds or 4,
                        progress=bar.update)
    meta = {"radar": name, "calibration": source, "seeds": args.seeds, "reference_seeds": args.reference_seeds or 4}
    for p in write_validation(rows, args.out, meta):
        print(f"wrote {p}")
    print(json.dumps(summary(rows), indent=1))
    return 0
