"""Device side of exact triangle meshes (the TriangleMesh collider, triangle_mesh.py): the
uniform grid of cells its triangles are binned into, and the queries through it.

docs/physics.md 1, triangle mesh row, exact path. The triangles are binned into a uniform
grid of cubic cells (each triangle in every cell its bounding box overlaps), built in Taichi
by a counting sort (`bin_triangles`, with the steps of tai_coll/sorting.py). Queries, in the
mesh's local frame:

- distance: the exact distance to the nearest triangle, searched over growing blocks of
  cells around the point until no cell left out can hold a nearer one (`_nearest`; at
  most MAX_SHELLS cells away: past that, a lower bound on the distance, which keeps the
  solver's clearance skipping safe);
- sign: closed meshes (every edge shared by exactly two triangles) are signed by the
  parity of a watertight ray cast along x, toward the grid's nearer end, through the
  cells of its row (triangles.ray_x_crossing); open meshes (and shells, thickness > 0)
  are unsigned: phi = distance - thickness / 2, and the normal points from the surface
  toward the point, so a particle is pushed back to the side it came from;
- crossing: the first contact the path runs into, of the particle's sphere (radius
  r + thickness / 2) with the triangles of the cells within that radius of the segment,
  visited slab by slab along the segment's major axis in the direction of motion (a
  conservative 3-D line drawing), stopping once no later slab can hold an earlier
  contact; each triangle is an exact swept-sphere test (triangles.swept_sphere_triangle),
  so a fast particle cannot pass a zero-thickness sheet.

Shape data (types.ShapeArgs): ishape = (float offset, int offset, triangles,
cells x, cells y, cells z, closed, vertices); fshape = (grid origin xyz, cell size,
half thickness); float block = local vertex coordinates, then a bounding sphere per
triangle (center, radius: the queries skip the triangles it rules out); int block =
triangle vertex indices, then per-cell start offsets (cells + 1), then the cells' triangle
ids.
"""

import numpy as np
import taichi as ti

from .. import runtime, sorting
from .triangles import MISS, closest_on_triangle, ray_x_crossing, swept_sphere_triangle

vec3 = ti.math.vec3
ivec3 = ti.math.ivec3

INFINITY = 1e30
MAX_SHELLS = 8           # the nearest-triangle search looks at most this many cells away
CELL_BOUND = 1 << 20     # cell coordinates are clamped in floating point before rounding


# ---------------------------------------------------------------------------- shared reads

@ti.func
def cell_coordinate(x, h, n):
    """Index of the cell holding coordinate x (measured from the grid origin), clamped to
    [0, n - 1]. The grid build and the queries round through this one function, so a
    triangle is found in exactly the cells it was binned into."""
    return ti.math.clamp(ti.cast(ti.floor(ti.math.clamp(x / h, -1.0, CELL_BOUND)), ti.i32), 0, n - 1)


@ti.func
def raw_cell(x, h):
    """Unclamped cell index of coordinate x (bounded against integer overflow)."""
    return ti.cast(ti.floor(ti.math.clamp(x / h, -CELL_BOUND, CELL_BOUND)), ti.i32)


@ti.func
def _vertex(g: ti.template(), ci, v):
    base = g.ishape[ci][0] + 3 * v
    return vec3(g.fpool[base], g.fpool[base + 1], g.fpool[base + 2])


@ti.func
def _triangle(g: ti.template(), ci, tri):
    base = g.ishape[ci][1] + 3 * tri
    return (_vertex(g, ci, g.ipool[base]), _vertex(g, ci, g.ipool[base + 1]),
            _vertex(g, ci, g.ipool[base + 2]))


@ti.func
def _bounding_sphere(g: ti.template(), ci, tri):
    """(center, radius) of a sphere around the triangle, stored after the vertices."""
    base = g.ishape[ci][0] + 3 * g.ishape[ci][7] + 4 * tri
    return vec3(g.fpool[base], g.fpool[base + 1], g.fpool[base + 2]), g.fpool[base + 3]


@ti.func
def _grid(g: ti.template(), ci):
    """(origin, cell size, cells per axis, offset of the cell starts in the int pool)."""
    origin = vec3(g.fshape[ci][0], g.fshape[ci][1], g.fshape[ci][2])
    dims = ivec3(g.ishape[ci][3], g.ishape[ci][4], g.ishape[ci][5])
    starts = g.ishape[ci][1] + 3 * g.ishape[ci][2]
    return origin, g.fshape[ci][3], dims, starts


@ti.func
def _cell_span(g: ti.template(), starts, dims, cell: ivec3):
    """Where cell's triangle ids lie in the int pool: [first, last)."""
    index = (cell.x * dims.y + cell.y) * dims.z + cell.z
    ids = starts + dims.x * dims.y * dims.z + 1
    return ids + g.ipool[starts + index], ids + g.ipool[starts + index + 1]


@ti.func
def _cyclic(v, m):
    """(v[m], v[m+1], v[m+2]), indices mod 3."""
    w = v
    if m == 1:
        w = ti.Vector([v[1], v[2], v[0]])
    elif m == 2:
        w = ti.Vector([v[2], v[0], v[1]])
    return w


@ti.func
def _uncyclic(v, m):
    """Inverse of _cyclic."""
    w = v
    if m == 1:
        w = ti.Vector([v[2], v[0], v[1]])
    elif m == 2:
        w = ti.Vector([v[1], v[2], v[0]])
    return w


# ---------------------------------------------------------------------------- queries

@ti.func
def _cells_around(q: vec3, reach, h, dims: ivec3, home: ivec3):
    """The block of cells overlapping the cube q +- reach, within MAX_SHELLS of home and
    the grid: (lowest, highest) cell (empty when lowest > highest on some axis)."""
    lo = ivec3(raw_cell(q.x - reach, h), raw_cell(q.y - reach, h), raw_cell(q.z - reach, h))
    hi = ivec3(raw_cell(q.x + reach, h), raw_cell(q.y + reach, h), raw_cell(q.z + reach, h))
    return ti.max(lo, home - MAX_SHELLS, 0), ti.min(hi, home + MAX_SHELLS, dims - 1)


@ti.func
def _nearest(g: ti.template(), ci, p: vec3):
    """(distance, closest surface point found): exact when the search completes, else a
    lower bound on the distance.

    Rounds over growing blocks of cells around p, each visiting the cells the earlier ones
    left out: first the cells within the distance to the grid (the cell of p when inside),
    then, once a triangle is found at distance d, the cells overlapping the cube p +- d,
    which hold every nearer triangle; while none is found the block grows by a cell. The
    search is certain once the distance found is within the distance from p to the cells
    not visited; blocks stop growing MAX_SHELLS cells from p's cell."""
    origin, h, dims, starts = _grid(g, ci)
    q = p - origin
    home = ivec3(cell_coordinate(q.x, h, dims.x), cell_coordinate(q.y, h, dims.y), cell_coordinate(q.z, h, dims.z))
    outside = ti.max(-q, q - dims * h, 0.0)
    reach = outside.norm()  # distance to the grid's box
    best = INFINITY
    best_point = p
    bound = 0.0
    done_lo = ivec3(0, 0, 0)
    done_hi = ivec3(-1, -1, -1)
    for _ in range(MAX_SHELLS + 2):
        lo, hi = _cells_around(q, reach, h, dims, home)
        for i in range(lo.x, hi.x + 1):
            for j in range(lo.y, hi.y + 1):
                for k in range(lo.z, hi.z + 1):
                    cell = ivec3(i, j, k)
                    if not (all(cell >= done_lo) and all(cell <= done_hi)):
                        first, last = _cell_span(g, starts, dims, cell)
                        for s in range(first, last):
                            tri = g.ipool[s]
                            center, radius = _bounding_sphere(g, ci, tri)
                            if (p - center).norm() - radius < best:
                                a, b, c = _triangle(g, ci, tri)
                                point = closest_on_triangle(p, a, b, c)
                                dist = (p - point).norm()
                                if dist < best:
                                    best, best_point = dist, point
        grew = any(lo < done_lo) or any(hi > done_hi)
        done_lo, done_hi = lo, hi
        # The cells not visited lie beyond the faces of the block that have cells behind them.
        bound = INFINITY
        for a in ti.static(range(3)):
            if lo[a] > 0:
                bound = ti.min(bound, ti.max(q[a] - lo[a] * h, 0.0))
            if hi[a] < dims[a] - 1:
                bound = ti.min(bound, ti.max((hi[a] + 1) * h - q[a], 0.0))
        if best <= bound or not grew:
            break
        reach = best if best < INFINITY else reach + h
    return ti.min(best, bound), best_point


@ti.func
def _inside_by_parity(g: ti.template(), ci, p: vec3) -> bool:
    """Parity of the crossings of a ray from p along x with a closed mesh, cast toward the
    nearer end of the grid. Walks the cells of the ray's row; a triangle binned into
    several cells of the row is tested only in the first of them the walk meets."""
    origin, h, dims, starts = _grid(g, ci)
    q = p - origin
    cell = ivec3(raw_cell(q.x, h), raw_cell(q.y, h), raw_cell(q.z, h))
    inside = False
    if 0 <= cell.y and cell.y < dims.y and 0 <= cell.z and cell.z < dims.z and 0 <= cell.x and cell.x < dims.x:
        step = 1 if 2 * cell.x >= dims.x else -1
        for m in range(dims.x - cell.x if step > 0 else cell.x + 1):
            i = cell.x + step * m
            first, last = _cell_span(g, starts, dims, ivec3(i, cell.y, cell.z))
            for s in range(first, last):
                tri = g.ipool[s]
                center, radius = _bounding_sphere(g, ci, tri)
                if (center.y - p.y) ** 2 + (center.z - p.z) ** 2 <= radius * radius:
                    a, b, c = _triangle(g, ci, tri)
                    # The first cell of the walk holding the triangle: where its near end lies.
                    near_end = ti.min(a.x, b.x, c.x) if step > 0 else ti.max(a.x, b.x, c.x)
                    binned = cell_coordinate(near_end - origin.x, h, dims.x)
                    walk_first = ti.max(binned, cell.x) if step > 0 else ti.min(binned, cell.x)
                    if walk_first == i:
                        shadow, x = ray_x_crossing(p, a, b, c)
                        if shadow and (x - p.x) * step > 0.0:
                            inside = not inside
    return inside


@ti.func
def mesh_sdf(g: ti.template(), ci, p: vec3):
    """(phi, outward normal) at local point p: the distance to the surface, negative inside
    a closed mesh, minus half the thickness."""
    dist, point = _nearest(g, ci, p)
    n = vec3(0.0, 1.0, 0.0)
    w = p - point
    if w.norm() > 1e-12 * (1.0 + p.norm()):
        n = w.normalized()
    if g.ishape[ci][6] != 0 and _inside_by_parity(g, ci, p):
        dist, n = -dist, -n
    return dist - g.fshape[ci][4], n


@ti.func
def mesh_crossing(g: ti.template(), ci, x0: vec3, x1: vec3, r):
    """First contact of a sphere of radius r moving x0 -> x1 with the mesh surface (offset
    by half its thickness) that the path runs into: (hit, t, normal facing the start); t = 0
    when x0 starts within reach of a triangle and moves closer. The solvers sweep only from
    clear starts; on the host, TriangleMesh.crossing adds every start in contact (or inside
    a closed mesh) as t = 0."""
    origin, h, dims, starts = _grid(g, ci)
    R = r + g.fshape[ci][4]
    d = x1 - x0
    dd = d.dot(d)
    ad = ti.abs(d)
    m = 0 if ad.x >= ad.y and ad.x >= ad.z else (1 if ad.y >= ad.z else 2)
    # Slabs of cells across the major axis m, then the box of cells the swept sphere
    # can reach inside each slab; coordinates in the cyclic order (m, m+1, m+2).
    q0 = _cyclic(x0 - origin, m)
    dq = _cyclic(d, m)
    n_cells = _cyclic(dims, m)
    s_lo = ti.max(raw_cell(ti.min(q0.x, q0.x + dq.x) - R, h), 0)
    s_hi = ti.min(raw_cell(ti.max(q0.x, q0.x + dq.x) + R, h), n_cells.x - 1)
    best = MISS
    n = vec3(0.0, 1.0, 0.0)
    for step in range(ti.max(s_hi - s_lo + 1, 0)):
        s = s_lo + step if dq.x >= 0.0 else s_hi - step
        ta = 0.0
        tb = 1.0
        if dq.x != 0.0:
            t_near = (s * h - R - q0.x) / dq.x
            t_far = ((s + 1) * h + R - q0.x) / dq.x
            ta = ti.math.clamp(ti.min(t_near, t_far), 0.0, 1.0)
            tb = ti.math.clamp(ti.max(t_near, t_far), 0.0, 1.0)
        if ta > best:
            break  # later slabs can only be reached later
        qa = q0 + ta * dq
        qb = q0 + tb * dq
        u_lo = ti.max(raw_cell(ti.min(qa.y, qb.y) - R, h), 0)
        u_hi = ti.min(raw_cell(ti.max(qa.y, qb.y) + R, h), n_cells.y - 1)
        v_lo = ti.max(raw_cell(ti.min(qa.z, qb.z) - R, h), 0)
        v_hi = ti.min(raw_cell(ti.max(qa.z, qb.z) + R, h), n_cells.z - 1)
        for iu in range(u_lo, u_hi + 1):
            for iv in range(v_lo, v_hi + 1):
                first, last = _cell_span(g, starts, dims, _uncyclic(ivec3(s, iu, iv), m))
                for k in range(first, last):
                    tri = g.ipool[k]
                    center, radius = _bounding_sphere(g, ci, tri)
                    w = center - x0
                    along = ti.math.clamp(w.dot(d) / ti.max(dd, 1e-300), 0.0, 1.0)
                    if (w - along * d).norm() <= radius + R:  # the path passes near it
                        a, b, c = _triangle(g, ci, tri)
                        t_tri, n_tri = swept_sphere_triangle(x0, d, a, b, c, R)
                        if t_tri < best:
                            best, n = t_tri, n_tri
    return best <= 1.0, ti.min(best, 1.0), n


# ---------------------------------------------------------------------------- binning (Taichi)

@ti.func
def _triangle_cells(verts: ti.template(), tris: ti.template(), t, origin: vec3, h, dims: ivec3):
    """The block of cells a triangle's bounding box overlaps: (lowest, highest) cell."""
    a = vec3(verts[tris[t, 0], 0], verts[tris[t, 0], 1], verts[tris[t, 0], 2])
    b = vec3(verts[tris[t, 1], 0], verts[tris[t, 1], 1], verts[tris[t, 1], 2])
    c = vec3(verts[tris[t, 2], 0], verts[tris[t, 2], 1], verts[tris[t, 2], 2])
    lo = ti.min(a, b, c) - origin
    hi = ti.max(a, b, c) - origin
    first = ivec3(cell_coordinate(lo.x, h, dims.x), cell_coordinate(lo.y, h, dims.y), cell_coordinate(lo.z, h, dims.z))
    last = ivec3(cell_coordinate(hi.x, h, dims.x), cell_coordinate(hi.y, h, dims.y), cell_coordinate(hi.z, h, dims.z))
    return first, last


@ti.kernel
def _count_and_scan(verts: ti.types.ndarray(), tris: ti.types.ndarray(), origin: vec3, h: float, dims: ivec3,
                    # outputs
                    counts: ti.types.ndarray(), block_sums: ti.types.ndarray(), starts: ti.types.ndarray(),
                    cursor: ti.types.ndarray()):
    """The counting sort's first steps: the triangles per cell, then each cell's first slot
    (starts, and a copy the fill advances, cursor)."""
    for t in range(tris.shape[0]):
        first, last = _triangle_cells(verts, tris, t, origin, h, dims)
        for i in range(first.x, last.x + 1):
            for j in range(first.y, last.y + 1):
                for k in range(first.z, last.z + 1):
                    ti.atomic_add(counts[(i * dims.y + j) * dims.z + k], 1)
    sorting.exclusive_scan(counts, counts.shape[0], block_sums, starts)
    for cell in range(counts.shape[0]):
        cursor[cell] = starts[cell]


@ti.kernel
def _fill_and_sort(verts: ti.types.ndarray(), tris: ti.types.ndarray(), origin: vec3, h: float, dims: ivec3,
                   starts: ti.types.ndarray(), cursor: ti.types.ndarray(),
                   # outputs
                   ids: ti.types.ndarray()):
    """The counting sort's last steps: every triangle into each cell its box overlaps, then
    each cell's ids sorted (a fixed order keeps ties between equidistant triangles
    deterministic)."""
    for t in range(tris.shape[0]):
        first, last = _triangle_cells(verts, tris, t, origin, h, dims)
        for i in range(first.x, last.x + 1):
            for j in range(first.y, last.y + 1):
                for k in range(first.z, last.z + 1):
                    ids[ti.atomic_add(cursor[(i * dims.y + j) * dims.z + k], 1)] = t
    sorting.sort_bins(starts, starts.shape[0] - 1, ids)


def bin_triangles(vertices: np.ndarray, triangles: np.ndarray, origin: np.ndarray, h: float, dims: np.ndarray):
    """Counting sort of triangle ids into cells, in Taichi kernels. Returns (starts (cells+1,),
    ids) as int32 arrays; the vertices must be in the dtype the queries will read."""
    runtime.ensure_init()
    n_cells = int(np.prod(dims))
    dims_t = ivec3(*[int(x) for x in dims])
    origin_t = vec3(*[float(x) for x in origin])
    counts = np.zeros(n_cells, dtype=np.int32)
    block_sums = np.zeros(sorting.scan_blocks(n_cells), dtype=np.int32)
    starts = np.zeros(n_cells + 1, dtype=np.int32)
    cursor = np.zeros(n_cells, dtype=np.int32)
    _count_and_scan(vertices, triangles, origin_t, float(h), dims_t, counts, block_sums, starts, cursor)
    ids = np.zeros(max(int(starts[-1]), 1), dtype=np.int32)
    _fill_and_sort(vertices, triangles, origin_t, float(h), dims_t, starts, cursor, ids)
    return starts, ids[: int(starts[-1])]
