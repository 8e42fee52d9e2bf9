"""Occlusion rays straight through Embree 3, the ray tracing kernel library Mitsuba ships and uses on CPU.

Mitsuba's own route (``params.update()`` then ``scene.ray_test``) rebuilds the BVH of the `visibility`
batch scene with a per-update cost of ~3x Embree's bare build (measured on the bench walk's 16-frame
batches of the 10k body: ~150 ms against ~50 ms on a loaded 2-core machine), and each ray test goes
through a Dr.Jit kernel. Here the same Embree library (the ``libembree3.so`` beside Mitsuba's modules;
its C API is compiled into the ``mitsuba`` C++ namespace, hence the mangled names) builds the same
triangles from float32 buffers shared with numpy and answers any-hit queries for a numpy array of rays
(``rtcOccluded1M``). Same library, same float32 triangles and rays: the answers are Embree's either way
(tests/test_facet_speed.py compares the two routes ray by ray).

`available()` is False when the library or a symbol is missing (another Mitsuba build); `visibility`
then falls back to Mitsuba.
"""
from __future__ import annotations

import ctypes
import os
import threading
from typing import Any

import numba
import numpy as np

_P, _U, _S, _I = ctypes.c_void_p, ctypes.c_uint, ctypes.c_size_t, ctypes.c_int
# (name, mangled symbol, restype, argtypes) of the Embree 3.13 calls used (namespace ``mitsuba``).
_API = {
    "new_device": ("_ZN7mitsuba12rtcNewDeviceEPKc", _P, [ctypes.c_char_p]),
    "device_error": ("_ZN7mitsuba17rtcGetDeviceErrorEPNS_11RTCDeviceTyE", _I, [_P]),
    "new_scene": ("_ZN7mitsuba11rtcNewSceneEPNS_11RTCDeviceTyE", _P, [_P]),
    "release_scene": ("_ZN7mitsuba15rtcReleaseSceneEPNS_10RTCSceneTyE", None, [_P]),
    "new_geometry": ("_ZN7mitsuba14rtcNewGeometryEPNS_11RTCDeviceTyENS_15RTCGeometryTypeE", _P, [_P, _I]),
    "release_geometry": ("_ZN7mitsuba18rtcReleaseGeometryEPNS_13RTCGeometryTyE", None, [_P]),
    "shared_buffer": ("_ZN7mitsuba26rtcSetSharedGeometryBufferEPNS_13RTCGeometryTyENS_13RTCBufferTypeEjNS_9RTCFormat"
                      "EPKvmmm", None, [_P, _I, _U, _I, _P, _S, _S, _S]),
    "update_buffer": ("_ZN7mitsuba23rtcUpdateGeometryBufferEPNS_13RTCGeometryTyENS_13RTCBufferTypeEj", None,
                      [_P, _I, _U]),
    "commit_geometry": ("_ZN7mitsuba17rtcCommitGeometryEPNS_13RTCGeometryTyE", None, [_P]),
    "attach": ("_ZN7mitsuba17rtcAttachGeometryEPNS_10RTCSceneTyEPNS_13RTCGeometryTyE", _U, [_P, _P]),
    "scene_quality": ("_ZN7mitsuba23rtcSetSceneBuildQualityEPNS_10RTCSceneTyENS_15RTCBuildQualityE", None, [_P, _I]),
    "geometry_quality": ("_ZN7mitsuba26rtcSetGeometryBuildQualityEPNS_13RTCGeometryTyENS_15RTCBuildQualityE", None,
                         [_P, _I]),
    "commit_scene": ("_ZN7mitsuba14rtcCommitSceneEPNS_10RTCSceneTyE", None, [_P]),
    "occluded_1m": ("_ZN7mitsuba13rtcOccluded1MEPNS_10RTCSceneTyEPNS_19RTCIntersectContextEPNS_6RTCRayEjm", None,
                    [_P, _P, _P, _U, _S]),
}
_GEOMETRY_TRIANGLE, _BUFFER_INDEX, _BUFFER_VERTEX = 0, 0, 1
_FORMAT_UINT3, _FORMAT_FLOAT3 = 0x5003, 0x9003
# RTC_BUILD_QUALITY_LOW (Morton builder): each BVH is used for one batch of rays only, and on the bench walk
# the low-quality build costs 0.03 s against 0.12 s (medium) while the rays take 0.27 against 0.24 s
# (benchmarks/bench_facets.py --quick, idle). Which triangles a ray hits does not depend on the BVH.
_BUILD_QUALITY_LOW = 0
_RAY_FLOATS = 12  # struct RTCRay: org[3], tnear, dir[3], time, tfar, mask, id, flags (48 bytes)
_CHUNK = 1 << 16  # rays per rtcOccluded1M call (threads take chunks in turn)

_lock = threading.RLock()
_state: dict = {}


def _load():
    """The bound calls and one device, or None when Mitsuba's Embree is not usable."""
    with _lock:
        if "api" in _state:
            return _state["api"]
        api: dict[str, Any] | None = None
        try:
            import mitsuba

            lib = ctypes.CDLL(os.path.join(os.path.dirname(mitsuba.__file__), "libembree3.so"))
            bound: dict[str, Any] = {}
            for key, (sym, res, args) in _API.items():
                f = getattr(lib, sym)
                f.restype, f.argtypes = res, args
                bound[key] = f
            bound["device"] = bound["new_device"](None)
            api = bound if bound["device"] else None
        except (ImportError, OSError, AttributeError):
            api = None
        _state["api"] = api
        # The struct layouts above are Embree 3.13's: a library built otherwise could answer wrongly rather
        # than fail, so one known scene must give the known answers before any caller relies on it (the
        # lock is re-entrant: the test's own scene reads the api published just above, other threads wait).
        if api is not None and not _self_test():
            _state["api"] = api = None
        return api


def _self_test() -> bool:
    """A unit triangle in the z = 0 plane: a ray through it is occluded, one beside it and one that stops
    short of it are not."""
    try:
        scene = EmbreeScene(None, np.array([[0, 1, 2]]), 3)
        scene.set_body(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))
        org = np.array([[0.2, 0.2, 1.0], [2.0, 2.0, 1.0], [0.2, 0.2, 1.0]])
        hit = scene.occluded(org, np.array([[0.0, 0.0, -1.0]] * 3), np.array([2.0, 2.0, 0.5]))
        return hit.tolist() == [True, False, False]
    except (RuntimeError, OSError, ValueError):
        return False


def new_rays(n: int) -> np.ndarray:
    """[n, 12] float32 RTCRay records: zero (tnear, time, flags, id) with every geometry's mask set; the caller
    fills org (0:3), dir (4:7) and tfar (8)."""
    rays = np.zeros((n, _RAY_FLOATS), np.float32)
    rays.view(np.uint32)[:, 9] = 0xFFFFFFFF  # mask: every geometry
    return rays


@numba.njit(cache=True, inline="always")
def _ray_one(i, sx, sy, sz, ex, ey, ez, stop, o, rays, bits, valid):
    """Ray record i of the segment s -> e shifted by o, stopping `stop` short: the arithmetic of
    `visibility`'s numpy route (d = e - s, |d| summed as einsum does, d / |d|, then float32 through
    `EmbreeScene.occluded`), so the rays are the same bit for bit (tests/test_facet_speed_kernels.py)."""
    d0, d1, d2 = ex - sx, ey - sy, ez - sz
    dist = np.sqrt((d0 * d0 + d2 * d2) + d1 * d1)  # numpy's einsum order (two lanes)
    den = dist if dist > 0 else 1.0
    t = dist - stop
    rays[i, 0], rays[i, 1], rays[i, 2], rays[i, 3] = sx + o[0], sy + o[1], sz + o[2], 0.0
    rays[i, 4], rays[i, 5], rays[i, 6], rays[i, 7] = d0 / den, d1 / den, d2 / den, 0.0
    rays[i, 8] = max(t, 0.0)
    bits[i, 9], bits[i, 10], bits[i, 11] = 0xFFFFFFFF, 0, 0
    valid[i] = t > 0


@numba.njit(cache=True, nogil=True)
def pack_rays(points, index, end, stop, cells, offsets, rays, bits, valid):
    """Embree ray records [N, 12] (float32 `rays`, its uint32 view `bits`) of segments start -> end [N, 3],
    start = points[index[i]] (or points[i] without index), shifted into cell offsets[cells[i]] and stopping
    stop[i] (or stop[0]) short; valid[i]: a positive length remains."""
    for i in range(end.shape[0]):
        j = index[i] if index.shape[0] else i
        _ray_one(i, points[j, 0], points[j, 1], points[j, 2], end[i, 0], end[i, 1], end[i, 2],
                 stop[i] if stop.shape[0] > 1 else stop[0], offsets[cells[i]], rays, bits, valid)


@numba.njit(cache=True, nogil=True)
def pack_direct(sources, s_idx, centroids, b, f, stop, offsets, rays, bits, valid):
    """`pack_rays` of the segments sources[s_idx] -> centroids[b, f] in cells b (read in place)."""
    for i in range(b.shape[0]):
        p, c = sources[s_idx[i]], centroids[b[i], f[i]]
        _ray_one(i, p[0], p[1], p[2], c[0], c[1], c[2], stop, offsets[b[i]], rays, bits, valid)


def available() -> bool:
    """Whether Mitsuba's Embree library can be called directly."""
    return _load() is not None


class EmbreeScene:
    """A static triangle set plus one deformable triangle set (fixed faces, vertices replaced by `set_body`).

    Args:
        static: (vertices [Vs, 3] (m), faces [Ts, 3]) of the geometry that never moves, or None.
        body_faces: [T, 3] triangles of the deformable set; n_body_vertices: its vertex count.
    """

    def __init__(self, static, body_faces: np.ndarray, n_body_vertices: int):
        api = _load()
        if api is None:
            raise RuntimeError("Mitsuba's Embree library is not available")
        self._api = api
        self._scene = api["new_scene"](api["device"])
        api["scene_quality"](self._scene, _BUILD_QUALITY_LOW)
        self._geoms: list[Any] = []  # Embree geometry handles
        self._keep: list[np.ndarray] = []
        if static is not None and len(static[1]):
            self._add(np.asarray(static[0], np.float32), static[1])
        # Embree reads vertices with 16-byte loads: one float of padding after the last vertex.
        self._body_v = np.zeros(3 * n_body_vertices + 1, np.float32)
        self._body = self._add(self._body_v, body_faces)
        self._committed = False

    def _add(self, vertices, faces):
        api = self._api
        v = vertices if vertices.ndim == 1 else np.concatenate([np.ravel(vertices), [0.0]]).astype(np.float32)
        f = np.ascontiguousarray(faces, np.uint32)
        g = api["new_geometry"](api["device"], _GEOMETRY_TRIANGLE)
        api["geometry_quality"](g, _BUILD_QUALITY_LOW)
        api["shared_buffer"](g, _BUFFER_VERTEX, 0, _FORMAT_FLOAT3, v.ctypes.data, 0, 12, (v.size - 1) // 3)
        api["shared_buffer"](g, _BUFFER_INDEX, 0, _FORMAT_UINT3, f.ctypes.data, 0, 12, len(f))
        api["commit_geometry"](g)
        api["attach"](self._scene, g)
        self._geoms.append(g)
        self._keep += [v, f]  # Embree reads these buffers in place: they live as long as the scene
        return g

    def set_body(self, vertices: np.ndarray) -> None:
        """Replace the deformable set's vertices [n_body_vertices, 3] (m) and rebuild the BVH."""
        api = self._api
        self._body_v[:-1] = np.ravel(vertices)
        api["update_buffer"](self._body, _BUFFER_VERTEX, 0)
        api["commit_geometry"](self._body)
        api["commit_scene"](self._scene)
        self._committed = True
        err = api["device_error"](api["device"])
        if err:
            raise RuntimeError(f"Embree error {err} while building the BVH")

    def occluded(self, origins: np.ndarray, directions: np.ndarray, max_t: np.ndarray) -> np.ndarray:
        """Any-hit test [N] bool of rays origins [N, 3] + t directions [N, 3] (unit), 0 <= t <= max_t [N] (m)."""
        n = len(origins)
        if n == 0:
            return np.zeros(0, bool)
        rays = new_rays(n)
        rays[:, 0:3] = origins
        rays[:, 4:7] = directions
        rays[:, 8] = np.maximum(max_t, 0.0)
        return self.occluded_rays(rays)

    def occluded_rays(self, rays: np.ndarray) -> np.ndarray:
        """Any-hit test [N] bool of rays already laid out as Embree's RTCRay (`new_rays`, filled in place)."""
        n = len(rays)
        if n == 0:
            return np.zeros(0, bool)
        if not self._committed:
            self.set_body(self._body_v[:-1].reshape(-1, 3))
        # RTCIntersectContext: flags (0 = incoherent), filter pointer (null), instID[1] = invalid; padded.
        ctx = np.zeros(8, np.uint32)
        ctx[4] = 0xFFFFFFFF
        occ, scene = self._api["occluded_1m"], self._scene
        chunks = range(0, n, _CHUNK)
        if n <= _CHUNK or (os.cpu_count() or 1) < 2:
            for a in chunks:
                occ(scene, ctx.ctypes.data, rays[a:].ctypes.data, min(_CHUNK, n - a), 4 * _RAY_FLOATS)
        else:  # ctypes drops the GIL during the call: two threads share the chunks
            def work(start):
                for a in range(start, n, 2 * _CHUNK):
                    occ(scene, ctx.ctypes.data, rays[a:].ctypes.data, min(_CHUNK, n - a), 4 * _RAY_FLOATS)

            t = threading.Thread(target=work, args=(_CHUNK,))
            t.start()
            work(0)
            t.join()
        return rays[:, 8] == -np.inf  # Embree marks an occluded ray with tfar = -inf

    def __del__(self):
        api = getattr(self, "_api", None)
        if api is None:
            return
        for g in self._geoms:
            api["release_geometry"](g)
        api["release_scene"](self._scene)
