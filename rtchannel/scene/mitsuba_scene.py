"""A Sionna RT scene file loaded with Mitsuba alone, for the ray casts of the `facets` backend.

`import sionna.rt` costs 0.4-0.6 s of every `rtchannel simulate --backend facets` process (its package
imports matplotlib.pyplot, IPython, ipywidgets and pythreejs for its previews and rewrites its kernels'
source with Dr.Jit's AST pass), while the facets backend needs only the geometry and, of the radio materials,
the walls' slab parameters. Sionna RT registers its radio materials as Mitsuba BSDF plugins when it is
imported; here one small plugin of our own (`PLUGIN`) stands in for them, the scene XML is rewritten to name
it, and the materials' parameters are evaluated as Sionna RT 2.2 does:

- `rewrite_materials` follows `sionna.rt.scene_utils.process_xml`: a BSDF whose id (after a ``mat-`` prefix)
  starts with ``itu_``/``itu-`` is the ITU material of that name (or of its ``type`` string), thickness from
  its ``thickness`` float or `DEFAULT_THICKNESS`; ``radio-material`` and ``itu-radio-material`` BSDFs keep their
  properties; top-level materials are copied into the shapes that reference them. Anything else (other
  BSDF types, ``<include>``d files, whose text is not rewritten, shapes without a radio material) raises
  `NeedsSionna`: the caller then loads the scene through Sionna RT.
- `load` reads each shape's material and then swaps it for a plain ``diffuse`` BSDF, so no stand-in
  material outlives the load (Sionna RT's solver traces calls over every live BSDF of the process).
- `slab_parameters`: ``radio-material`` as `sionna.rt.RadioMaterial` reads its properties (defaults 1, 0 and
  `DEFAULT_THICKNESS`; float32 like Sionna's ``mi.Float``); ITU materials as `sionna.rt.radio_materials.itu.
  itu_material` at the scene frequency (``a f_GHz^b``, ``c f_GHz^d`` in Dr.Jit float32, same operations).
- `object_id`: Sionna's ``SceneObject.object_id`` (the shape pointer reinterpreted as UInt32).

tests/test_rt_scene.py loads the room and a furnished scene both ways and requires the same objects, ids,
static meshes and walls bit for bit, and the ITU table below to equal Sionna's: a Sionna update that changes
any of this fails there.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from copy import deepcopy
from typing import Any

from processing.errors import InputError

PLUGIN = "rtchannel-radio-material"
DEFAULT_THICKNESS = 0.1  # [m], sionna.rt.constants.DEFAULT_THICKNESS
_KIND = "rtchannel_sionna_type"  # string property naming the Sionna plugin the BSDF stands for

# ITU-R P.2040-4, Section 2.1.4 (as `sionna.rt.radio_materials.itu.ITU_MATERIALS_PROPERTIES` of Sionna RT 2.2):
# {name: {(f_min, f_max) [GHz]: (a, b, c, d)}}, eps_r' = a f_GHz^b, sigma = c f_GHz^d [S/m].
ITU_MATERIALS_PROPERTIES = {
    "vacuum": {(0.001, 100.): (1.0, 0.0, 0.0, 0.0)},
    "concrete": {(1., 100.): (5.24, 0.0, 0.0462, 0.7822), (110., 330.): (5.17, 0.0, 0.0145, 1.0900)},
    "brick": {(1., 40.): (3.91, 0.0, 0.0238, 0.16), (110., 330.): (4.15, 0.0, 0.0006, 1.5712)},
    "plasterboard": {(1., 100.): (2.73, 0.0, 0.0085, 0.9395), (110., 330.): (2.56, 0.0, 0.0001, 1.7799),
                     (100., 400.): (2.65, 0.0, 0.0002, 1.598)},
    "wood": {(0.001, 100.): (1.99, 0.0, 0.0047, 1.0718), (110., 330.): (1.82, 0.0, 0.0040, 1.0761),
             (100., 400.): (2.1183, 0.0, 0.0055, 1.1113)},
    "glass": {(0.1, 100.): (6.31, 0.0, 0.0036, 1.3394), (220., 450.): (5.79, 0.0, 0.0004, 1.658),
              (100., 400.): (6.5767, 0.0, 0.0012, 1.4697)},
    "clear_acrylic": {(110., 330.): (2.58, 0.0, 0.0001, 1.6524)},
    "ceiling_board": {(1.0, 100.): (1.48, 0.0, 0.0011, 1.0750), (220., 450.): (1.52, 0.0, 0.0029, 1.029),
                      (100., 400.): (1.2567, 0.0, 0.00013, 1.454)},
    "chipboard": {(1.0, 100.): (2.58, 0.0, 0.0217, 0.7800), (100., 200.): (2.16, 0.0, 0.0023, 1.359)},
    "plywood": {(1.0, 40.): (2.71, 0.0, 0.33, 0.0), (110., 330.): (1.94, 0.0, 0.0067, 0.9982),
                (100., 400.): (2.17, 0.0, 0.0063, 1.045)},
    "marble": {(1.0, 60.): (7.074, 0.0, 0.0055, 0.9262), (110., 330.): (7.94, 0.0, 0.0001, 1.7330),
               (100., 400.): (8.62, 0.0, 0.0027, 1.15)},
    "floorboard": {(50., 100.): (3.66, 0.0, 0.0044, 1.3515), (220., 300.): (5.27, 0.0, 2.22e-17, 7.3413),
                   (300., 400.): (5.27, 0.0, 0.0003, 2.0298), (400., 450.): (5.27, 0.0, 49.8726, 0.0),
                   (100., 400.): (3.1575, 0.0, 0.001675, 1.32775)},
    "vinyl_tile": {(1.0, 40.): (3.62, 0.0, 0.0051, 0.8422)},
    "carpet_tile": {(1.0, 40.): (2.08, 0.0, 0.0009, 0.8200)},
    "asphalt_concrete": {(1.0, 40.): (4.83, 0.0, 0.0108, 1.3969)},
    "metal": {(1.0, 100.): (1.0, 0.0, 1e7, 0.0)},
    "very_dry_ground": {(1.0, 10.): (3.0, 0.0, 0.00015, 2.52)},
    "medium_dry_ground": {(1.0, 10.): (15., -0.1, 0.035, 1.63)},
    "wet_ground": {(1.0, 10.): (30., -0.4, 0.15, 1.30)},
}


class NeedsSionna(Exception):
    """The scene uses something only Sionna RT's own loader handles; load it through Sionna RT."""


def rewrite_materials(xml: str) -> str:
    """The scene XML with every radio material replaced by `PLUGIN` (see the module doc); raises NeedsSionna."""
    root = ET.fromstring(xml)
    if root.find(".//include") is not None:
        raise NeedsSionna("included files keep Sionna's plugin names")
    for bsdf in root.iter("bsdf"):
        kind, mat_id = bsdf.attrib.get("type"), bsdf.attrib.get("id")
        name = mat_id[4:] if mat_id is not None and mat_id.startswith("mat-") else mat_id
        if name is not None and (name.startswith("itu_") or name.startswith("itu-")):
            thickness = DEFAULT_THICKNESS
            prop = bsdf.find("float[@name='thickness']")
            if prop is not None:
                thickness = float(prop.get("value", thickness))
            prop = bsdf.find("string[@name='type']")
            itu_type = prop.get("value") if prop is not None else name[4:]
            if itu_type is None:  # Sionna's loader reads it as the material "None" and names the error
                raise NeedsSionna("an ITU material's type has no value")
            bsdf.clear()
            bsdf.attrib.update({"type": PLUGIN, "id": str(mat_id)})
            for tag, pname, value in (("string", _KIND, "itu-radio-material"), ("string", "type", itu_type),
                                      ("float", "thickness", str(thickness))):
                bsdf.append(ET.Element(tag, {"name": pname, "value": value}))
        elif kind in ("radio-material", "itu-radio-material"):
            if name in ITU_MATERIALS_PROPERTIES and kind != "itu-radio-material":
                raise NeedsSionna("Sionna rejects an ITU material name without the itu_ prefix")
            bsdf.attrib["type"] = PLUGIN
            bsdf.insert(0, ET.Element("string", {"name": _KIND, "value": kind}))
        else:
            raise NeedsSionna(f"BSDF type {kind!r}")
    _inline_top_level_bsdfs(root)
    return ET.tostring(root, encoding="unicode")


def _inline_top_level_bsdfs(root) -> None:
    """Replace each shape's ``<ref>`` to a top-level BSDF by a copy of it and drop the top-level ones: a
    Mitsuba scene keeps its top-level objects alive, and our stand-in materials must not outlive the load
    (`load`). Refs from anywhere but a shape raise NeedsSionna."""
    top = {b.get("id"): b for b in root.findall("bsdf")}
    for b in top.values():
        root.remove(b)
    inlined = set()
    for shape in root.iter("shape"):
        for i, child in enumerate(list(shape)):
            if child.tag == "ref" and child.get("id") in top:
                copy = deepcopy(top[child.get("id")])
                copy.attrib.pop("id", None)
                if child.get("name") is not None:
                    copy.set("name", child.get("name"))
                shape.remove(child)
                shape.insert(i, copy)
                inlined.add(id(child))
    for ref in root.iter("ref"):
        if ref.get("id") in top and id(ref) not in inlined:
            raise NeedsSionna("a material referenced outside a shape")


_REGISTERED: list = []


def register_plugin(mi: Any):
    """Register `PLUGIN` with Mitsuba (once per process); returns its class. Its instances keep the BSDF's
    properties as `values` {name: value}."""
    if _REGISTERED:
        return _REGISTERED[0]
    bsdf: Any = mi.BSDF  # the variant's class, known at run time only

    class CapturedRadioMaterial(bsdf):
        def __init__(self, props):
            super().__init__(props)
            self.values = {k: props[k] for k in props.keys()}  # reading marks every property as used

    mi.register_bsdf(PLUGIN, lambda props: CapturedRadioMaterial(props))
    _REGISTERED.append(CapturedRadioMaterial)
    return CapturedRadioMaterial


def load(xml: str, mi):
    """(Mitsuba scene, [(shape id, mesh, material values)]) of a scene XML (after `rewrite_materials`), shapes in
    Mitsuba's order (Sionna's object order); raises NeedsSionna for a shape without one of our materials.

    Each shape then gets a plain ``diffuse`` BSDF in place of ours (ray casts never look at it): Dr.Jit keeps
    every live BSDF in one registry, and Sionna RT's path solver traces its method calls over all of them,
    so an instance of `PLUGIN` (which implements none) left alive would break a Sionna RT trace of another
    scene in the same process (tests/test_rt_scene.py)."""
    cls = register_plugin(mi)
    scene = mi.load_string(xml, optimize=False)  # as sionna.rt.load_scene_from_string
    shapes = []
    for s in scene.shapes():
        bsdf = s.bsdf()
        if not isinstance(s, mi.Mesh) or not isinstance(bsdf, cls):
            raise NeedsSionna(f"shape {s.id()!r} is not a mesh with a radio material")
        shapes.append((s.id(), s, bsdf.values))
    plain = mi.load_dict({"type": "diffuse"})
    for _, s, _ in shapes:
        s.set_bsdf(plain)
    return scene, shapes


def slab_parameters(mi, dr, values: dict, frequency_hz: float) -> tuple[float, float, float]:
    """(eps_r', sigma [S/m], thickness [m]) of a captured material at `frequency_hz`, as Sionna RT evaluates
    them (float32); ValueError for values Sionna rejects."""
    if values.get(_KIND) == "itu-radio-material":
        itu_type = values.get("type")
        if itu_type not in ITU_MATERIALS_PROPERTIES:
            raise InputError(f"Invalid ITU material type \"{itu_type}\"")
        f_ghz = mi.Float(frequency_hz) / 1e9
        for (lo, hi), (a, b, c, d) in ITU_MATERIALS_PROPERTIES[itu_type].items():
            if lo <= f_ghz <= hi:
                break
        else:
            raise InputError(f"Properties of ITU material '{itu_type}' are not defined for this frequency")
        eps, sigma = a * dr.power(f_ghz, b), c * dr.power(f_ghz, d)
    else:
        eps, sigma = mi.Float(values.get("relative_permittivity", 1.0)), mi.Float(values.get("conductivity", 0.0))
    thickness = mi.Float(values.get("thickness", DEFAULT_THICKNESS))
    eps, sigma, thickness = float(eps[0]), float(sigma[0]), float(thickness[0])
    if eps < 1.0 or sigma < 0.0 or thickness < 0.0:
        raise InputError("radio material with relative permittivity < 1, negative conductivity or thickness")
    return eps, sigma, thickness


def object_id(mi, dr, shape) -> int:
    """Sionna RT's object id of a shape (``SceneObject.object_id``: its pointer reinterpreted as UInt32)."""
    return int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0])


__all__ = ["DEFAULT_THICKNESS", "ITU_MATERIALS_PROPERTIES", "NeedsSionna", "PLUGIN", "load", "object_id",
           "register_plugin", "rewrite_materials", "slab_parameters"]
