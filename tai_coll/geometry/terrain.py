"""Device queries of height fields (the HeightField collider, height_field.py): terrain
y = h(x, z) from a 2-D array of heights (docs/physics.md 1, height field row; seed 002).

heights[i, j] is the height of the vertex at x = origin_x + i dx, z = origin_z + j dz
(y = origin_y + heights[i, j], y up). Each cell is split along its (i, j) - (i+1, j+1)
diagonal into two triangles. Beyond its footprint the terrain continues flat at its border
heights (vertex indices are clamped), so, like a plane, it has no edge to fall off and no
bounding sphere.

- inside: below the plane of the triangle under the point (the seed's vertical test);
- distance: exact within the caller's `reach` (INFINITY: at any range). The closest
  surface point lies no farther than the one straight above or below (|dv|), so only
  cells within min(|dv|, reach) need searching: the cells within WINDOW of the point's
  first; when that reaches past them (a point high over fine cells, a large particle
  beside a steep step), a box tree over blocks of BLOCK x BLOCK cells
  (triangles.tree_nearest) finishes the search from the best found. The ring of cells
  just beyond the footprint stands for the flat continuation on its side (their triangles
  are moved along the border under the point), so the tree covers the unbounded terrain.
  Nothing within reach: phi is a lower bound no less than reach, the larger of the
  tree's and |dv| / sqrt(1 + G^2), G the steepest slope of the field. The normal is the
  direction from the closest point (the triangle's normal over a face, as in the seed;
  blended across edges);
- crossing: the particle's swept sphere against the triangles of the cells the segment's
  2-D shadow passes, widened by the radius (2-D line drawing by columns along the major
  horizontal axis, in the direction of motion), each an exact swept-sphere test.

Shape data: ishape = (float offset, int offset, vertices along x, vertices along z, blocks
along z, leaves of the box tree); fshape = (local origin xyz, dx, dz, 1 / sqrt(1 + G^2),
highest local y); float block = heights, row-major (i, j), then the box tree's boxes; int
block = the blocks in the tree's leaf order, block (bi, bj) as bi * (blocks along z) + bj,
holding the cells i = BLOCK bi - 1 ... BLOCK bi + BLOCK - 2 (j likewise; cell -1 is the
ring).
"""

import taichi as ti

from .triangles import MISS, closest_on_triangle, swept_sphere_triangle, tree_nearest

vec3 = ti.math.vec3

WINDOW = 2               # cells searched on each side of the point before the box tree
BLOCK = 4                # cells along each side of a leaf of the box tree
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
def _cell_nearest(g: ti.template(), ci, i, j, q: vec3, best, nearest: vec3):
    """The nearer of (best, nearest) and the closest point of cell (i, j)'s triangles to q;
    and a lower bound on the cell's distance. A cell of the ring just beyond the footprint
    (i = -1 or nx - 1, j likewise) is flat across the border, so its piece is moved along
    the border to lie under q: it then stands for the whole continuation of the terrain on
    that side (docs/physics.md 1.2)."""
    nx = g.ishape[ci][2]
    nz = g.ishape[ci][3]
    dx = g.fshape[ci][3]
    dz = g.fshape[ci][4]
    shift = vec3(0.0, 0.0, 0.0)
    if i == -1:
        shift.x = ti.min(q.x + 0.5 * dx, 0.0)
    elif i == nx - 1:
        shift.x = ti.max(q.x - 0.5 * dx - (nx - 1) * dx, 0.0)
    if j == -1:
        shift.z = ti.min(q.z + 0.5 * dz, 0.0)
    elif j == nz - 1:
        shift.z = ti.max(q.z - 0.5 * dz - (nz - 1) * dz, 0.0)
    c00 = _corner(g, ci, i, j) + shift
    c10 = _corner(g, ci, i + 1, j) + shift
    c01 = _corner(g, ci, i, j + 1) + shift
    c11 = _corner(g, ci, i + 1, j + 1) + shift
    # The cell's box (footprint x height range): skip the cell unless it could be nearer.
    low = vec3(ti.max(c00.x - q.x, q.x - c11.x, 0.0),
               ti.max(ti.min(c00.y, c10.y, c01.y, c11.y) - q.y, q.y - ti.max(c00.y, c10.y, c01.y, c11.y), 0.0),
               ti.max(c00.z - q.z, q.z - c11.z, 0.0)).norm()
    if low < best:
        low = INFINITY
        for upper in range(2):  # triangle 0 is (00, 10, 11), triangle 1 is (00, 01, 11)
            point = closest_on_triangle(q, c00, c01 if upper == 1 else c10, c11)
            dist = (q - point).norm()
            low = ti.min(low, dist)
            if dist < best:
                best, nearest = dist, point
    return best, nearest, low


@ti.func
def _block_nearest(g: ti.template(), ci, leaf, q: vec3, best, nearest: vec3):
    """_cell_nearest over the cells of the box tree's leaf `leaf` (one block), or for leaf
    -1 over the window of cells around q (_around): (best, nearest, lower bound on the
    cells' distance)."""
    nx = g.ishape[ci][2]
    nz = g.ishape[ci][3]
    i0 = 0
    j0 = 0
    i_count = 0
    j_count = 0
    if leaf < 0:
        i0, i_count, j0, j_count, _ = _around(g, ci, q, best)
    else:
        block = g.ipool[g.ishape[ci][1] + leaf]
        i0 = BLOCK * (block // g.ishape[ci][4]) - 1
        j0 = BLOCK * (block % g.ishape[ci][4]) - 1
        i_count = ti.min(BLOCK, nx - i0)
        j_count = ti.min(BLOCK, nz - j0)
    low = INFINITY
    for cell in range(i_count * j_count):
        best, nearest, bound = _cell_nearest(g, ci, i0 + cell // j_count, j0 + cell % j_count, q, best, nearest)
        low = ti.min(low, bound)
    return best, nearest, low


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
def _around(g: ti.template(), ci, q: vec3, reach):
    """The window of cells within `reach` of q horizontally, at most WINDOW cells from q's:
    (first i, count, first j, count, horizontal distance from q to the cells left out)."""
    dx = g.fshape[ci][3]
    dz = g.fshape[ci][4]
    i_lo, i_hi, beyond_x = _window(q.x, reach, _cell(q.x, dx), dx)
    j_lo, j_hi, beyond_z = _window(q.z, reach, _cell(q.z, dz), dz)
    return i_lo, i_hi - i_lo + 1, j_lo, j_hi - j_lo + 1, ti.min(beyond_x, beyond_z)


@ti.func
def field_sdf(g: ti.template(), ci, p: vec3, reach=INFINITY):
    """(phi, outward normal) at local point p; exact where |phi| < reach (the caller's
    radius, say), a lower bound no less than reach farther out."""
    q = p - vec3(g.fshape[ci][0], g.fshape[ci][1], g.fshape[ci][2])
    dv, up = _vertical(g, ci, q)
    # The point straight above or below is on the terrain: start from it, search the
    # window of cells within |dv| (or reach), and the box tree when that reaches past it.
    start = ti.min(ti.abs(dv), reach)
    _, _, _, _, beyond = _around(g, ci, q, start)
    base = g.ishape[ci][0] + g.ishape[ci][2] * g.ishape[ci][3]
    dist, nearest, floor = tree_nearest(g, ci, base, g.ishape[ci][5], q, start, vec3(q.x, q.y - dv, q.z),
                                        _block_nearest, True, beyond)
    if dist >= reach:  # nothing within reach: the bounds the search and the slopes give
        dist = ti.max(floor, ti.abs(dv) * g.fshape[ci][5])
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
