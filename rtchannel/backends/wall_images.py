"""Image sources in planar walls for first-order body-wall multipath (SI units).

A path tx -> wall -> facet -> rx has the length of the straight line from tx', the mirror image of tx in
the wall's plane, to the facet, plus facet -> rx. It exists (image validity) when

- the antenna and the facet's centroid are on the room side of the wall (the side its normal points to),
- the reflection point q, where the segment centroid -> tx' crosses the plane, lies inside the wall
  polygon (a convex polygon, as `rtchannel.scene.rt_scene.Wall` provides),
- and both legs (tx -> q, q -> facet) are unoccluded (checked by ray casts in `visibility`).

A double bounce tx -> wall -> facet -> wall -> rx is the straight path tx' -> facet -> rx' with both
antennas mirrored; it exists when both single-image conditions hold (one reflection point per antenna).

Walls are duck-typed: anything with ``point`` [3], unit ``normal`` [3] (into the room), ``polygon`` [K, 3]
(convex, ordered), ``relative_permittivity`` (complex) and optionally ``thickness`` [m].
"""
from __future__ import annotations

import numpy as np

from rtchannel.scene.rt_scene import Wall

# a wall for tests and custom geometry: the scene's own type (area and thickness default to 0)
PlanarWall = Wall


def mirror(points: np.ndarray, wall) -> np.ndarray:
    """Mirror images [..., 3] of `points` [..., 3] (m) in the wall's plane."""
    n = np.asarray(wall.normal, float)
    d = (np.asarray(points, float) - wall.point) @ n
    return points - 2 * d[..., None] * n


def signed_distance(points: np.ndarray, wall) -> np.ndarray:
    """Distance [m] of points [..., 3] from the wall plane, positive on the room side."""
    return (np.asarray(points, float) - wall.point) @ np.asarray(wall.normal, float)


def in_convex_polygon(q: np.ndarray, wall, tol: float = 1e-9) -> np.ndarray:
    """Whether points q [N, 3] lying in the wall plane are inside its (convex, ordered) polygon."""
    poly = np.asarray(wall.polygon, float)
    n = np.asarray(wall.normal, float)
    edges = np.roll(poly, -1, axis=0) - poly
    # Sign of the edge-normal test must agree for all edges (either winding of the polygon).
    s = np.einsum("kj,nkj->nk", np.cross(edges, n), q[:, None, :] - poly[None])
    return np.all(s >= -tol, axis=1) | np.all(s <= tol, axis=1)


def reflection_points(centroids: np.ndarray, source: np.ndarray, wall) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reflection points of source -> wall -> centroids.

    Args:
        centroids: [N, 3] facet centroids (m). source: [3] antenna position (m). wall: a planar wall.

    Returns:
        (image [3], q [N, 3] reflection points (m), valid [N]): valid where source and centroid are on the
        room side and q lies inside the wall polygon. q is finite everywhere (clamped where invalid).
    """
    image = mirror(np.asarray(source, float), wall)
    h_src = float(signed_distance(source, wall))
    h_c = signed_distance(centroids, wall)
    valid = (h_c > 0) & (h_src > 0)
    # Fraction along centroid -> image where the plane is crossed: h_c / (h_c + h_src).
    frac = np.where(valid, h_c / np.where(valid, h_c + h_src, 1.0), 0.0)
    q = centroids + frac[:, None] * (image - centroids)
    if valid.any():
        valid[valid] = in_convex_polygon(q[valid], wall)
    return image, q, valid

