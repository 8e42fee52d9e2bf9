"""Scene-file sandbox: a scene XML may only reference files inside its own folder or the project's asset
folders, and every error about it is one line that never quotes file content.

`read_scene_xml` is called where a scene file is read (`rtchannel.scene.rt_scene.RTScene`), before
Mitsuba sees it. It parses the file with defusedxml (no DTD, no entity expansion, no external
references), substitutes Mitsuba's ``<default name=... value=...>`` parameters, and checks every
path-like value - ``<include filename>``, ``<path value>``, any ``filename``/``file``/``path``
attribute, ``<string name="filename" value=...>`` and any value with a path separator or a mesh/image
suffix - after resolving symlinks and ``..``: it must name an existing file (a folder for ``<path>``)
under one of `allowed_roots`. Included files are checked the same way, recursively. `load_scene_string`
turns a Mitsuba/Sionna load failure into one `SceneFileError` line (quoted strings removed).

The allowed roots are kept in one list, `EXTRA_ROOTS` (besides the scene's own folder): append a
folder there (e.g. a furniture-model cache) to let scenes reference it.
"""
from __future__ import annotations

import re
from pathlib import Path

from rtchannel.errors import SceneFileError
from rtchannel.assets import asset_root, scenes_dir

# Folders every scene may reference besides its own (the project's scenes and meshes; add caches here).
EXTRA_ROOTS: list[Path] = [scenes_dir(), asset_root("meshes")]
MAX_SCENE_BYTES = 16 * 2**20  # a scene description (meshes are separate files); larger is not a hand-written scene
MAX_ELEMENTS = 200_000  # XML elements over the scene and its includes
MAX_INCLUDE_DEPTH = 8  # nested <include>; deeper is a cycle or a mistake
_PATH_NAMES = {"filename", "file", "path", "filepath"}
_FILE_SUFFIX = re.compile(r"\.(xml|ply|obj|serialized|stl|off|exr|hdr|png|jpe?g|bmp|tga|pfm|ppm|spd|vol|npy)$", re.I)
_VAR = re.compile(r"\$(\w+)")


def allowed_roots(scene_path: str | Path) -> list[Path]:
    """Resolved folders a scene file may reference: its own folder and `EXTRA_ROOTS`."""
    return [Path(scene_path).resolve().parent, *(Path(r).resolve() for r in EXTRA_ROOTS)]


def _inside(p: Path, roots: list[Path]) -> bool:
    return any(p == r or r in p.parents for r in roots)


def _parse(path: Path, budget: list[int]):
    """Root element of a scene file, each element carrying `sourceline`; SceneFileError if malformed."""
    import xml.etree.ElementTree as ET

    from defusedxml import DTDForbidden, EntitiesForbidden, ExternalReferenceForbidden
    from defusedxml.ElementTree import DefusedXMLParser

    try:
        size = path.stat().st_size
        if size > MAX_SCENE_BYTES:
            raise SceneFileError(f"{path}: {size / 2**20:.0f} MiB is larger than the {MAX_SCENE_BYTES >> 20} MiB "
                                 "limit for a scene file")
        data = path.read_bytes()
    except OSError as e:
        raise SceneFileError(f"{path}: cannot read scene file: {e.strerror or type(e).__name__}") from None

    class LineElement(ET.Element):  # the C Element takes no attributes; a subclass has a __dict__
        sourceline: int | None = None

    class Target(ET.TreeBuilder):
        def start(self, tag, attrs):
            budget[0] -= 1
            if budget[0] < 0:
                raise SceneFileError(f"{path}: more than {MAX_ELEMENTS} XML elements")
            el = super().start(tag, attrs)
            assert isinstance(el, LineElement)  # element_factory=LineElement
            el.sourceline = parser.parser.CurrentLineNumber
            return el

    parser = DefusedXMLParser(target=Target(element_factory=LineElement), forbid_dtd=True, forbid_entities=True,
                              forbid_external=True)
    try:
        parser.feed(data)
        return parser.close()
    except ET.ParseError as e:
        line, col = getattr(e, "position", (None, None))
        raise SceneFileError(f"{path}: line {line}, column {col}: malformed XML") from None
    except (DTDForbidden, EntitiesForbidden, ExternalReferenceForbidden) as e:
        raise SceneFileError(f"{path}: {type(e).__name__}: DTDs and entities are not allowed in scene files") from None
    except (ValueError, UnicodeError) as e:  # e.g. an encoding declaration expat does not know
        raise SceneFileError(f"{path}: not a readable XML file ({type(e).__name__})") from None


def _substitute(value: str, defaults: dict[str, str], path: Path, line: int) -> str:
    def sub(m):
        if m.group(1) not in defaults:
            raise SceneFileError(f"{path}: line {line}: ${m.group(1)} has no <default> value in the file "
                                 "(scene parameters must be defined in the scene)")
        return defaults[m.group(1)]
    return _VAR.sub(sub, value)


def _check_ref(value: str, base: Path, roots: list[Path], path: Path, line: int, what: str,
               folder: bool = False) -> Path:
    """The resolved file a scene value names; SceneFileError unless it exists under one of `roots`."""
    if not value.strip() or "\0" in value:
        raise SceneFileError(f"{path}: line {line}: empty or invalid {what}")
    p = Path(value).expanduser()
    target = (p if p.is_absolute() else base / p).resolve()
    if not _inside(target, roots):
        raise SceneFileError(f"{path}: line {line}: {what} {value[:80]!r} points outside the scene's folder "
                             "(scenes may reference only files in their own folder or the project's scenes/meshes)")
    if not (target.is_dir() if folder else target.is_file()):
        raise SceneFileError(f"{path}: line {line}: {what} {value[:80]!r} does not exist")
    return target


def _check(path: Path, roots: list[Path], depth: int, budget: list[int], seen: set[Path]) -> None:
    root = _parse(path, budget)
    if depth == 0 and root.tag != "scene":
        raise SceneFileError(f"{path}: not a Mitsuba scene file (the root element is <{root.tag[:40]}>, not <scene>)")
    base = path.parent
    defaults = {el.get("name", ""): el.get("value", "") for el in root.iter("default")}
    for el in root.iter():
        line: int = getattr(el, "sourceline", 0)  # _parse's LineElement sets it on every element
        attrs = {k: _substitute(v, defaults, path, line) if "$" in v else v for k, v in el.attrib.items()}
        if el.tag == "include":
            inc = _check_ref(attrs.get("filename", ""), base, roots, path, line, "include")
            if depth + 1 > MAX_INCLUDE_DEPTH or inc in seen:
                raise SceneFileError(f"{path}: line {line}: includes nested deeper than {MAX_INCLUDE_DEPTH} or in a "
                                     "cycle")
            _check(inc, roots, depth + 1, budget, seen | {inc})
            continue
        if el.tag == "path":  # adds a search folder to Mitsuba's file resolver
            _check_ref(attrs.get("value", ""), base, roots, path, line, "search path", folder=True)
            continue
        named = el.get("name", "").lower()
        for key, value in attrs.items():
            key_l = key.lower()
            pathlike = (key_l in _PATH_NAMES
                        or (key_l == "value" and (named in _PATH_NAMES or named.endswith("filename")))
                        or (key_l not in ("name", "id", "type") and ("/" in value or "\\" in value
                                                                      or _FILE_SUFFIX.search(value.strip()))))
            if pathlike:
                _check_ref(value, base, roots, path, line, f"{el.tag[:20]} {named or key}")


def check_scene_file(path: str | Path) -> None:
    """Raise `SceneFileError` unless the scene file and everything it references pass the sandbox."""
    path = Path(path)
    resolved = path.resolve()
    if not resolved.is_file():
        raise SceneFileError(f"{path}: scene file not found")
    _check(resolved, allowed_roots(resolved), 0, [MAX_ELEMENTS], {resolved})


def read_scene_xml(path: str | Path) -> str:
    """The text of a scene file that passed `check_scene_file` (SceneFileError otherwise)."""
    check_scene_file(path)
    try:
        return Path(path).read_bytes().decode("utf-8")
    except (OSError, UnicodeError) as e:
        raise SceneFileError(f"{path}: cannot read scene file as UTF-8 ({type(e).__name__})") from None


_QUOTED = re.compile(r"\"[^\"]*\"|'[^']*'|`[^`]*`")
_WHERE = re.compile(r"line (\d+), col(?:umn)? (\d+)")


def load_error_line(path: str | Path, exc: BaseException) -> str:
    """One line for a Mitsuba/Sionna load failure: file, position if given, the reason without quoted text."""
    text = " ".join(str(exc).split())
    where = _WHERE.search(text)
    reason = _QUOTED.sub("...", re.sub(r"^\[[^\]]*\]\s*", "", text))[:200]
    pos = f" (line {where.group(1)}, column {where.group(2)})" if where else ""
    return f"{path}: the ray tracer could not load the scene{pos}: {type(exc).__name__}: {reason}"


def load_scene_string(loader, xml: str, path: str | Path, **kwargs):
    """`loader(xml, **kwargs)` (e.g. ``sionna.rt.load_scene_from_string``) with failures as `SceneFileError`."""
    try:
        return loader(xml, **kwargs)
    except (RuntimeError, ValueError, TypeError, KeyError, IndexError, OSError) as e:
        raise SceneFileError(load_error_line(path, e)) from None


__all__ = ["EXTRA_ROOTS", "MAX_SCENE_BYTES", "allowed_roots", "check_scene_file", "load_error_line",
           "load_scene_string", "read_scene_xml"]
