"""The `rtchannel` command line. Errors in user input: one line on stderr, exit status 2."""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np
from pydantic import ValidationError

EXIT_USAGE = 2


class UserError(Exception):
    """A problem with what the user asked for; printed as one line, exit status 2."""


def _validation_line(err: ValidationError, what: str) -> str:
    first = err.errors()[0]
    loc = ".".join(str(x) for x in first.get("loc", ())) or "(root)"
    more = f" (and {err.error_count() - 1} more)" if err.error_count() > 1 else ""
    return f"{what}: {loc}: {first.get('msg', 'invalid value')}{more}"


def _add_motion_args(p) -> None:
    p.add_argument("--activity", default="walk", help="fall, walk, stand, sit or pick (default walk)")
    p.add_argument("--motion-file", type=Path, help="BVH or C3D motion capture instead of a procedural motion")
    p.add_argument("--height", type=float, default=1.75, help="body height [m] (default 1.75)")
    p.add_argument("--speed", type=float, help="walking speed [m/s] (procedural walk only)")
    p.add_argument("--duration", type=float, help="activity duration [s] (procedural)")
    p.add_argument("--distance", type=float, help="walking distance [m] (procedural walk only, default 4)")
    p.add_argument("--start", type=float, nargs=2, metavar=("X", "Y"),
                   help="start of the hips' ground point [m]; default: walks are centred on the origin "
                   "(toward Radar 1 at direction 1), other activities start at the origin")
    p.add_argument("--fps", type=float, default=60.0, help="motion frame rate [Hz] (default 60)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def add_radar_args(p) -> None:
    """--radar-config and the mutually exclusive --direction / --angle-deg (read by `load_radar`)."""
    p.add_argument("--radar-config", type=Path, help="YAML/JSON radar configuration (waveform, dsp, links)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--direction", type=int, default=1, help="seed direction 1..18 (Radar 1 at 20(k-1) deg)")
    g.add_argument("--angle-deg", type=float, help="rotate all radars by this angle about z instead [deg]")


def parse_options(items: list[str] | None, per_backend: bool = False) -> dict:
    """`NAME=VALUE` items -> {name: value}; with `per_backend`, `BACKEND.NAME=VALUE` -> {backend: {name:
    value}}. Values are parsed as YAML scalars (numbers, true/false, null)."""
    import yaml

    out: dict = {}
    form = "BACKEND.NAME=VALUE" if per_backend else "NAME=VALUE"
    for item in items or []:
        key, sep, value = item.partition("=")
        backend, dot, name = key.partition(".") if per_backend else ("", ".", key)
        if not sep or not dot or not name or (per_backend and not backend):
            raise UserError(f"--option must look like {form}, got '{item}'")
        (out.setdefault(backend, {}) if per_backend else out)[name] = yaml.safe_load(value)
    return out


def _add_simulate(sub) -> None:
    p = sub.add_parser("simulate", help="simulate one activity and write signature.h5 plus PNGs",
                       description="Simulate one activity through a scattering backend and the shared FMCW "
                       "synthesiser/DSP; writes DIR/signature.h5 and DIR/{pvt,mean_velocity,range}.png.")
    _add_motion_args(p)
    p.add_argument("--backend", default="points", help="scattering backend: points, facets or sionna (default points)")
    p.add_argument("--scene", help="mesh backends: room, free_space or a Mitsuba XML file (default room)")
    p.add_argument("--lod", help="mesh backends: avatar level of detail full, 10k, 5k, 2k (default 10k)")
    p.add_argument("--option", action="append", metavar="NAME=VALUE",
                   help="any other backend option, e.g. walls=false, trace_fps=30, samples_per_src=100000")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    add_radar_args(p)
    p.add_argument("--keep-iq", action="store_true", help="store raw IQ in signature.h5")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_simulate)


def load_radar(args):
    from rtchannel.radar import RadarConfig, direction_angles

    if args.radar_config is not None and not args.radar_config.is_file():
        raise UserError(f"radar config file not found: {args.radar_config}")
    try:
        radar = RadarConfig.from_file(args.radar_config) if args.radar_config else RadarConfig()
    except ValidationError as e:
        raise UserError(_validation_line(e, f"radar config {args.radar_config}")) from None
    angle = args.angle_deg if args.angle_deg is not None else direction_angles(args.direction)[0]
    return radar.rotated(angle), angle


def _build_motion(args):
    """The motion the user asked for: a motion-capture file or a procedural activity."""
    if args.motion_file is not None:
        from rtchannel.motion.load import load_motion

        if not args.motion_file.is_file():
            raise UserError(f"motion file not found: {args.motion_file}")
        motion = load_motion(args.motion_file, height=args.height, activity=args.activity)
        if args.start is not None:
            motion = motion.transformed(0.0, offset=(*(np.asarray(args.start) - motion.positions[0, 0, :2]), 0.0))
        return motion if args.fps == motion.fps else motion.resampled(args.fps)
    from rtchannel.motion.procedural import ProceduralParams, generate

    overrides = {k: v for k, v in (("speed", args.speed), ("duration", args.duration),
                                   ("distance", args.distance)) if v is not None}
    if args.start is not None:
        overrides["start"] = tuple(args.start)
    elif args.activity == "walk":
        # centred on the origin so the default 4 m walk toward Radar 1 (3 m away) stops short of it
        d = args.distance if args.distance is not None else (
            4.0 if args.duration is None else (args.speed or 1.3) * args.duration)
        overrides["start"] = (-d / 2, 0.0)
    try:
        params = ProceduralParams(height=args.height, fps=args.fps, seed=args.seed, **overrides)
    except ValidationError as e:
        raise UserError(_validation_line(e, "motion parameters")) from None
    return generate(args.activity, params)


def _backend_options(args) -> dict:
    """Backend keyword options from --scene/--lod/--option (values parsed as YAML scalars)."""
    from rtchannel.simulate import BACKENDS

    if args.backend not in BACKENDS:
        raise UserError(f"unknown backend '{args.backend}'; choose one of {', '.join(BACKENDS)}")
    opts = parse_options(args.option)
    for name in ("scene", "lod"):
        if getattr(args, name) is not None:
            if args.backend == "points":
                raise UserError(f"--{name} applies to the mesh backends (facets, sionna), not points")
            opts[name] = getattr(args, name)
    return opts


def cmd_simulate(args) -> int:
    import inspect

    from tqdm import tqdm

    from processing.signature_file import write_signature_file
    from rtchannel.plots import plot_all
    from rtchannel.simulate import backend_function, simulate

    options = _backend_options(args)
    accepted = inspect.signature(backend_function(args.backend)).parameters
    unknown = [k for k in options if k not in accepted or k in ("motion", "radar")]
    if unknown:
        raise UserError(f"backend '{args.backend}' has no option '{unknown[0]}'")
    radar, angle = load_radar(args)
    motion = _build_motion(args)

    n_chirps = int(motion.duration / radar.waveform.pri_s + 1) * len(radar.links)
    with tqdm(total=n_chirps, unit="chirp", disable=args.quiet or None, desc=f"{args.activity}") as bar:
        result = simulate(motion, radar, backend=args.backend, keep_iq=args.keep_iq, progress=bar.update,
                          **options)
    sigs = {name: r.signature for name, r in result.links.items()}
    config = {"motion": motion.params, "radar": radar.model_dump(mode="json"), "backend": args.backend,
              "backend_options": options,
              "angle_deg": angle, "direction": None if args.angle_deg is not None else args.direction}
    link_attrs = {link.name: {"tx": link.tx_pos, "rx": link.rx_pos} for link in radar.links}
    out = write_signature_file(
        args.out / "signature.h5", sigs, activity=args.activity, backend=args.backend, seed=args.seed,
        direction_deg=angle, config=config, link_attrs=link_attrs,
        iq={n: r.iq for n, r in result.links.items()} if args.keep_iq else None)
    print(f"wrote {out}")
    if not args.no_plots:
        for png in plot_all(sigs, args.out, title=f"{args.activity} ({args.backend}, {angle:g} deg)"):
            print(f"wrote {png}")
    return 0


def _add_render(sub) -> None:
    p = sub.add_parser("render", help="render the scene (skinned body, radars) to PNG/GIF",
                       description="Render the skinned avatar at chosen frames with the radar positions "
                       "(Mitsuba, the ray tracer's own renderer), plus an animation strip of the activity.")
    _add_motion_args(p)
    p.add_argument("--out", required=True, type=Path, help="scene PNG to write")
    p.add_argument("--strip", type=Path, help="also write an animation strip (.png) or animation (.gif)")
    p.add_argument("--frames", type=int, nargs="+", help="frame indices (default: 5 evenly spaced)")
    add_radar_args(p)
    p.add_argument("--lod", default="10k", help="avatar level of detail: full, 10k, 5k, 2k (default 10k)")
    p.set_defaults(func=cmd_render)


def cmd_render(args) -> int:
    from rtchannel.render import render_scene, render_strip

    radar, _ = load_radar(args)
    motion = _build_motion(args)
    frames = args.frames or list(np.linspace(0, motion.n_frames - 1, 5).round().astype(int))
    bad = [f for f in frames if not 0 <= f < motion.n_frames]
    if bad:
        raise UserError(f"frames {bad} outside 0..{motion.n_frames - 1}")
    antennas = [p for link in radar.links for p in {tuple(link.tx_pos), tuple(link.rx_pos)}]
    print(f"wrote {render_scene(motion, frames, antennas, args.out, lod=args.lod)}")
    if args.strip:
        print(f"wrote {render_strip(motion, args.strip, radar_positions=antennas)}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="rtchannel", description="Motion-capture driven MIMO radar simulator.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_simulate(sub)
    _add_render(sub)
    from rtchannel.bench_cli import add_bench
    from rtchannel.classify_cli import add_classifier_commands
    from rtchannel.compare_cli import add_compare
    from rtchannel.dataset_cli import add_dataset

    add_dataset(sub)
    add_classifier_commands(sub)
    add_compare(sub)
    add_bench(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)

    def one_line_warning(message, category, filename, lineno, file=None, line=None):
        print(f"warning: {message}", file=sys.stderr)

    warnings.showwarning = one_line_warning
    try:
        return args.func(args)
    except UserError as e:
        print(f"error: {e}", file=sys.stderr)
    except ValidationError as e:
        print(f"error: {_validation_line(e, 'invalid value')}", file=sys.stderr)
    except (ValueError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
    except Exception as e:  # noqa: BLE001 - any library failure surfaces as one clear line
        if type(e).__name__ == "LLVMNotFoundError":
            print(f"error: {e}", file=sys.stderr)
        else:
            raise
    return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
