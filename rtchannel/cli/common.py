"""What every `rtchannel` command shares: the user-error type, argument groups for motion and radar,
option parsing, and building the API objects (`Motion`, `Radar`) from arguments."""
from __future__ import annotations

import argparse
import math
from pathlib import Path

from pydantic import ValidationError

EXIT_USAGE = 2


class UserError(Exception):
    """A problem with what the user asked for; printed as one line, exit status 2."""


class OneLineParser(argparse.ArgumentParser):
    """argparse with the project's error contract: a bad argument is one line on stderr, exit status 2
    (argparse's own default prints the usage first: two lines)."""

    def error(self, message):  # noqa: D102 - argparse hook
        self.exit(EXIT_USAGE, f"error: {self.prog}: {message}\n")


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {value}")
    return value


MAX_SEED = 2 ** 63 - 1  # seeds are stored as 64-bit integers (HDF5 attributes, numpy generators)


def seed_int(text: str) -> int:
    """argparse type: a random seed, an integer 0..2^63-1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer 0..2^63-1, got {text!r}") from None
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"must be an integer 0..2^63-1, got {value}")
    return value


def finite_float(text: str) -> float:
    """argparse type: a finite number (no nan/inf)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
    return value


def validation_line(err: ValidationError, what: str) -> str:
    """One line naming the first invalid field of a pydantic error (and how many more there are)."""
    first = err.errors()[0]
    loc = ".".join(str(x) for x in first.get("loc", ())) or "(root)"
    more = f" (and {err.error_count() - 1} more)" if err.error_count() > 1 else ""
    return f"{what}: {loc}: {first.get('msg', 'invalid value')}{more}"


def add_motion_args(p) -> None:
    """Arguments choosing a procedural activity or a motion-capture file (read by `build_motion`)."""
    p.add_argument("--activity", default="walk", help="fall, walk, stand, sit or pick (default walk)")
    p.add_argument("--motion-file", type=Path, help="motion capture instead of a procedural motion: BVH (CMU, iClone "
                   "rigs), C3D (CMU 41 markers, Vicon plug-in-gait) or AMC (with --skeleton)")
    p.add_argument("--skeleton", type=Path, help="--motion-file take.amc: its ASF skeleton file")
    p.add_argument("--up", choices=("x", "y", "z", "-x", "-y", "-z"),
                   help="--motion-file: the file's up axis (default: ASF/AMC and OpenCap y; BVH and C3D guessed "
                   "from head above feet over the whole take)")
    p.add_argument("--height", type=finite_float, default=1.75, help="body height [m] (default 1.75)")
    p.add_argument("--speed", type=finite_float, help="walking speed [m/s] (procedural walk only)")
    p.add_argument("--duration", type=finite_float, help="activity duration [s] (procedural)")
    p.add_argument("--distance", type=finite_float, help="walking distance [m] (procedural walk only, default 4)")
    p.add_argument("--start", type=finite_float, nargs=2, metavar=("X", "Y"),
                   help="start of the hips' ground point [m]; default: walks (procedural or --motion-file "
                   "--activity walk) are centred on the origin, other activities start at the origin")
    p.add_argument("--heading", type=finite_float, metavar="DEG",
                   help="direction the person faces at the start [deg, counter-clockwise from +x, toward "
                   "Radar 1 at direction 1]; default 0")
    p.add_argument("--trim", type=finite_float, nargs=2, metavar=("START", "END"),
                   help="--motion-file: keep only START..END seconds of the take (e.g. one sit-down of a "
                   "longer recording)")
    p.add_argument("--fall-direction", choices=("forward", "left", "right", "backward"),
                   help="procedural fall: the direction (default: from --seed, seed mod 3 = forward, left, right)")
    p.add_argument("--fps", type=finite_float, default=60.0, help="motion frame rate [Hz] (default 60)")
    p.add_argument("--seed", type=seed_int, default=0, help="random seed, 0..2^63-1 (default 0)")


RADAR_PRESETS = ("seed", "glasgow")


def add_radar_args(p) -> None:
    """--radar/--radar-config, the Glasgow geometry and the mutually exclusive --direction / --angle-deg
    (read by `load_radar`)."""
    r = p.add_mutually_exclusive_group()
    r.add_argument("--radar", choices=RADAR_PRESETS, help="radar preset: seed (default; the seed's 2x2 at "
                   "24.125 GHz) or glasgow (one 5.8 GHz Ancortek 580AD with Yagis and the Glasgow DSP, "
                   "Radar.glasgow)")
    r.add_argument("--radar-config", type=Path, help="YAML/JSON radar configuration (waveform, dsp, links)")
    p.add_argument("--radar-height", type=finite_float, help="--radar glasgow: antenna height [m], 0.5-2 "
                   "(default 1.0)")
    p.add_argument("--radar-distance", type=finite_float, help="--radar glasgow: distance to the person [m], "
                   "1-4 (default 2.5)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--direction", type=int, default=1, help="seed direction 1..18 (Radar 1 at 20(k-1) deg)")
    g.add_argument("--angle-deg", type=finite_float, help="rotate all radars by this angle about z instead [deg]")


def check_output(path: Path | None, kind: str = "dir") -> None:
    """Refuse, before any work, an output that cannot be written: `kind` "dir" (a folder the command
    fills; created here) or "file" (its folder is created). Names the path; catches an existing file
    where a folder is needed (and the reverse), a read-only location and a full device (a probe write)."""
    import os
    import uuid

    if path is None:
        return
    path = Path(path)
    folder = path if kind == "dir" else path.parent
    if kind == "dir" and path.exists() and not path.is_dir():
        raise UserError(f"--out {path}: exists and is not a folder")
    if kind == "file" and path.is_dir():
        raise UserError(f"--out {path}: is a folder, expected a file name")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f".rtchannel-probe-{os.getpid()}-{uuid.uuid4().hex[:6]}"
        with open(probe, "wb") as f:
            f.write(b"\0" * 4096)
            f.flush()
            os.fsync(f.fileno())
        probe.unlink()
    except OSError as e:
        raise UserError(f"--out {path}: cannot write there ({e.strerror or e})") from None


def output_file(path: Path, suffix: str) -> Path:
    """The file an ``--out FILE`` names, `suffix` (".pt", ".csv") added when it has none; UserError for an
    existing folder (which would otherwise give FOLDER.pt beside it, outside what --out names)."""
    path = Path(path)
    if path.is_dir():
        raise UserError(f"--out {path}: is a folder, expected a file name ({suffix})")
    return path if path.suffix else path.with_suffix(suffix)


def split_list(values: list[str] | None) -> list[str]:
    """Items given space- or comma-separated (``--backends points,facets`` = ``--backends points facets``)."""
    return [v for item in values or [] for v in item.split(",") if v]


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
        try:
            parsed = yaml.safe_load(value)
        except yaml.YAMLError as e:
            mark = getattr(e, "problem_mark", None)
            where = f" at character {mark.column + 1}" if mark is not None else ""
            raise UserError(f"--option {item[:80]}: the value is not a YAML scalar{where} "
                            f"({getattr(e, 'problem', None) or 'syntax error'})") from None
        except RecursionError:  # PyYAML's composer recurses per nesting level: a run of '[' ends here
            raise UserError(f"--option {key}: the value is not a YAML scalar (nested too deeply)") from None
        (out.setdefault(backend, {}) if per_backend else out)[name] = parsed
    return out


def checked_options(items: list[str] | None, backends: list[str]) -> dict[str, dict]:
    """``--option BACKEND.NAME=VALUE`` items parsed and validated for each of `backends` (names, types),
    before any simulation runs: {backend: {name: value}}. UserError (one line) otherwise."""
    from rtchannel.backends import RESERVED_OPTIONS, validate_options

    options = parse_options(items, per_backend=True)
    unknown = [b for b in options if b not in backends]
    if unknown:
        raise UserError(f"--option for backend '{unknown[0]}' which is not in {', '.join(backends)}")
    for b, opts in options.items():
        try:
            validate_options(b, opts, reserved=RESERVED_OPTIONS + ("scene",))
        except ValueError as e:
            raise UserError(f"--option {b}.{e}" if str(e).startswith("backend option") else str(e)) from None
    return options


def load_radar(args):
    """The radar of --radar (preset) or --radar-config (default: the seed's 2x2) rotated by --angle-deg or
    --direction. Raises UserError (or ConfigError for a Glasgow height/distance out of range), one line."""
    from rtchannel.radar import RadarConfig, direction_angles

    if args.radar_config is not None and not args.radar_config.is_file():
        raise UserError(f"radar config file not found: {args.radar_config}")
    preset = getattr(args, "radar", None)
    geometry = {k: v for k, v in (("height_m", getattr(args, "radar_height", None)),
                                  ("distance_m", getattr(args, "radar_distance", None))) if v is not None}
    if geometry and preset != "glasgow":
        raise UserError("--radar-height/--radar-distance apply to --radar glasgow only")
    try:
        if preset == "glasgow":
            radar = RadarConfig.glasgow(**geometry)
        else:
            radar = RadarConfig.from_file(args.radar_config) if args.radar_config else RadarConfig()
    except ValidationError as e:
        raise UserError(validation_line(e, f"radar config {args.radar_config}")) from None
    if args.angle_deg is not None and not (math.isfinite(args.angle_deg) and abs(args.angle_deg) <= 3600):
        raise UserError(f"--angle-deg must be a finite angle within +-3600 deg, got {args.angle_deg}")
    try:
        angle = args.angle_deg if args.angle_deg is not None else direction_angles(args.direction)[0]
    except ValueError as e:
        raise UserError(f"--direction: {e}") from None
    return radar.rotated(angle), angle


def build_motion(args):
    """The motion the user asked for: a motion-capture file or a procedural activity."""

    from rtchannel.motion.pose import Motion

    heading = getattr(args, "heading", None)
    trim = getattr(args, "trim", None)
    if args.motion_file is not None:
        from rtchannel.motion.compose import place_take  # here: a procedural activity never needs scipy.spatial

        if getattr(args, "fall_direction", None) is not None:
            raise UserError("--fall-direction applies to a procedural fall, not to --motion-file")
        given = [f"--{n}" for n in ("speed", "duration", "distance") if getattr(args, n, None) is not None]
        if given:  # a take has its own pace and length (--trim cuts it)
            raise UserError(f"{given[0]} applies to a procedural activity, not to --motion-file (use --trim to cut "
                            "a take)")
        if not args.motion_file.is_file():
            raise UserError(f"motion file not found: {args.motion_file}")
        skeleton = getattr(args, "skeleton", None)
        if skeleton is not None and not skeleton.is_file():
            raise UserError(f"skeleton file not found: {skeleton}")
        extra = {} if skeleton is None else {"skeleton": skeleton}
        if getattr(args, "up", None) is not None:
            extra["up"] = args.up
        from rtchannel.motion.source import check_fps

        check_fps(args.fps, "--fps")  # the bounds of procedural motions, before the take is read
        motion = Motion.from_file(args.motion_file, height=args.height, activity=args.activity, **extra)
        motion = place_take(motion, start=args.start, heading_deg=heading, trim=trim)
        return motion if args.fps == motion.fps else motion.resampled(args.fps)
    if trim is not None:
        raise UserError("--trim applies to --motion-file; a procedural activity takes --duration")
    for name in ("up", "skeleton"):
        if getattr(args, name, None) is not None:
            raise UserError(f"--{name} applies to --motion-file, not to a procedural activity")
    params = {k: v for k, v in (("speed", args.speed), ("duration", args.duration),
                                ("distance", args.distance)) if v is not None}
    direction = getattr(args, "fall_direction", None)
    if direction is not None:
        if args.activity != "fall":
            raise UserError(f"--fall-direction applies to --activity fall, not {args.activity!r}")
        params["fall_direction"] = direction
    if args.start is not None:
        params["start"] = tuple(args.start)
    if heading is not None:
        params["heading_deg"] = heading
    try:
        return Motion.procedural(args.activity, height=args.height, fps=args.fps, seed=args.seed, **params)
    except ValidationError as e:
        raise UserError(validation_line(e, "motion parameters")) from None


def add_accuracy_args(p) -> None:
    """--accuracy and --calibration (read by `accuracy_kwargs`)."""
    p.add_argument("--accuracy", metavar="BUDGET", help="mesh backends: fast, balanced, exact or an EMD [m/s]; the "
                   "cheapest calibrated settings within it are used and stored with the signature (rtchannel.accuracy)")
    p.add_argument("--calibration", type=Path, help="with --accuracy: a calibration table from `rtchannel bench "
                   "--calibrate` (default: the shipped table of the radar's carrier and range bin)")


def accuracy_kwargs(args) -> dict:
    """{"accuracy", "calibration"} for `simulate` from --accuracy/--calibration (empty without --accuracy);
    a bad budget or a missing table file is a one-line UserError."""
    from rtchannel.accuracy import parse_budget

    if getattr(args, "accuracy", None) is None:
        if getattr(args, "calibration", None) is not None:
            raise UserError("--calibration needs --accuracy")
        return {}
    try:
        budget = parse_budget(args.accuracy)
    except ValueError as e:
        raise UserError(f"--accuracy: {e}") from None
    if args.calibration is not None and not args.calibration.is_file():
        raise UserError(f"--calibration: file not found: {args.calibration}")
    return {"accuracy": budget, "calibration": args.calibration}
