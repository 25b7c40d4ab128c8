"""Height fields: terrain y = h(x, z) from a 2-D array of heights (seed 002).

PHYSICS.md 1, height field row. heights[i, j] is the height of the vertex at
x = origin_x + i dx, z = origin_z + j dz (y = origin_y + heights[i, j], y up). Each cell is
split along its (i, j) - (i+1, j+1) diagonal into two triangles. Beyond its footprint the
terrain continues flat at its border heights (vertex indices are clamped), so, like a
plane, it has no edge to fall off and no bounding sphere.

- inside: below the plane of the triangle under the point (the seed's vertical test);
- distance: exact, to the triangles of the cells within the vertical distance |dv| of the
  point (the closest surface point lies no farther than the one straight above or below).
  The search covers at most (2 WINDOW + 1)^2 cells; past that (a point far above a fine
  field) phi is a lower bound: max(|dv| / sqrt(1 + G^2), the nearest found within the
  window or beyond its edge), G the steepest slope of the field, so the solver's clearance
  stays safe. The normal is the direction from the closest point (the triangle's normal
  over a face, as in the seed; blended across edges);
- crossing: the particle's swept sphere against the triangles of the cells the segment's
  2-D shadow passes, widened by the radius (2-D line drawing by columns along the major
  horizontal axis, in the direction of motion), each an exact swept-sphere test.

Shape data: ishape = (float offset, int offset, vertices along x, vertices along z);
fshape = (local origin xyz, dx, dz, 1 / sqrt(1 + G^2), highest local y); float block =
heights, row-major (i, j).
"""

import os

import numpy as np
import taichi as ti

from .. import validate
from . import kinds
from .colliders import Collider
from .triangles import MISS, closest_on_triangle, swept_sphere_triangle

vec3 = ti.math.vec3

WINDOW = 2               # cells searched on each side of the point for the exact distance
CELL_BOUND = 1 << 20     # cell coordinates are clamped in floating point before rounding
INFINITY = 1e30


@ti.func
def _cell(x, h):
    return ti.cast(ti.floor(ti.math.clamp(x / h, -CELL_BOUND, CELL_BOUND)), ti.i32)


@ti.func
def _corner(g: ti.template(), ci, i, j) -> vec3:
    """Vertex (i, j), measured from the local origin; indices clamped to the array."""
    nx = g.ishape[ci][2]
    nz = g.ishape[ci][3]
    height = g.fpool[g.ishape[ci][0] + ti.math.clamp(i, 0, nx - 1) * nz + ti.math.clamp(j, 0, nz - 1)]
    return vec3(i * g.fshape[ci][3], height, j * g.fshape[ci][4])


@ti.func
def _cell_triangle(g: ti.template(), ci, i, j, upper):
    """Triangle 0 of cell (i, j) is (00, 10, 11), below the diagonal (fx >= fz); triangle 1
    is (00, 01, 11)."""
    return _corner(g, ci, i, j), _corner(g, ci, i + 1 - upper, j + upper), _corner(g, ci, i + 1, j + 1)


@ti.func
def _vertical(g: ti.template(), ci, q: vec3):
    """(height of q above the plane of the triangle under it, that triangle's upward
    normal): the seed's inside test, for q measured from the local origin."""
    dx = g.fshape[ci][3]
    dz = g.fshape[ci][4]
    i = _cell(q.x, dx)
    j = _cell(q.z, dz)
    a, b, c = _cell_triangle(g, ci, i, j, 1 if q.z / dz - j > q.x / dx - i else 0)
    up = (b - a).cross(c - a)
    if up.y < 0.0:
        up = -up
    return q.y - (a.y - (up.x * (q.x - a.x) + up.z * (q.z - a.z)) / up.y), up.normalized()


@ti.func
def field_sdf(g: ti.template(), ci, p: vec3):
    """(phi, outward normal) at local point p."""
    dx = g.fshape[ci][3]
    dz = g.fshape[ci][4]
    q = p - vec3(g.fshape[ci][0], g.fshape[ci][1], g.fshape[ci][2])
    i = _cell(q.x, dx)
    j = _cell(q.z, dz)
    dv, up = _vertical(g, ci, q)
    reach = ti.abs(dv)
    # Exact distance over the cells within |dv| horizontally, at most WINDOW cells away.
    i_lo = _cell(q.x - reach, dx)
    i_hi = _cell(q.x + reach, dx)
    j_lo = _cell(q.z - reach, dz)
    j_hi = _cell(q.z + reach, dz)
    beyond = INFINITY  # horizontal distance to the cells left out of the window
    if i_lo < i - WINDOW:
        i_lo = i - WINDOW
        beyond = ti.min(beyond, q.x - i_lo * dx)
    if i_hi > i + WINDOW:
        i_hi = i + WINDOW
        beyond = ti.min(beyond, (i_hi + 1) * dx - q.x)
    if j_lo < j - WINDOW:
        j_lo = j - WINDOW
        beyond = ti.min(beyond, q.z - j_lo * dz)
    if j_hi > j + WINDOW:
        j_hi = j + WINDOW
        beyond = ti.min(beyond, (j_hi + 1) * dz - q.z)
    # The point straight above or below is on the terrain: start from it, and skip the
    # cells whose box (footprint x height range) lies no nearer.
    best = reach
    nearest = vec3(q.x, q.y - dv, q.z)
    for cell in range((i_hi - i_lo + 1) * (j_hi - j_lo + 1)):
        ic = i_lo + cell // (j_hi - j_lo + 1)
        jc = j_lo + cell % (j_hi - j_lo + 1)
        y00 = _corner(g, ci, ic, jc).y
        y11 = _corner(g, ci, ic + 1, jc + 1).y
        y10 = _corner(g, ci, ic + 1, jc).y
        y01 = _corner(g, ci, ic, jc + 1).y
        gap = vec3(ti.max(ic * dx - q.x, q.x - (ic + 1) * dx, 0.0),
                   ti.max(ti.min(y00, y11, y10, y01) - q.y, q.y - ti.max(y00, y11, y10, y01), 0.0),
                   ti.max(jc * dz - q.z, q.z - (jc + 1) * dz, 0.0))
        if gap.norm() < best:
            for upper in range(2):
                ta, tb, tc = _cell_triangle(g, ci, ic, jc, upper)
                point = closest_on_triangle(q, ta, tb, tc)
                dist = (q - point).norm()
                if dist < best:
                    best, nearest = dist, point
    dist = ti.max(reach * g.fshape[ci][5], ti.min(best, beyond))
    side = 1.0 if dv >= 0.0 else -1.0
    n = up
    w = q - nearest
    if w.norm() > 1e-12 * (1.0 + q.norm()):
        n = side * w.normalized()
    return side * dist, n


@ti.func
def field_crossing(g: ti.template(), ci, x0: vec3, x1: vec3, r):
    """First contact of a sphere of radius r moving x0 -> x1 with the terrain that the
    path runs into: (hit, t, normal facing the start); t = 0 when x0 starts below the
    terrain, or within r of it and moving closer (HeightField.crossing, on the host, adds
    every start within r as t = 0)."""
    origin = vec3(g.fshape[ci][0], g.fshape[ci][1], g.fshape[ci][2])
    dv, n = _vertical(g, ci, x0 - origin)
    hit = False
    t = 1.0
    if dv < 0.0:
        hit, t = True, 0.0  # starts below the terrain
    elif ti.min(x0.y, x1.y) - r <= origin.y + g.fshape[ci][6]:  # else above every peak
        dx = g.fshape[ci][3]
        dz = g.fshape[ci][4]
        q0 = x0 - origin
        d = x1 - x0
        # Columns of cells across the major horizontal axis (x when `along_x`), each with
        # the range of cells the swept sphere reaches on the other axis.
        along_x = ti.abs(d.x) >= ti.abs(d.z)
        h_major = dx if along_x else dz
        h_minor = dz if along_x else dx
        m0 = q0.x if along_x else q0.z
        dm = d.x if along_x else d.z
        n0 = q0.z if along_x else q0.x
        dn = d.z if along_x else d.x
        s_lo = _cell(ti.min(m0, m0 + dm) - r, h_major)
        s_hi = _cell(ti.max(m0, m0 + dm) + r, h_major)
        best = MISS
        for step in range(s_hi - s_lo + 1):
            s = s_lo + step if dm >= 0.0 else s_hi - step
            ta = 0.0
            tb = 1.0
            if dm != 0.0:
                t_near = (s * h_major - r - m0) / dm
                t_far = ((s + 1) * h_major + r - m0) / dm
                ta = ti.math.clamp(ti.min(t_near, t_far), 0.0, 1.0)
                tb = ti.math.clamp(ti.max(t_near, t_far), 0.0, 1.0)
            if ta > best:
                break  # later columns can only be reached later
            u_lo = _cell(ti.min(n0 + ta * dn, n0 + tb * dn) - r, h_minor)
            u_hi = _cell(ti.max(n0 + ta * dn, n0 + tb * dn) + r, h_minor)
            for cell in range((u_hi - u_lo + 1) * 2):
                u = u_lo + cell // 2
                ci_x = s if along_x else u
                ci_z = u if along_x else s
                a, b, c = _cell_triangle(g, ci, ci_x, ci_z, cell % 2)
                t_tri, n_tri = swept_sphere_triangle(q0, d, a, b, c, r)
                if t_tri < best:
                    best, n = t_tri, n_tri
        if best <= 1.0:
            hit, t = True, best
    return hit, t, n


# ---------------------------------------------------------------------------- the collider

def _read_netpbm(path: str) -> np.ndarray:
    """A PGM or PPM image (P2, P3, P5, P6) as an (H, W) float array in [0, 1]; colour is
    averaged to grey."""
    with open(path, "rb") as f:
        data = f.read()
    magic = data[:2]
    if magic not in (b"P2", b"P3", b"P5", b"P6"):
        raise ValueError(f"path: {path!r} is not a PGM/PPM image (magic {magic!r})")
    channels = 3 if magic in (b"P3", b"P6") else 1
    # Header: magic, width, height, maxval, separated by whitespace, '#' comments allowed.
    fields = []
    pos = 2
    while len(fields) < 3:
        while pos < len(data) and data[pos:pos + 1].isspace():
            pos += 1
        if data[pos:pos + 1] == b"#":
            while pos < len(data) and data[pos:pos + 1] not in (b"\n", b"\r"):
                pos += 1
            continue
        start = pos
        while pos < len(data) and not data[pos:pos + 1].isspace():
            pos += 1
        if start == pos:
            raise ValueError(f"path: {path!r} has a truncated PGM/PPM header")
        fields.append(int(data[start:pos]))
    width, height, maxval = fields
    count = width * height * channels
    if magic in (b"P2", b"P3"):
        values = np.array(data[pos:].split()[:count], dtype=np.float64)
    else:
        dtype = np.dtype(">u2") if maxval > 255 else np.dtype("u1")
        values = np.frombuffer(data, dtype=dtype, count=count, offset=pos + 1).astype(np.float64)
    if values.size != count:
        raise ValueError(f"path: {path!r} holds {values.size} samples, expected {count}")
    image = values.reshape(height, width, channels).mean(axis=2)
    return image / maxval


class HeightField(Collider):
    """Terrain y = h(x, z) (PHYSICS.md 1): heights[i, j] (m) at x = origin_x + i dx,
    z = origin_z + j dz, y = origin_y + heights[i, j]; each cell is two triangles. Beyond
    the footprint the border heights continue flat.

    heights: 2-D array, at least 2 x 2 vertices, finite.
    cell_size: dx = dz (m, > 0), or a pair (dx, dz).
    origin: position of vertex (0, 0) at height 0 (m).
    The collider's center (pivot of angular_velocity) is the footprint's center at origin_y.
    """

    kind = kinds.HEIGHT_FIELD

    def __init__(self, *, heights, cell_size, origin=(0.0, 0.0, 0.0)):
        try:
            h = np.asarray(heights, dtype=np.float64)
        except (TypeError, ValueError):
            raise TypeError("heights must be a 2-D array of numbers") from None
        if h.ndim != 2 or h.shape[0] < 2 or h.shape[1] < 2:
            raise ValueError(f"heights must be a 2-D array of at least 2 x 2 vertices; got shape {h.shape}")
        if not np.all(np.isfinite(h)):
            raise ValueError("heights must be finite")
        if np.ndim(cell_size) == 0:
            dx = dz = validate.real("cell_size", cell_size, low=0.0, low_open=True)
        else:
            pair = np.asarray(cell_size)
            if pair.shape != (2,):
                raise ValueError(f"cell_size must be a number or a pair (dx, dz); got shape {pair.shape}")
            dx = validate.real("cell_size[0]", float(pair[0]), low=0.0, low_open=True)
            dz = validate.real("cell_size[1]", float(pair[1]), low=0.0, low_open=True)
        origin = validate.vector3("origin", origin)
        self.heights = h
        self.cell_size = (dx, dz)
        self.origin = origin
        half = np.array([(h.shape[0] - 1) * dx / 2.0, 0.0, (h.shape[1] - 1) * dz / 2.0])
        self._local_origin = -half
        # Steepest slope over the triangles: |grad h| of each triangle's plane.
        sx0 = np.diff(h, axis=0)[:, :-1] / dx   # h10 - h00: lower triangle's x slope
        sz0 = (h[1:, 1:] - h[1:, :-1]) / dz      # h11 - h10: its z slope
        sz1 = np.diff(h, axis=1)[:-1, :] / dz   # h01 - h00: upper triangle's z slope
        sx1 = (h[1:, 1:] - h[:-1, 1:]) / dx      # h11 - h01: its x slope
        self.max_slope = float(max(np.max(np.hypot(sx0, sz0)), np.max(np.hypot(sx1, sz1))))
        super().__init__(center=origin + half, rotation=np.eye(3), params=(), bound=self.UNBOUNDED)

    @classmethod
    def from_image(cls, path, *, cell_size, height_scale: float = 1.0, origin=(0.0, 0.0, 0.0)) -> "HeightField":
        """A terrain from an image file: a .npy 2-D array (heights = values * height_scale)
        or a PGM/PPM image (heights = grey level in [0, 1] * height_scale). Pixel (row, col)
        becomes vertex (i = col, j = row): x runs along the image's width, z down its height."""
        path = os.fspath(path)
        height_scale = validate.real("height_scale", height_scale)
        if not os.path.exists(path):
            raise FileNotFoundError(f"height image not found: {path!r}")
        if path.lower().endswith(".npy"):
            image = np.load(path, allow_pickle=False)
            if image.ndim != 2:
                raise ValueError(f"path: {path!r} must hold a 2-D array; got shape {image.shape}")
        else:
            image = _read_netpbm(path)
        return cls(heights=np.asarray(image, dtype=np.float64).T * height_scale, cell_size=cell_size,
                   origin=origin)

    def height(self, x, z) -> np.ndarray:
        """The terrain's height y at world (x, z) (arrays broadcast), by the same triangles
        the kernels use, on the host (for scenes and tests of a field that has not moved)."""
        dx, dz = self.cell_size
        fx = (np.asarray(x, dtype=np.float64) - self.origin[0]) / dx
        fz = (np.asarray(z, dtype=np.float64) - self.origin[2]) / dz
        i = np.floor(fx)
        j = np.floor(fz)
        ux, uz = fx - i, fz - j
        nx, nz = self.heights.shape
        i, j = i.astype(np.int64), j.astype(np.int64)

        def at(a, b):
            return self.heights[np.clip(a, 0, nx - 1), np.clip(b, 0, nz - 1)]

        h00, h10, h01, h11 = at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)
        lower = h00 + ux * (h10 - h00) + uz * (h11 - h10)
        upper = h00 + uz * (h01 - h00) + ux * (h11 - h01)
        return self.origin[1] + np.where(uz > ux, upper, lower)

    def crossing(self, starts, ends, radius: float = 0.0):
        hit, t, n = super().crossing(starts, ends, radius)
        phi, normal = self._query(starts)
        touching = phi < radius  # in contact at the start, whichever way it moves
        hit[touching], t[touching], n[touching] = True, 0.0, normal[touching]
        return hit, t, n

    def shape_data(self):
        nx, nz = self.heights.shape
        ishape = np.array([0, 0, nx, nz, 0, 0, 0, 0], dtype=np.int32)
        fshape = np.array([*self._local_origin, *self.cell_size, 1.0 / np.sqrt(1.0 + self.max_slope ** 2),
                           float(self.heights.max()), 0.0])
        return ishape, fshape, self.heights.ravel(), np.zeros(0, dtype=np.int32)

    def _describe(self):
        return f"{self.heights.shape[0]} x {self.heights.shape[1]} heights, cell_size={self.cell_size}, " \
               f"origin={self.origin.tolist()}"
