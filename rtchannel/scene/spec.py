"""`Scene`: what the person moves in — a room, free space or a user's Mitsuba XML file, plus furniture.

A `Scene` is a light description (no Mitsuba is loaded until a mesh backend traces it). The mesh
backends (`facets`, `sionna`) ray-trace the body inside it; the `points` backend is the seed's free-space
model and ignores it. Furniture (`rtchannel.scene.furniture.Furniture`, e.g. the chair `with_chair_for`
places under a sitter) is written with the base scene into a generated, content-addressed scene file
(`xml_path`), so the ray tracer sees it as static geometry: it occludes the body and, being static, its
own returns are what the DSP's clutter removal takes out (see `scenes/README.md`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from processing.errors import InputError


@dataclass(frozen=True)
class Scene:
    """A ray-tracing scene.

    Args:
        source: "room" (8 x 8 m concrete room with floor and 3 m walls, `scenes/room.xml`), "free_space"
            (nothing but the body), a box room of any size "room:X0,X1,Y0,Y1,H" (m, `rtchannel.scene.rooms`)
            or the path of a Mitsuba 3 XML file whose shapes carry radio
            materials (see `scenes/README.md`).
        furniture: static pieces added to the source (`rtchannel.scene.furniture.Furniture`).
    """

    source: str | Path = "room"
    furniture: tuple = field(default=())

    def __post_init__(self):
        from rtchannel.scene.furniture import Furniture

        items = tuple(self.furniture)
        if not all(isinstance(f, Furniture) for f in items):
            raise TypeError("Scene.furniture must hold rtchannel.scene.furniture.Furniture items")
        object.__setattr__(self, "furniture", items)

    @classmethod
    def room(cls) -> "Scene":
        """The default 8 x 8 x 3 m concrete room (ITU-R P.2040 materials)."""
        return cls("room")

    @classmethod
    def free_space(cls) -> "Scene":
        """Nothing but the body."""
        return cls("free_space")

    @classmethod
    def from_xml(cls, path: str | Path) -> "Scene":
        """A user's Mitsuba 3 scene file (its shapes need radio materials; the id "body" is reserved;
        references to other files are sandboxed to its folder).

        Args:
            path: the XML file.
        """
        return cls(Path(path))

    def with_furniture(self, *items) -> "Scene":
        """This scene plus furniture.

        Args:
            *items: `Furniture` pieces, or dicts of its fields.
        """
        from rtchannel.scene.furniture import Furniture

        new = tuple(f if isinstance(f, Furniture) else Furniture(**f) for f in items)
        return replace(self, furniture=self.furniture + new)

    @classmethod
    def for_motion(cls, motion, scene=None, chair: str = "auto") -> "Scene | None":
        """The scene for a motion: with ``chair="auto"`` and a sit/stand motion, the scene plus the chair placed
        by `chair_fit.chair_for`; otherwise the scene unchanged (None stays None: the backend's default).

        Args:
            motion: the `Motion` (its activity decides; sit and stand sit on the chair).
            scene: a `Scene`, a name or an XML path; None: the room.
            chair: "auto" or "none" (`chair_fit.CHAIR_MODES`).

        Raises:
            ValueError: unknown `chair` mode, or a sit/stand motion without a seated phase.
        """
        from rtchannel.scene.chair_fit import CHAIR_MODES, wants_chair

        if chair not in CHAIR_MODES:
            raise InputError(f"chair must be one of {', '.join(CHAIR_MODES)}, got {chair!r}")
        if chair == "none" or not wants_chair(motion):
            return scene
        base = scene if isinstance(scene, Scene) else Scene("room" if scene is None else scene)
        return base.with_chair_for(motion)

    def with_chair_for(self, motion, **options) -> "Scene":
        """This scene plus the built-in chair placed under the seated person of a motion
        (`rtchannel.scene.chair_fit.chair_for`). Raises ValueError without a seated phase.

        Args:
            motion: a `Motion` with a seated phase.
            **options: `chair_for` options (e.g. the seat height [m]).
        """
        from rtchannel.scene.chair_fit import chair_for

        return self.with_furniture(chair_for(motion, **options))

    def base_xml_path(self) -> Path:
        """The source's scene file, without furniture; raises ValueError if it does not exist."""
        from rtchannel.scene.rooms import is_room_name, room_xml_path
        from rtchannel.scene.rt_scene import SCENES

        if is_room_name(self.source):
            return room_xml_path(str(self.source))
        path = SCENES.get(str(self.source), Path(self.source))
        if not path.is_file():
            raise InputError(f"scene '{self.source}' is neither one of {', '.join(SCENES)} nor an existing XML file")
        return path.resolve()

    def xml_path(self) -> Path:
        """The scene file the ray tracer loads: the source's, or with furniture a generated one in the cache
        folder (`furniture.furnished_scene_xml`; its path changes with the content). Raises ValueError if
        the source does not exist."""
        base = self.base_xml_path()
        if not self.furniture:
            return base
        from rtchannel.scene.furniture import furnished_scene_xml

        return furnished_scene_xml(base, self.furniture)

    @property
    def name(self) -> str:
        """Short name for reports: the preset name or the file name, with "+chair" etc. for furniture."""
        base = str(self.source) if str(self.source) in ("room", "free_space") or str(self.source).startswith(
            "room:") else Path(self.source).name
        return base + "".join(f"+{f.label}" for f in self.furniture)

    def describe(self) -> dict:
        """JSON-serialisable description stored with every simulation (`from_describe` rebuilds the scene)."""
        d: dict[str, Any] = {"source": str(self.source)}
        if self.furniture:
            d["furniture"] = [f.describe() for f in self.furniture]
        return d

    @classmethod
    def from_describe(cls, d: dict) -> "Scene":
        """The scene `describe()` recorded.

        Args:
            d: the dict `describe()` returned (as stored in a result's config).
        """
        from rtchannel.scene.furniture import Furniture

        return cls(d["source"], tuple(Furniture.from_describe(f) for f in d.get("furniture", ())))

    def __repr__(self) -> str:
        return f"Scene({str(self.source)!r}" + "".join(f" + {f.label} at {tuple(round(x, 2) for x in f.position)} m"
                                                       for f in self.furniture[:4]) + ")"

    def __str__(self) -> str:
        return str(self.source) + "".join(f"+{f.label}" for f in self.furniture)
