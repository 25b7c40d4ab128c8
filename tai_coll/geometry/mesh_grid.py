"""Device side of exact triangle meshes (the TriangleMesh collider, triangle_mesh.py): the
uniform grid of cells its triangles are binned into, the box tree over them, and the
queries through both.

docs/physics.md 1, triangle mesh row, exact path. The triangles are binned into a uniform
grid of cubic cells (each triangle in every cell its bounding box overlaps), built in Taichi
by a counting sort (`bin_triangles`, with the steps of tai_coll/sorting.py), and put under
a box tree (triangles.triangle_tree). Queries, in the mesh's local frame:

- distance: the exact distance to the nearest triangle within the caller's `reach` (a
  particle's radius; INFINITY: at any range, a point far off the mesh, a large particle
  over small cells), the triangles of the point's cell first, then branch and bound down
  the box tree (`_nearest`, triangles.tree_nearest): its cost grows with the depth of the
  tree and the triangles near the point, not with the distance in cells. Past the reach,
  a lower bound no less than it (the least gap of the boxes the search skipped); inside a
  closed mesh, exact at every depth;
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
half thickness, leaves of the box tree); float block = local vertex coordinates, then a
bounding sphere per triangle (center, radius: the queries skip the triangles it rules
out), then the box tree's boxes (triangles.box_tree); int block = triangle vertex indices,
then per-cell start offsets (cells + 1), then the cells' triangle ids, then the triangles
in the tree's leaf order.
"""

import numpy as np
import taichi as ti

from .. import runtime, sorting
from .triangles import MISS, TREE_LEAF, nearer_triangle, ray_x_crossing, swept_sphere_triangle, tree_nearest

vec3 = ti.math.vec3
ivec3 = ti.math.ivec3

INFINITY = 1e30
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
def _tree(g: ti.template(), ci):
    """(offset of the box tree's boxes in the float pool, its leaves, offset of its
    triangle order in the int pool)."""
    triangles = g.ishape[ci][2]
    dims = ivec3(g.ishape[ci][3], g.ishape[ci][4], g.ishape[ci][5])
    cells = dims.x * dims.y * dims.z
    starts = g.ishape[ci][1] + 3 * triangles
    boxes = g.ishape[ci][0] + 3 * g.ishape[ci][7] + 4 * triangles
    return boxes, ti.cast(g.fshape[ci][5], ti.i32), starts + cells + 1 + g.ipool[starts + cells]


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
def _home(g: ti.template(), ci, p: vec3):
    """(the cell holding p, clamped to the grid; the distance from p to the cells of the
    grid outside it, INFINITY if there are none)."""
    origin, h, dims, _ = _grid(g, ci)
    q = p - origin
    home = ivec3(cell_coordinate(q.x, h, dims.x), cell_coordinate(q.y, h, dims.y), cell_coordinate(q.z, h, dims.z))
    others = INFINITY
    for a in ti.static(range(3)):
        if home[a] > 0:
            others = ti.min(others, ti.max(q[a] - home[a] * h, 0.0))
        if home[a] < dims[a] - 1:
            others = ti.min(others, ti.max((home[a] + 1) * h - q[a], 0.0))
    return home, others


@ti.func
def _leaf_nearest(g: ti.template(), ci, leaf, p: vec3, best, point: vec3):
    """The nearest of the triangles in one leaf of the box tree, or for leaf -1 in the
    cell holding p (_home), if nearer than `best`; and a lower bound on their distance."""
    first = 0
    last = 0
    ids = 0  # triangle ids at ipool[ids + first ... ids + last - 1]
    if leaf < 0:
        # (each unused value its own name: one name given values of different types, as `_`
        # would be here, compiles to a mismatched store without Taichi's CFG optimisation)
        _origin, _h, dims, starts = _grid(g, ci)
        home, _others = _home(g, ci, p)
        first, last = _cell_span(g, starts, dims, home)
    else:
        _boxes, _leaves, ids = _tree(g, ci)
        ids += leaf * TREE_LEAF
        last = ti.min(TREE_LEAF, g.ishape[ci][2] - leaf * TREE_LEAF)
    vertices = g.ishape[ci][0]
    spheres = vertices + 3 * g.ishape[ci][7]
    low = INFINITY
    for k in range(first, last):
        best, point, bound = nearer_triangle(g, vertices, g.ishape[ci][1], spheres, g.ipool[ids + k], p, best, point)
        low = ti.min(low, bound)
    return best, point, low


@ti.func
def _nearest(g: ti.template(), ci, p: vec3, reach):
    """(distance, closest surface point, found): the nearest triangle to p within `reach`
    (INFINITY: at any range). The triangles of p's cell come first; the box tree
    (triangles.tree_nearest) settles what they leave open. Without a triangle within
    reach, (a lower bound on the distance, no less than reach; p; False)."""
    boxes, leaves, _ids = _tree(g, ci)  # (not `_` twice: see _leaf_nearest)
    _home_cell, others = _home(g, ci, p)
    dist, point, floor = tree_nearest(g, ci, boxes, leaves, p, reach, p, _leaf_nearest, True, others)
    found = dist < reach
    if not found:
        dist = floor
    return dist, point, found


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
def mesh_sdf(g: ti.template(), ci, p: vec3, reach=INFINITY):
    """(phi, outward normal) at local point p: the distance to the surface, negative inside
    a closed mesh, minus half the thickness. Exact where |phi| < reach (the caller's
    radius, say); farther out, phi is a lower bound no less than reach, and n points away
    from the mesh's centre. Inside a closed mesh, exact at every depth (the repulsion of a
    particle found deep inside needs its way out)."""
    inside = False
    if g.ishape[ci][6] != 0:  # closed
        inside = _inside_by_parity(g, ci, p)
    dist, point, found = _nearest(g, ci, p, INFINITY if inside else reach + g.fshape[ci][4])
    n = vec3(0.0, 1.0, 0.0)
    w = p - point
    if not found:
        w = p  # the local frame's origin is the centre of the mesh's bounds
    if w.norm() > 1e-12 * (1.0 + p.norm()):
        n = w.normalized()
    if inside:
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
                    scan_block: ti.template(),
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
    sorting.exclusive_scan(counts, counts.shape[0], block_sums, scan_block, starts)
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
    _count_and_scan(vertices, triangles, origin_t, float(h), dims_t, sorting.scan_block(runtime.info().arch), counts,
                    block_sums, starts, cursor)
    ids = np.zeros(max(int(starts[-1]), 1), dtype=np.int32)
    _fill_and_sort(vertices, triangles, origin_t, float(h), dims_t, starts, cursor, ids)
    return starts, ids[: int(starts[-1])]
