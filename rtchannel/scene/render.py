"""Look at a motion: Mitsuba renders of the skinned avatar on a floor, with the radars as spheres.

For inspection, not for simulation: an RGB path tracer (variant ``llvm_ad_rgb``), a checkered 1 m
floor grid, soft sky light plus a sun, a fixed camera chosen from the scene's extent (or given).
`render_scene` can add the static geometry the ray tracer uses (walls, floor, furniture of a `Scene`):
walls that stand between the camera and the room are left out (an architectural cut-away), so the
body stays visible.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from processing.atomic import atomic_path
from processing.constants import DEFAULT_CARRIER_HZ
from processing.errors import InputError
from rtchannel.body.avatar import load_avatar
from rtchannel.motion.pose import Motion
from rtchannel.body.skinning import skin_vertices

_PALETTE = ((0.80, 0.35, 0.25), (0.25, 0.50, 0.80), (0.30, 0.70, 0.35), (0.85, 0.65, 0.20),
            (0.60, 0.35, 0.75), (0.20, 0.70, 0.70), (0.75, 0.45, 0.55), (0.55, 0.55, 0.55))
_RADAR_COLOUR = (0.95, 0.05, 0.05)



# output formats by file extension: what each writer can produce (others are refused up front, so a file's
# name always says what it holds)
SCENE_FORMATS = {".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG", ".exr": "OpenEXR"}
STRIP_FORMATS = {".png": "PNG", ".gif": "GIF"}


def check_format(path, formats: dict, what: str) -> None:
    """InputError (one line) unless `path`'s extension is one of `formats`."""
    suffix = Path(path).suffix.lower()
    if suffix not in formats:
        raise InputError(f"{path}: cannot write the {what} as '{suffix or 'no extension'}'; use "
                         f"{', '.join(formats)}")

def _mi():
    from rtchannel.scene.llvm import import_mitsuba

    return import_mitsuba("llvm_ad_rgb")


def _mesh(mi, name: str, vertices: np.ndarray, faces: np.ndarray, colour):
    props = mi.Properties()
    props["bsdf"] = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": list(colour)}})
    mesh = mi.Mesh(name, len(vertices), len(faces), props=props, has_vertex_normals=True)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(np.asarray(vertices, np.float32).ravel())
    params["faces"] = mi.UInt32(np.asarray(faces, np.uint32).ravel())
    params.update()
    mesh.recompute_vertex_normals()
    return mesh


def default_camera(points: np.ndarray, fov_deg: float = 40.0, aspect: float = 4 / 3) -> tuple[np.ndarray, np.ndarray]:
    """(origin, target) of a camera seeing all `points` [N, 3] from the front-left, above eye level (m)."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    target = 0.5 * (lo + hi)
    target[2] = 0.45 * max(hi[2], 1.0)
    radius = 0.5 * np.linalg.norm(hi - lo) + 0.1
    direction = np.array([0.5, -1.0, 0.6])
    direction /= np.linalg.norm(direction)
    half_x = np.radians(fov_deg) / 2  # Mitsuba's fov is horizontal
    half = min(half_x, np.arctan(np.tan(half_x) / aspect))
    dist = radius / np.sin(half)
    return target + dist * direction, target


def _static_geometry(scene, height: float, frequency_hz: float, camera_origin) -> list:
    """(vertices, faces, colour) of the scene's static geometry as the ray tracer loads it, minus the walls
    the camera looks through from outside the room."""
    from rtchannel.scene.rt_scene import get_scene

    rt = get_scene(scene, "2k", height, frequency_hz, sionna=False)  # geometry only: no Sionna RT import
    hidden = {w.name for w in rt.walls
              if "#" not in w.name and float((np.asarray(camera_origin) - w.point) @ w.normal) < 0}
    shapes = []
    for k, (name, v, f) in enumerate(rt.static_meshes):
        if name in hidden:
            continue
        flat = np.ptp(v[:, 2]) < 1e-6  # floors grey, walls sand, furniture wood-brown
        colour = (0.50, 0.30, 0.15) if name.startswith("furniture") else (0.55,) * 3 if flat else (0.78, 0.70, 0.55)
        shapes.append((v, f, colour))
    return shapes


def _scene(mi, bodies, radar_positions, camera, size, spp, floor_extent, static=()):
    (ox, oy, oz), tgt = camera
    c = np.asarray(floor_extent[0])
    half = float(floor_extent[1])
    scene = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 4},
        "sensor": {
            "type": "perspective", "fov": 40.0,
            "to_world": mi.ScalarTransform4f().look_at(origin=[ox, oy, oz], target=list(map(float, tgt)),
                                                       up=[0, 0, 1]),
            "film": {"type": "hdrfilm", "width": int(size[0]), "height": int(size[1]), "rfilter": {"type": "gaussian"}},
            "sampler": {"type": "independent", "sample_count": int(spp)},
        },
        "sky": {"type": "constant", "radiance": {"type": "rgb", "value": [0.55, 0.6, 0.7]}},
        "sun": {"type": "directional", "direction": [-0.4, 0.6, -1.0],
                "irradiance": {"type": "rgb", "value": [2.2, 2.1, 1.9]}},
        "floor": {
            "type": "rectangle",
            "to_world": mi.ScalarTransform4f().translate([float(c[0]), float(c[1]), 0.0]).scale([half, half, 1.0]),
            "bsdf": {"type": "diffuse", "reflectance": {
                "type": "checkerboard", "color0": {"type": "rgb", "value": [0.42, 0.42, 0.40]},
                "color1": {"type": "rgb", "value": [0.62, 0.62, 0.60]},
                "to_uv": mi.ScalarTransform4f().scale([half, half, 1.0])}},
        },
    }
    if static:
        del scene["floor"]  # the scene's own floor replaces the checkered one
    for k, shape in enumerate(static):
        scene[f"static{k}"] = shape
    for k, body in enumerate(bodies):
        scene[f"body{k}"] = body
    for k, p in enumerate(np.atleast_2d(radar_positions) if len(radar_positions) else []):
        scene[f"radar{k}"] = {"type": "sphere", "center": [float(x) for x in p], "radius": 0.08,
                              "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(_RADAR_COLOUR)}}}
        scene[f"mast{k}"] = {"type": "cylinder", "p0": [float(p[0]), float(p[1]), 0.0],
                             "p1": [float(p[0]), float(p[1]), float(p[2])], "radius": 0.015,
                             "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.2, 0.2, 0.2]}}}
    return mi.load_dict(scene)


def _floor(points: np.ndarray) -> tuple[np.ndarray, float]:
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre = np.round(0.5 * (lo + hi))
    return centre, float(np.ceil(max(hi[0] - lo[0], hi[1] - lo[1]) / 2 + 1.5))


def render_scene(motion: Motion, frames, radar_positions, out_png, lod: str = "10k", *,
                 size=(960, 720), spp: int = 32, camera=None, scene=None,
                 frequency_hz: float = DEFAULT_CARRIER_HZ) -> Path:
    """Render the skinned body at several frames (one colour each) with radars as red spheres on masts.

    Args:
        motion: the pose sequence.
        frames: frame indices to show together.
        radar_positions: [[x, y, z], ...] radar positions (m), may be empty.
        out_png: output PNG path.
        lod: avatar level of detail.
        size: image (width, height) in pixels; spp: samples per pixel.
        camera: optional (origin, target) in metres; default sees bodies and radars from the front-left.
        scene: optional `rtchannel.Scene` (or "room", a Mitsuba XML path): draw its static geometry as the
            ray tracer loads it (walls facing the camera from outside are cut away); None: a floor grid.
        frequency_hz: carrier at which the scene's materials are evaluated (geometry only matters here).

    Returns:
        The path written.
    """
    check_format(out_png, SCENE_FORMATS, "scene picture")
    av = load_avatar(lod)
    frames = np.atleast_1d(np.asarray(frames, dtype=int))
    verts = skin_vertices(av, motion, frames)
    radars = np.asarray(radar_positions, float).reshape(-1, 3)
    pts = np.concatenate([verts.reshape(-1, 3), radars, motion.positions[:, 0]])
    camera = camera or default_camera(pts, aspect=size[0] / size[1])
    # the ray tracer's own scene loads in its Mitsuba variant: take its geometry before switching to RGB
    geometry = [] if scene is None else _static_geometry(scene, motion.rig.height, frequency_hz, camera[0])
    mi = _mi()
    static = [_mesh(mi, f"static{k}", v, f, colour) for k, (v, f, colour) in enumerate(geometry)]
    bodies = [_mesh(mi, f"body{k}", v, av.faces, _PALETTE[k % len(_PALETTE)]) for k, v in enumerate(verts)]
    scene = _scene(mi, bodies, radars, camera, size, spp, _floor(pts), static)
    out = Path(out_png)
    suffix = out.suffix.lower()
    # what mi.util.write_bitmap does, but into the atomic temporary (whose .tmp suffix names no format)
    bitmap = mi.util.convert_to_bitmap(mi.render(scene), suffix in (".png", ".jpg", ".jpeg"))
    fmt = SCENE_FORMATS[suffix]
    with atomic_path(out) as tmp:
        bitmap.write(str(tmp), getattr(mi.Bitmap.FileFormat, fmt))
    return out


def render_strip(motion: Motion, out, n: int = 8, lod: str = "5k", *, panel=(240, 360), spp: int = 16,
                 radar_positions=()) -> Path:
    """An animation strip of the whole motion: `n` evenly spaced frames.

    The camera tracks the hips at a fixed offset (the checkered floor shows the travel), so the body
    stays large in each panel. Writes a single-row PNG (``.png``) or an animated GIF (``.gif``); each
    panel is `panel` pixels.
    """
    from PIL import Image, ImageDraw

    check_format(out, STRIP_FORMATS, "animation strip")
    mi = _mi()
    av = load_avatar(lod)
    frames = np.linspace(0, motion.n_frames - 1, n).round().astype(int)
    verts = skin_vertices(av, motion, frames)
    radars = np.asarray(radar_positions, float).reshape(-1, 3)
    pts = np.concatenate([verts.reshape(-1, 3), radars])
    body = _mesh(mi, "body", verts[0], av.faces, _PALETTE[0])
    size = np.max(np.ptp(verts, axis=1), axis=0)  # the largest body extent over the strip, per axis
    cams = []
    for v in verts:
        c = 0.5 * (v.min(axis=0) + v.max(axis=0))
        box = np.array([[c[0] - size[0] / 2, c[1] - size[1] / 2, 0.0],
                        [c[0] + size[0] / 2, c[1] + size[1] / 2, size[2]]])
        cams.append(default_camera(box, aspect=panel[0] / panel[1]))
    scene = _scene(mi, [body], radars, cams[0], panel, spp, _floor(pts))
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith("vertex_positions"))
    cam_key = next((k for k in params.keys() if k.endswith("to_world") and k.startswith("sensor")), None)
    images = []
    for f, v, (origin, target) in zip(frames, verts, cams):
        params[key] = mi.Float(np.asarray(v, np.float32).ravel())
        if cam_key is not None:
            params[cam_key] = mi.Transform4f().look_at(origin=mi.ScalarPoint3f(*map(float, origin)),
                                                       target=mi.ScalarPoint3f(*map(float, target)),
                                                       up=mi.ScalarPoint3f(0, 0, 1))
        params.update()
        bmp = mi.util.convert_to_bitmap(mi.render(scene))
        img = Image.fromarray(np.asarray(bmp)).convert("RGB")
        ImageDraw.Draw(img).text((6, 4), f"t = {f / motion.fps:.2f} s", fill=(0, 0, 0))
        images.append(img)
    out = Path(out)
    if out.suffix.lower() == ".gif":
        with atomic_path(out) as tmp:
            images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:],
                           duration=int(1000 * motion.duration / max(1, n - 1)), loop=0)
    else:
        strip = Image.new("RGB", (panel[0] * n, panel[1]), "white")
        for k, img in enumerate(images):
            strip.paste(img, (k * panel[0], 0))
        with atomic_path(out) as tmp:
            strip.save(tmp, format="PNG")
    return out
