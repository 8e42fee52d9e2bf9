"""`rtchannel render`: a picture of the scene the ray tracer uses, with the body and the radars."""
from __future__ import annotations

from pathlib import Path

from rtchannel.cli.common import UserError, add_motion_args, add_radar_args, build_motion, check_output, load_radar
from rtchannel.cli.simulate import add_chair_arg, scene_with_chair


def add_render(sub) -> None:
    """Register the `render` subcommand."""
    p = sub.add_parser("render", help="render the scene (skinned body, radars) to PNG/GIF",
                       description="Render the skinned avatar at chosen frames with the radar positions "
                       "(Mitsuba, the ray tracer's own renderer), plus an animation strip of the activity.")
    add_motion_args(p)
    p.add_argument("--out", required=True, type=Path, help="scene PNG to write")
    p.add_argument("--strip", type=Path,
                   help="also write an animation strip (.png) or animation (.gif); other extensions are refused")
    p.add_argument("--frames", type=int, nargs="+", help="frame indices (default: 5 evenly spaced)")
    add_radar_args(p)
    p.add_argument("--lod", default="10k", help="avatar level of detail: full, 10k, 5k, 2k (default 10k)")
    p.add_argument("--scene", default="room", help="static geometry to draw: room (default), free_space or a "
                   "Mitsuba XML file (walls facing the camera are cut away)")
    add_chair_arg(p)
    p.set_defaults(func=cmd_render)


def cmd_render(args) -> int:
    import numpy as np

    from rtchannel.scene.render import SCENE_FORMATS, STRIP_FORMATS, check_format, render_scene, render_strip

    check_format(args.out, SCENE_FORMATS, "scene picture (--out)")
    if args.strip is not None:
        check_format(args.strip, STRIP_FORMATS, "animation strip (--strip)")
    radar, _ = load_radar(args)
    check_output(args.out, "file")
    if args.strip is not None:
        check_output(args.strip, "file")
    motion = build_motion(args)
    frames = args.frames or list(np.linspace(0, motion.n_frames - 1, 5).round().astype(int))
    bad = [f for f in frames if not 0 <= f < motion.n_frames]
    if bad:
        raise UserError(f"frames {bad} outside 0..{motion.n_frames - 1}")
    antennas = [p for link in radar.links for p in {tuple(link.tx_pos), tuple(link.rx_pos)}]
    from rtchannel.scene.spec import Scene

    scene = scene_with_chair(Scene(args.scene), motion, args.chair)
    scene.xml_path()  # a missing scene is a one-line user error before any rendering
    png = render_scene(motion, frames, antennas, args.out, lod=args.lod, scene=scene,
                       frequency_hz=radar.waveform.carrier_hz)
    print(f"wrote {png}")
    if args.strip:
        print(f"wrote {render_strip(motion, args.strip, radar_positions=antennas)}")
    return 0
