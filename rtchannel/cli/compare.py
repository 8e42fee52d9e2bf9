"""`rtchannel compare`: the same activities through several backends; Table-I style DTW table + figure."""
from __future__ import annotations

from pathlib import Path


def _sim_paths(items) -> list[Path]:
    from rtchannel.cli.common import UserError

    paths = []
    for item in items:
        p = Path(item)
        found = sorted(p.rglob("signature.h5")) if p.is_dir() else [p] if p.is_file() else []
        if not found:
            raise UserError(f"--sim: no signature.h5 at {p}")
        paths += found
    return paths


def cmd_compare_real(args) -> int:
    """Table I with real recordings: simulated curves (rows) against real images (columns)."""
    from processing.realdata.real_images import load_real_images, parse_people, read_labels_csv
    from processing.metrics.sim_real_table import (curves_from_dataset, curves_from_images, curves_from_signature_files,
                                           dtw_activity_table, write_dtw_table)
    from rtchannel.cli.common import UserError, check_output

    if (args.sim is None) == (args.data is None):
        raise UserError("--real needs the simulated side: --sim FILES/DIRS or --data DATASET[:FILTER]")
    check_output(args.out, "dir")
    if args.sim is not None:
        sim = curves_from_signature_files(_sim_paths(args.sim), args.link)
    else:
        from rtchannel.cli.classify import open_spec

        reader, idx = open_spec(args.data)
        sim = curves_from_dataset(reader, idx, args.link)
    labels = read_labels_csv(args.labels) if args.labels is not None else None
    images, bad = load_real_images(args.real, labels=labels, people=parse_people(args.people))
    for _, why in bad:
        print(f"warning: skipping unreadable image {why}")
    table = dtw_activity_table(sim, curves_from_images(images), args.dt, args.dtw_scale)
    files = write_dtw_table(table, args.out)
    print(files[2].read_text())
    print("wrote " + ", ".join(str(f) for f in files))
    return 0


def cmd_compare(args) -> int:
    from tqdm import tqdm

    if args.real is not None:
        return cmd_compare_real(args)

    from rtchannel.cli.common import (UserError, accuracy_kwargs, check_output, checked_options, load_radar,
                                      split_list)
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
    options = checked_options(args.option, args.backends)
    radar, _ = load_radar(args)
    check_output(args.out, "dir")
    with tqdm(total=len(args.backends) * len(args.activities), unit="run", disable=args.quiet or None) as bar:
        files = compare(args.backends, args.activities, radar, args.out, seed=args.seed, height=args.height,
                        options=options, progress=bar.update, **accuracy_kwargs(args))
    for f in files:
        print(f"wrote {f}")
    table = next(f for f in files if f.suffix == ".md")
    print(table.read_text())
    return 0


def add_compare(sub) -> None:
    """Register the `compare` subcommand."""
    from rtchannel.cli.common import add_accuracy_args, add_radar_args, seed_int
    from rtchannel.motion.activities import ACTIVITIES

    p = sub.add_parser("compare", help="one set of activities through several backends: DTW table + p(v,t) figure",
                       description="Simulate procedural activities through two or more backends and write the "
                       "seed's Table I between the first backend and each other one (normalised DTW of mean "
                       "radial velocities for every activity pair), per-activity p(v,t) total-variation and "
                       "mean-velocity RMSE, and a side-by-side PNG of p(v,t). With --real: simulated signatures "
                       "(--sim or --data) against real spectrogram images instead, rows simulated, columns real.")
    p.add_argument("--backends", nargs="+", default=["points", "facets"],
                   help="backends, space- or comma-separated (default points facets)")
    p.add_argument("--activities", nargs="+", default=list(ACTIVITIES), help="activities (default all five)")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument("--option", action="append", metavar="BACKEND.NAME=VALUE",
                   help="backend option, e.g. facets.lod=5k or sionna.samples_per_src=100000 (repeatable)")
    p.add_argument("--height", type=float, default=1.75, help="body height [m]")
    p.add_argument("--seed", type=seed_int, default=0, help="motion seed")
    add_radar_args(p)
    add_accuracy_args(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    g = p.add_argument_group("Table I against real recordings (--real: no simulation is run)")
    g.add_argument("--real", type=Path, help="folder of real spectrogram images (Glasgow layout and names, or "
                   "--labels); the table's columns")
    g.add_argument("--sim", nargs="+", help="simulated signature.h5 files or folders holding them; the rows")
    g.add_argument("--data", help="or a dataset DIR[:FILTER] as the rows")
    g.add_argument("--link", default="radar1", help="simulated link to compare (default radar1)")
    g.add_argument("--labels", type=Path, help="CSV file,activity[,subject] for images without Glasgow names")
    g.add_argument("--people", help="real subjects only, e.g. P36-P45")
    g.add_argument("--dt", type=float, default=0.016, help="common time step of the curves before DTW [s] "
                   "(default 0.016)")
    g.add_argument("--dtw-scale", type=float, help="divide every DTW by this speed [m/s] (default: each "
                   "pair's peak |v|, as the backend table)")
    p.set_defaults(func=cmd_compare)
