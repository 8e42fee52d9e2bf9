"""`Scene`: what the person moves in — a room, free space or a user's Mitsuba XML file.

A `Scene` is a light description (no Mitsuba is loaded until a mesh backend traces it). The mesh
backends (`facets`, `sionna`) ray-trace the body inside it; the `points` backend is the seed's free-space
model and ignores it.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Scene:
    """A ray-tracing scene.

    Args:
        source: "room" (8 x 8 m concrete room with floor and 3 m walls, `scenes/room.xml`), "free_space"
            (nothing but the body) or the path of a Mitsuba 3 XML file whose shapes carry radio
            materials (see `scenes/README.md`).
    """

    source: str | Path = "room"

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
        """A user's Mitsuba 3 scene file (its shapes need radio materials; the id "body" is reserved)."""
        return cls(Path(path))

    def xml_path(self) -> Path:
        """The resolved scene file; raises ValueError if it does not exist."""
        from rtchannel.scene.rt_scene import SCENES

        path = SCENES.get(str(self.source), Path(self.source))
        if not path.is_file():
            raise ValueError(f"scene '{self.source}' is neither one of {', '.join(SCENES)} nor an existing XML file")
        return path.resolve()

    @property
    def name(self) -> str:
        """Short name for reports: the preset name or the file name."""
        return str(self.source) if str(self.source) in ("room", "free_space") else Path(self.source).name

    def describe(self) -> dict:
        """JSON-serialisable description stored with every simulation."""
        return {"source": str(self.source)}

    def __str__(self) -> str:
        return str(self.source)
