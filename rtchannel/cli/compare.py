"""`rtchannel compare`: the same activities through several backends; Table-I style DTW table + figure."""
from __future__ import annotations

from pathlib import Path


def cmd_compare(args) -> int:
    from tqdm import tqdm

    from rtchannel.cli.common import UserError, check_output, load_radar, parse_options, split_list
    from rtchannel.analysis.compare import compare
    from rtchannel.motion.activities import ACTIVITIES
    from rtchannel.backends import BACKENDS

    args.backends = split_list(args.backends)
    args.activities = split_list(args.activities)
    bad = [b for b in args.backends if b not in BACKENDS]
    if bad or len(args.backends) < 2:
        raise UserError(f"--backends needs two or more of {', '.join(BACKENDS)}; got {' '.join(args.backends)}")
    bad = [a for a in args.activities if a not in ACTIVITIES]
    if bad:
        raise UserError(f"unknown activity '{bad[0]}'; choose from {', '.join(ACTIVITIES)}")
    options = parse_options(args.option, per_backend=True)
    unknown = [b for b in options if b not in args.backends]
    if unknown:
        raise UserError(f"--option for backend '{unknown[0]}' which is not in --backends")
    radar, _ = load_radar(args)
    check_output(args.out, "dir")
    with tqdm(total=len(args.backends) * len(args.activities), unit="run", disable=args.quiet or None) as bar:
        files = compare(args.backends, args.activities, radar, args.out, seed=args.seed, height=args.height,
                        options=options, progress=bar.update)
    for f in files:
        print(f"wrote {f}")
    table = next(f for f in files if f.suffix == ".md")
    print(table.read_text())
    return 0


def add_compare(sub) -> None:
    """Register the `compare` subcommand."""
    from rtchannel.cli.common import add_radar_args
    from rtchannel.motion.activities import ACTIVITIES

    p = sub.add_parser("compare", help="one set of activities through several backends: DTW table + p(v,t) figure",
                       description="Simulate procedural activities through two or more backends and write the "
                       "seed's Table I between the first backend and each other one (normalised DTW of mean "
                       "radial velocities for every activity pair), per-activity p(v,t) total-variation and "
                       "mean-velocity RMSE, and a side-by-side PNG of p(v,t).")
    p.add_argument("--backends", nargs="+", default=["points", "facets"], help="backends, space- or comma-separated (default points facets)")
    p.add_argument("--activities", nargs="+", default=list(ACTIVITIES), help="activities (default all five)")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument("--option", action="append", metavar="BACKEND.NAME=VALUE",
                   help="backend option, e.g. facets.lod=5k or sionna.samples_per_src=100000 (repeatable)")
    p.add_argument("--height", type=float, default=1.75, help="body height [m]")
    p.add_argument("--seed", type=int, default=0, help="motion seed")
    add_radar_args(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_compare)
