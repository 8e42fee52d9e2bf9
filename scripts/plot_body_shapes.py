"""Draw a few body shapes side by side, front and side views: docs/img/body_shapes.png.

    python scripts/plot_body_shapes.py [--out docs/img/body_shapes.png]

Each body is the avatar in a `rtchannel.body.shape.BodyShape` at its stature (rest pose, 2k mesh for speed
of drawing), shaded by the facets' normals; a ruler marks metres.
"""
import argparse
import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from PIL import Image  # noqa: E402

from rtchannel.body.avatar import load_avatar  # noqa: E402
from rtchannel.body.shape import BodyShape  # noqa: E402
from rtchannel.body.shaped_avatar import shaped_vertices  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
BODIES = (  # (label, shape, stature m)
    ("base mesh\n(today's avatar)", None, 1.70),
    ("woman 25 y\nBMI 18", BodyShape(sex="female", age_years=25, bmi=18), 1.65),
    ("woman 70 y\nBMI 31", BodyShape(sex="female", age_years=70, bmi=31), 1.58),
    ("woman 40 y\nBMI 40", BodyShape(sex="female", age_years=40, bmi=40, muscle=0.2), 1.62),
    ("man 22 y\nBMI 22, muscle 1", BodyShape(sex="male", age_years=22, bmi=22, muscle=1.0), 1.85),
    ("man 50 y\nBMI 27", BodyShape(sex="male", age_years=50, bmi=27, proportions=0.2), 1.76),
    ("man 85 y\nBMI 35", BodyShape(sex="male", age_years=85, bmi=35), 1.70),
)
LOD = "5k"
SPACING_M = 1.0  # between the bodies (the A-pose spans ~0.9 m)


def _draw(ax, v: np.ndarray, f: np.ndarray, axis: int, x0: float) -> None:
    """Triangles projected along `axis` (0: front view, looking along -x; 1: side view), painter-sorted."""
    light = np.array([0.6, 0.3, 0.75]) / np.linalg.norm([0.6, 0.3, 0.75])
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-30
    toward = np.zeros(3)
    toward[axis] = 1.0
    order = np.argsort(tri[:, :, axis].mean(axis=1))  # farthest first
    h = 1 - axis  # the horizontal coordinate of the view: y in the front view, x in the side view
    sign = -1.0 if axis == 0 else 1.0  # front view: the body's left (+y) on the picture's right
    polys = np.stack([x0 + sign * tri[order][:, :, h], tri[order][:, :, 2]], axis=-1)
    shade = 0.35 + 0.6 * np.clip(n[order] @ light, 0, 1)
    facing = n[order] @ toward > 0
    colour = np.where(facing[:, None], shade[:, None] * np.array([0.93, 0.78, 0.66]), 0.3)
    ax.add_collection(PolyCollection(polys, facecolors=colour, edgecolors="none"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "img" / "body_shapes.png")
    args = ap.parse_args()
    faces = load_avatar(LOD).faces
    fig, (front, side) = plt.subplots(2, 1, figsize=(14, 9), constrained_layout=True)
    for k, (label, shape, stature) in enumerate(BODIES):
        if shape is None:
            v = load_avatar(LOD, stature).vertices
        else:
            v = shaped_vertices(LOD, shape.key(stature), stature)
        x0 = SPACING_M * k
        _draw(front, v, faces, 0, x0)
        _draw(side, v, faces, 1, x0)
        m = None if shape is None else dict(shape.key(stature))
        extra = "" if m is None else f"\nMH muscle {m['mh_muscle']:.2f}\nMH weight {m['mh_weight']:.2f}"
        front.text(x0, 1.95, f"{label}, {stature:.2f} m{extra}", ha="center", va="bottom", fontsize=7.5)
    for ax, title in ((front, "front"), (side, "side (facing right)")):
        ax.set_xlim(-0.5, SPACING_M * (len(BODIES) - 1) + 0.5)
        ax.set_ylim(-0.05, 2.45)
        ax.set_aspect("equal")
        ax.set_yticks(np.arange(0, 2.01, 0.5))
        ax.set_xticks([])
        ax.set_ylabel("height [m]")
        ax.grid(axis="y", lw=0.4, alpha=0.5)
        ax.set_title(title, fontsize=9, loc="left")
    fig.suptitle("Body shapes on the same skinned mesh (MakeHuman macro targets; BMI from volume x density)",
                 fontsize=10)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    buf = io.BytesIO()
    fig.savefig(buf, dpi=100)
    # a 128-colour palette: the shading needs no more, and the file is a third the size
    Image.open(buf).convert("RGB").quantize(128).save(args.out, optimize=True)
    print(args.out)


if __name__ == "__main__":
    main()
