"""`rtchannel simulate`: one activity through one backend; writes signature.h5 and PNG figures."""
from __future__ import annotations

import argparse
from pathlib import Path

from rtchannel.cli.common import (UserError, accuracy_kwargs, add_accuracy_args, add_motion_args, add_radar_args,
                                  build_motion, check_output, load_radar, parse_options)


def add_simulate(sub) -> None:
    """Register the `simulate` subcommand."""
    p = sub.add_parser("simulate", help="simulate one activity and write signature.h5 plus PNGs",
                       description="Simulate one activity through a scattering backend and the shared FMCW "
                       "synthesiser/DSP; writes DIR/signature.h5 and DIR/{pvt,mean_velocity,range}.png.")
    add_motion_args(p)
    p.add_argument("--backend", default="points", help="scattering backend: points, facets or sionna (default points)")
    p.add_argument("--scene", help="mesh backends: room, free_space or a Mitsuba XML file (default room)")
    p.add_argument("--lod", help="mesh backends: avatar level of detail full, 10k, 5k, 2k or auto (default 10k)")
    add_accuracy_args(p)
    add_chair_arg(p)
    p.add_argument("--option", action="append", metavar="NAME=VALUE",
                   help="any other backend option, e.g. walls=false, trace_fps=30, samples_per_src=100000")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    add_radar_args(p)
    p.add_argument("--keep-iq", action="store_true", help="store raw IQ in signature.h5")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_simulate)


class StoreGiven(argparse.Action):
    """argparse's store, noting ``<dest>_given`` (a default cannot say whether the user gave the option)."""

    def __call__(self, parser, namespace, values, option_string=None):  # noqa: D102 - argparse hook
        setattr(namespace, self.dest, values)
        setattr(namespace, f"{self.dest}_given", True)


def add_chair_arg(p) -> None:
    """--chair auto|none, default the API's (`rtchannel.scene.chair_fit.DEFAULT_CHAIR`; read by `scene_with_chair`)."""
    from rtchannel.scene.chair_fit import CHAIR_MODES, DEFAULT_CHAIR

    p.add_argument("--chair", choices=CHAIR_MODES, default=DEFAULT_CHAIR, action=StoreGiven,
                   help="mesh backends and render: auto puts a wooden chair under the person for sit and stand, "
                   "placed from the motion (seat height, facing, backrest behind); none: no chair (default "
                   f"{DEFAULT_CHAIR}, as the Python API's simulate)")


def scene_with_chair(scene, motion, chair: str):
    """`scene` plus the chair `--chair` asks for (`Scene.for_motion`); a one-line user
    error when a sit/stand motion has no seated phase."""
    from rtchannel.scene.spec import Scene

    try:
        return Scene.for_motion(motion, scene, chair)
    except ValueError as e:
        raise UserError(f"--chair {chair}: {e}; use --chair none") from None


def backend_options(args) -> dict:
    """Backend keyword options from --lod/--option (values parsed as YAML scalars), checked against the
    backend; --scene is passed separately (`simulate(scene=...)`)."""
    from rtchannel.backends import BACKENDS, RESERVED_OPTIONS, validate_options

    if args.backend not in BACKENDS:
        raise UserError(f"unknown backend '{args.backend}'; choose one of {', '.join(BACKENDS)}")
    opts = parse_options(args.option)
    for name in ("scene", "lod", "chair"):
        given = getattr(args, f"{name}_given", False) if name == "chair" else getattr(args, name) is not None
        if given and args.backend == "points":
            raise UserError(f"--{name} applies to the mesh backends (facets, sionna), not points")
    if args.lod is not None:
        opts["lod"] = args.lod
    try:
        validate_options(args.backend, opts, reserved=RESERVED_OPTIONS + ("scene",))
    except ValueError as e:
        raise UserError(str(e)) from None
    return opts


def cmd_simulate(args) -> int:
    from processing.plots.figure_worker import FigureWorker

    options = backend_options(args)
    budget = accuracy_kwargs(args)
    radar, angle = load_radar(args)
    check_output(args.out, "dir")
    # the figures' process starts here, before the simulation's imports: it imports matplotlib on the other core
    # while this one simulates (processing.plots.figure_worker)
    with FigureWorker(enabled=not args.no_plots) as figures:
        return _simulate(args, options, budget, radar, angle, figures)


def _simulate(args, options: dict, budget: dict, radar, angle: float, figures) -> int:
    from tqdm import tqdm

    from rtchannel.pipeline import simulate
    from rtchannel.scene.spec import Scene

    from processing.dsp.config import check_recording

    motion = build_motion(args)
    check_recording(motion.duration, radar.waveform, radar.dsp, len(radar.links), args.keep_iq)
    scene = Scene(args.scene) if args.scene is not None else None
    n_chirps = int(motion.duration / radar.waveform.pri_s + 1) * len(radar.links)
    with tqdm(total=n_chirps, unit="chirp", disable=args.quiet or None, desc=f"{args.activity}") as bar:
        result = simulate(motion, radar, args.backend, scene=scene, chair=args.chair, keep_iq=args.keep_iq,
                          progress=bar.update, **budget, **options)
    scene = result.config.get("backend_options", {}).get("scene")
    if isinstance(scene, dict) and scene.get("furniture"):
        print(f"scene {scene['source']}: " + "; ".join(f.get("note") or f.get("label", "") for f in scene["furniture"]))
    result.config["direction"] = None if args.angle_deg is not None else args.direction
    out = result.save(args.out / "signature.h5", seed=args.seed)
    if "accuracy" in result.config:
        acc = result.config["accuracy"]
        print(f"accuracy {acc['budget']}: {acc['chosen']} (calibrated EMD {acc['calibrated_emd_m_s']:.3f} m/s, "
              f"{acc['calibrated_s_per_sim_s']:.3g} s per simulated s; {acc['calibration']})")
    print(f"wrote {out}")
    if not args.no_plots:
        title = f"{args.activity} ({args.backend}, {angle:g} deg)"
        for png in figures.save_figures(result.signatures, args.out, title=title):
            print(f"wrote {png}")
    return 0
