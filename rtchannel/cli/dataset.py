"""`rtchannel dataset`: run an augmentation plan into a resumable HDF5 dataset, or describe one (--info)."""
from __future__ import annotations

from pathlib import Path


def add_dataset(sub) -> None:
    """Register the `dataset` subcommand."""
    p = sub.add_parser(
        "dataset", help="generate a dataset from an augmentation plan (Dask), or --info DIR",
        description="Expand an augmentation plan (motion, physical and signal layers) into work items and run "
        "them with Dask into HDF5 shards plus an index. Re-running the same command skips finished items and "
        "completes an interrupted run. --config takes a YAML file or a preset name (seed).")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--config", help="plan YAML file, or a preset name: seed")
    g.add_argument("--info", type=Path, metavar="DIR", help="print counts and failures of the dataset in DIR")
    p.add_argument("--out", type=Path, help="dataset folder (required with --config)")
    p.add_argument("--scheduler", help="address of a running Dask scheduler (e.g. tcp://host:8786)")
    p.add_argument("--workers", type=int, help="local worker processes (default: number of cores; 1 runs "
                   "in this process)")
    p.add_argument("--retries", type=int, default=2, help="extra attempts for a failing item (default 2)")
    p.add_argument("--backend", help="override the plan's backend (points, facets, sionna)")
    p.add_argument("--dry-run", action="store_true", help="validate and count the work items, run nothing")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_dataset)


def cmd_dataset(args) -> int:
    from pydantic import ValidationError

    from rtchannel.cli.common import UserError, check_output, validation_line

    if args.info is not None:
        return _info(args.info)
    if args.out is None and not args.dry_run:
        raise UserError("--out DIR is required with --config")
    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers must be >= 1, got {args.workers}")
    if args.retries < 0:
        raise UserError(f"--retries must be >= 0, got {args.retries}")
    if args.scheduler is not None:  # before any work: a typo'd address is one line, not a bug report
        from rtchannel.dataset.runner import check_scheduler_address

        check_scheduler_address(args.scheduler)
    from rtchannel.dataset.build import build_dataset, plan_dataset
    from rtchannel.errors import InputError

    try:
        # counting downloads nothing
        plan, items = plan_dataset(args.config, backend=args.backend, fetch=not args.dry_run)
    except ValidationError as e:
        raise UserError(validation_line(e, f"plan {args.config}")) from None
    except InputError as e:
        if str(e).startswith("plan "):
            raise  # already one line naming the plan file (rtchannel.cli.main prints it)
        raise UserError(f"plan {args.config}: {e}") from None
    except FileNotFoundError as e:
        raise UserError(f"plan {args.config}: {e}") from None
    if args.dry_run:
        from collections import Counter

        from rtchannel.dataset.plan_check import check_sources

        checked = check_sources(plan, f"plan {args.config}")  # each motion file loads; options fit it
        c = Counter(it.activity for it in items)
        print(f"{plan.name}: {len(items)} items ({', '.join(f'{k}={v}' for k, v in sorted(c.items()))}), "
              f"{len({it.group for it in items})} motion groups, backend {plan.backend}")
        if checked.loaded or checked.not_local:
            print(f"motion files: {checked.loaded} loaded and checked" + (
                f"; {checked.not_local} registered files not local, not checked (rtchannel data fetch gets them)"
                if checked.not_local else ""))
        return 0
    from rtchannel.dataset.runner import PlanMismatchError

    check_output(args.out, "dir")  # after the plan is valid: a bad plan leaves no folder behind

    try:
        s = build_dataset(plan, args.out, scheduler=args.scheduler, workers=args.workers, retries=args.retries,
                          progress=not args.quiet)
    except (PlanMismatchError, BlockingIOError) as e:
        raise UserError(str(e)) from None
    except (OSError, TimeoutError) as e:
        if args.scheduler:
            raise UserError(f"cannot use the Dask scheduler at {args.scheduler}: {e}") from None
        raise
    rate = 60.0 * s.done_now / s.seconds if s.seconds > 0 else 0.0
    print(f"{args.out}: {s.done_before + s.done_now}/{s.total} items done ({s.done_now} now, {rate:.0f} items/min "
          f"on {s.workers} worker(s)), {len(s.failed)} failed")
    for entry in s.failed[:5]:
        print(f"failed {entry['item_id']}: {entry['error']}")
    return 0 if s.complete else 1


def _info(root) -> int:
    """`dataset --info DIR`: counts and failures, and what the index cannot say: its unreadable lines and
    the items the shards hold that it does not list (a damaged index is reported, not silently empty)."""
    from processing.errors import DatasetFormatError
    from processing.io.dataset_store import index_health
    from processing.io.dataset_reader import DatasetReader
    from rtchannel.cli.common import UserError

    if not root.is_dir():
        raise UserError(f"dataset folder not found: {root}")
    health = index_health(root)
    damage = []  # after the report, one error line and exit status 2: scripts see a damaged dataset
    try:
        print(DatasetReader(root).summary())
    except DatasetFormatError as e:
        print(f"{root}: the index cannot be read as a whole ({e})")
        damage.append(str(e))
    except FileNotFoundError as e:
        raise UserError(str(e)) from None
    bad = health["bad_lines"]
    if bad:
        print(f"  index: {len(bad)} unreadable line{'s' if len(bad) > 1 else ''} (first: line {bad[0]}); "
              f"{health['index_lines']} readable entries")
    print(f"  shards hold {health['shard_items']} items" + (f", {len(health['bad_shards'])} unreadable shards "
          f"({', '.join(health['bad_shards'][:3])})" if health["bad_shards"] else ""))
    if health["missing_from_index"]:
        n = health["missing_from_index"]
        print(f"  {n} item{'s' if n > 1 else ''} in the shards {'are' if n > 1 else 'is'} not in the index: run the "
              "same `rtchannel dataset` command again to resume, which rebuilds the index from the shards")
    if bad and not damage:
        damage.append(f"{root / 'index.jsonl'}: {len(bad)} unreadable line{'s' if len(bad) > 1 else ''} (first: line "
                      f"{bad[0]}; a run killed while writing leaves its last line torn: run it again to resume)")
    if health["bad_shards"]:
        damage.append(f"{len(health['bad_shards'])} unreadable shards ({', '.join(health['bad_shards'][:3])})")
    if damage:
        raise UserError(f"the dataset in {root} is damaged: {'; '.join(damage)}")
    return 0
