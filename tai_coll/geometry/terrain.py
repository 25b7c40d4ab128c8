"""Device queries of height fields (the HeightField collider, height_field.py): terrain
y = h(x, z) from a 2-D array of heights (docs/physics.md 1, height field row; seed 002).

heights[i, j] is the height of the vertex at x = origin_x + i dx, z = origin_z + j dz
(y = origin_y + heights[i, j], y up). Each cell is split along its (i, j) - (i+1, j+1)
diagonal into two triangles. Beyond its footprint the terrain continues flat at its border
heights (vertex indices are clamped), so, like a plane, it has no edge to fall off and no
bounding sphere.

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

import taichi as ti

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
def _window(x, reach, centre, h):
    """Cells [lo, hi] along one axis (spacing h) within `reach` of coordinate x, cut to WINDOW
    cells either side of x's cell `centre`; with the distance from x to the cells cut away
    (INFINITY if none)."""
    lo = _cell(x - reach, h)
    hi = _cell(x + reach, h)
    beyond = INFINITY
    if lo < centre - WINDOW:
        lo = centre - WINDOW
        beyond = ti.min(beyond, x - lo * h)
    if hi > centre + WINDOW:
        hi = centre + WINDOW
        beyond = ti.min(beyond, (hi + 1) * h - x)
    return lo, hi, beyond


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
    i_lo, i_hi, beyond_x = _window(q.x, reach, i, dx)
    j_lo, j_hi, beyond_z = _window(q.z, reach, j, dz)
    beyond = ti.min(beyond_x, beyond_z)  # horizontal distance to the cells left out of the window
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
