"""NumPy oracles for triangle geometry, written here from the textbook formulas and used by
tests/test_triangle_mesh.py and tests/test_height_field.py. Nothing from tai_coll is used.

- closest points: every point against every triangle, by minimising the squared distance
  over the face (barycentric projection) and over the three edges (clamped projections);
- the inside test of closed meshes: the generalised winding number, the sum of the solid
  angles of the triangles seen from the point (Van Oosterom and Strackee), over 4 pi;
- first contact of a swept sphere: dense sampling of the brute-force distance along the
  segment, then bisection; for a point (radius 0), Moller-Trumbore against every triangle.
"""

import numpy as np


def _segment_closest(p, a, b):
    ab = b - a
    denom = np.maximum(np.einsum("...k,...k->...", ab, ab), 1e-300)
    s = np.clip(np.einsum("...k,...k->...", p - a, ab) / denom, 0.0, 1.0)
    return a + s[..., None] * ab


def closest_points(points, triangles):
    """(distance (P, T), closest point (P, T, 3)) of each point to each triangle (T, 3, 3)."""
    p = np.asarray(points, float)[:, None, :]
    a, b, c = (np.asarray(triangles, float)[None, :, k, :] for k in range(3))
    n = np.cross(b - a, c - a)
    nn = np.maximum(np.einsum("...k,...k->...", n, n), 1e-300)
    # Face: the projection, kept where its barycentric coordinates are all >= 0.
    proj = p - (np.einsum("...k,...k->...", p - a, n) / nn)[..., None] * n
    u = np.einsum("...k,...k->...", np.cross(c - b, proj - b), n)
    v = np.einsum("...k,...k->...", np.cross(a - c, proj - c), n)
    w = np.einsum("...k,...k->...", np.cross(b - a, proj - a), n)
    inside = (u >= 0) & (v >= 0) & (w >= 0)
    candidates = [np.where(inside[..., None], proj, np.nan)]
    candidates += [_segment_closest(p, a, b), _segment_closest(p, b, c), _segment_closest(p, c, a)]
    stack = np.stack(candidates)  # (4, P, T, 3)
    dist = np.linalg.norm(stack - p[None], axis=-1)
    dist = np.where(np.isnan(dist), np.inf, dist)
    pick = np.argmin(dist, axis=0)
    best = np.take_along_axis(stack, pick[None, ..., None], axis=0)[0]
    return np.take_along_axis(dist, pick[None], axis=0)[0], best


def nearest(points, triangles, chunk=256):
    """(distance (P,), closest surface point (P, 3)) over all triangles."""
    points = np.asarray(points, float)
    dist = np.empty(len(points))
    point = np.empty((len(points), 3))
    for s in range(0, len(points), chunk):
        d, q = closest_points(points[s:s + chunk], triangles)
        k = np.argmin(d, axis=1)
        dist[s:s + chunk] = d[np.arange(len(k)), k]
        point[s:s + chunk] = q[np.arange(len(k)), k]
    return dist, point


def winding_number(points, triangles):
    """Generalised winding number: 1 inside a closed, outward-wound mesh, 0 outside."""
    p = np.asarray(points, float)[:, None, :]
    a, b, c = (np.asarray(triangles, float)[None, :, k, :] - p for k in range(3))
    la, lb, lc = (np.linalg.norm(v, axis=-1) for v in (a, b, c))
    det = np.einsum("...k,...k->...", a, np.cross(b, c))
    div = (la * lb * lc + np.einsum("...k,...k->...", a, b) * lc + np.einsum("...k,...k->...", b, c) * la
           + np.einsum("...k,...k->...", c, a) * lb)
    return (2.0 * np.arctan2(det, div)).sum(axis=1) / (4.0 * np.pi)


def _point_segment_distance(p, a, b):
    return np.linalg.norm(p - _segment_closest(p, a, b), axis=-1)


def swept_contact(x0, x1, radius, triangles, samples=2000, iterations=60):
    """First t in [0, 1] at which the distance from x0 + t (x1 - x0) to the triangles
    (T, 3, 3) drops to `radius`, by sampling and bisection (np.inf where it never does).
    Only triangles whose bounding sphere comes within reach of the segment take part."""
    x0 = np.asarray(x0, float)
    x1 = np.asarray(x1, float)
    triangles = np.asarray(triangles, float)
    centroid = triangles.mean(axis=1)
    spread = np.linalg.norm(triangles - centroid[:, None], axis=2).max(axis=1)
    out = np.full(len(x0), np.inf)
    ts = np.linspace(0.0, 1.0, samples + 1)
    for i in range(len(x0)):
        near = _point_segment_distance(centroid, x0[i], x1[i]) <= spread + radius + 1e-9
        if not near.any():
            continue
        tris = triangles[near]

        def gap(t):
            return closest_points(x0[i] + np.atleast_1d(t)[:, None] * (x1[i] - x0[i]), tris)[0].min(axis=1) - radius

        touching = np.flatnonzero(gap(ts) <= 0.0)
        if touching.size == 0:
            continue
        k = touching[0]
        if k == 0:
            out[i] = 0.0
            continue
        lo, hi = ts[k - 1], ts[k]
        for _ in range(iterations):
            mid = 0.5 * (lo + hi)
            if gap(mid)[0] <= 0.0:
                hi = mid
            else:
                lo = mid
        out[i] = hi
    return out


def segment_first_hit(x0, x1, triangles):
    """Moller-Trumbore: the first t in [0, 1] at which each segment x0 -> x1 passes through
    one of the triangles (T, 3, 3); np.inf where none."""
    x0 = np.asarray(x0, float)
    d = np.asarray(x1, float) - x0
    first = np.full(len(x0), np.inf)
    for tri in np.asarray(triangles, float):
        e1, e2 = tri[1] - tri[0], tri[2] - tri[0]
        pvec = np.cross(d, e2)
        det = pvec @ e1
        ok = np.abs(det) > 1e-14
        inv = 1.0 / np.where(ok, det, 1.0)
        s = x0 - tri[0]
        u = np.einsum("ij,ij->i", s, pvec) * inv
        q = np.cross(s, e1)
        v = np.einsum("ij,ij->i", d, q) * inv
        t = (q @ e2) * inv
        good = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t <= 1)
        first = np.where(good, np.minimum(first, t), first)
    return first
