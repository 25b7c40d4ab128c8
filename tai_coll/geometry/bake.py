"""Baking a triangle mesh into a signed-distance grid, in Taichi kernels.

docs/physics.md 1, triangle mesh row. Grid nodes sit at origin + h (i, j, k), stored in C order
of (nx, ny, nz). Phases, each a kernel with one top-level parallel loop:

1. narrow band (parallel over triangles): every node within BAND_CELLS cells of a triangle
   gets the exact point-triangle distance; an i64 atomic minimum of (quantised distance,
   triangle id) keeps the closest triangle per node.
2. propagation (parallel over grid rows): an exact Euclidean distance transform of the band
   nodes (Felzenszwalb and Huttenlocher's lower envelope of parabolas, one axis at a time)
   gives every node its nearest band node; the node takes that node's triangle.
3. distance (parallel over nodes): the exact distance to that triangle; nodes within
   REFINE_CELLS cells of the surface then also try their 26 neighbours' triangles and walk
   the mesh (triangles sharing a vertex with the best one) while that improves, twice.
   Within REFINE_CELLS the result matches a brute-force minimum over all triangles (tests,
   tools/bench_sdf.py); beyond, it can exceed the exact distance by a fraction of a cell.
4. sign (parallel over triangles, then over rows): the winding number along each grid row
   from signed ray crossings (a fill rule equivalent to simulation of simplicity makes rows
   through vertices and edges count once). For a mesh with boundary edges the surface is
   closed by a cone over each boundary loop; the ray crossings then count the closed chain,
   and the cone's solid angle (exact near the loop, its dipole term far away) turns that
   into the generalized winding number of the open mesh (Jacobson et al. 2013): the same
   number a per-node sum of solid angles over all triangles would give, at a cost per node
   of one term per boundary loop instead of one per triangle.

Distances are in the mesh's units. The host-side driver `bake_grid` returns numpy arrays.
"""


import math
import time
from dataclasses import dataclass

import numpy as np
import taichi as ti

from .triangles import closest_on_triangle, edge_function

vec3 = ti.math.vec3

BAND_CELLS = 1.0     # exact rasterisation reaches this far from each triangle (cells)
REFINE_CELLS = 3.5   # nodes this close to the surface also test their neighbours' triangles
REFINE_PASSES = 2
WALK_STEPS = 4      # mesh-walk steps per refinement pass
QUANTUM = 1 << 24    # distance quantisation of the band key, per cell
FAR = 1e30
DIPOLE_RATIO = 4.0   # a boundary loop farther than this many of its radii counts as a dipole

SIGN_NONE = 0
SIGN_WINDING = 1   # signed ray crossings (+ boundary cones for open meshes)
SIGN_PARITY = 2    # ray crossings mod 2, orientation ignored


# ------------------------------------------------------------------------ small geometry
# closest_on_triangle: the one copy in triangles.py, shared with tc.TriangleMesh.
@ti.func
def vertex(verts: ti.template(), index) -> vec3:
    return vec3(verts[index, 0], verts[index, 1], verts[index, 2])


@ti.func
def triangle_distance(verts: ti.template(), faces: ti.template(), t, p: vec3):
    a = vertex(verts, faces[t, 0])
    b = vertex(verts, faces[t, 1])
    c = vertex(verts, faces[t, 2])
    return (closest_on_triangle(p, a, b, c) - p).norm()


@ti.func
def pick(v, axis):
    """v[axis] for a runtime axis, without dynamic indexing."""
    out = v[0]
    if axis == 1:
        out = v[1]
    elif axis == 2:
        out = v[2]
    return out


@ti.func
def from_columns(w, iu, iv, iw):
    """(i, j, k) of the node at (iu, iv) in the plane across axis w, iw along it, where
    u = (w + 1) % 3 and v = (w + 2) % 3."""
    i, j, k = iw, iu, iv
    if w == 1:
        i, j, k = iv, iw, iu
    elif w == 2:
        i, j, k = iu, iv, iw
    return i, j, k


@ti.func
def node_position(origin: vec3, h, i, j, k) -> vec3:
    return origin + h * vec3(i, j, k)


# ------------------------------------------------------------------------ 1. narrow band
@ti.kernel
def rasterise_band(verts: ti.types.ndarray(), faces: ti.types.ndarray(), origin: vec3, h: float, nx: ti.i32,
                   ny: ti.i32, nz: ti.i32, band: float,
                   # outputs
                   key: ti.types.ndarray(dtype=ti.i64, ndim=1)):
    """Per triangle: the nodes within `band` of it, scanned as columns along the axis w where
    the triangle's normal is largest; in each column only the slab |n.(x - a)| <= band."""
    dims = ti.Vector([nx, ny, nz])
    for t in range(faces.shape[0]):
        a = vertex(verts, faces[t, 0])
        b = vertex(verts, faces[t, 1])
        c = vertex(verts, faces[t, 2])
        normal = (b - a).cross(c - a)
        an = ti.abs(normal)
        w = 0
        if an[1] > an[0] and an[1] >= an[2]:
            w = 1
        elif an[2] > an[0] and an[2] > an[1]:
            w = 2
        u = (w + 1) % 3
        v = (w + 2) % 3
        lo = (ti.min(a, b, c) - band - origin) / h
        hi = (ti.max(a, b, c) + band - origin) / h
        u0 = ti.max(ti.cast(ti.ceil(pick(lo, u)), ti.i32), 0)
        u1 = ti.min(ti.cast(ti.floor(pick(hi, u)), ti.i32), pick(dims, u) - 1)
        v0 = ti.max(ti.cast(ti.ceil(pick(lo, v)), ti.i32), 0)
        v1 = ti.min(ti.cast(ti.floor(pick(hi, v)), ti.i32), pick(dims, v) - 1)
        w_lo = pick(lo, w)
        w_hi = pick(hi, w)
        nw = pick(normal, w)
        nu = pick(normal, u)
        nv = pick(normal, v)
        slab = band * normal.norm() / ti.max(ti.abs(nw), 1e-300)
        for iu in range(u0, u1 + 1):
            for iv in range(v0, v1 + 1):
                # The plane's w over this column, in cells: n.(x - a) = 0.
                pu = pick(origin, u) + h * iu - pick(a, u)
                pv = pick(origin, v) + h * iv - pick(a, v)
                lo_w = w_lo
                hi_w = w_hi
                if ti.abs(nw) > 0.0:
                    plane_w = (pick(a, w) - (nu * pu + nv * pv) / nw - pick(origin, w)) / h
                    lo_w = ti.max(lo_w, plane_w - slab / h)
                    hi_w = ti.min(hi_w, plane_w + slab / h)
                w0 = ti.max(ti.cast(ti.ceil(lo_w), ti.i32), 0)
                w1 = ti.min(ti.cast(ti.floor(hi_w), ti.i32), pick(dims, w) - 1)
                for iw in range(w0, w1 + 1):
                    i, j, k = from_columns(w, iu, iv, iw)
                    p = node_position(origin, h, i, j, k)
                    d = (closest_on_triangle(p, a, b, c) - p).norm()
                    if d <= band:
                        q = ti.cast(d / h * QUANTUM, ti.i64)
                        node = (i * ny + j) * nz + k
                        ti.atomic_min(key[node], (q << 32) | ti.cast(t, ti.i64))


@ti.kernel
def decode_band(key: ti.types.ndarray(dtype=ti.i64, ndim=1),
                # outputs
                tri: ti.types.ndarray(dtype=ti.i32, ndim=1), f: ti.types.ndarray(ndim=1),
                seed: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    """Band nodes become the seeds of the distance transform (f = 0, seed = themselves)."""
    for node in range(key.shape[0]):
        if key[node] < (ti.i64(1) << 62):
            tri[node] = ti.cast(key[node] & ti.i64(0xFFFFFFFF), ti.i32)
            f[node] = 0.0
            seed[node] = node
        else:
            tri[node] = -1
            f[node] = FAR
            seed[node] = -1


# ------------------------------------------------------------------------ 2. distance transform
@ti.kernel
def transform_axis(axis: ti.template(), nx: ti.i32, ny: ti.i32, nz: ti.i32, f: ti.types.ndarray(ndim=1),
                   seed: ti.types.ndarray(dtype=ti.i32, ndim=1),
                   # scratch
                   env_at: ti.types.ndarray(dtype=ti.i32, ndim=2), env_from: ti.types.ndarray(ndim=2),
                   row_f: ti.types.ndarray(ndim=2), row_seed: ti.types.ndarray(dtype=ti.i32, ndim=2)):
    """One axis of the exact squared Euclidean distance transform (in cells^2), in place:
    f(q) <- min_p f(p) + (q - p)^2 along every row of the grid parallel to `axis`; `seed`
    follows the minimiser. Felzenszwalb & Huttenlocher (2012), the lower envelope of parabolas."""
    n = nx
    rows = ny * nz
    if ti.static(axis == 1):
        n = ny
        rows = nx * nz
    elif ti.static(axis == 2):
        n = nz
        rows = nx * ny
    for r in range(rows):
        base = r
        stride = ny * nz
        if ti.static(axis == 1):
            base = (r // nz) * ny * nz + r % nz
            stride = nz
        elif ti.static(axis == 2):
            base = r * nz
            stride = 1
        for q in range(n):
            row_f[r, q] = f[base + q * stride]
            row_seed[r, q] = seed[base + q * stride]
        k = -1
        for q in range(n):
            fq = row_f[r, q]
            if fq < FAR:
                s = -FAR
                while k >= 0:
                    p = env_at[r, k]
                    s = ((fq + q * q) - (row_f[r, p] + p * p)) / (2.0 * (q - p))
                    if s <= env_from[r, k]:
                        k -= 1
                    else:
                        break
                if k < 0:
                    s = -FAR
                k += 1
                env_at[r, k] = q
                env_from[r, k] = s
        if k >= 0:
            top = k
            k = 0
            for q in range(n):
                while k < top and env_from[r, k + 1] <= q:
                    k += 1
                p = env_at[r, k]
                f[base + q * stride] = row_f[r, p] + (q - p) * (q - p)
                seed[base + q * stride] = row_seed[r, p]


# ------------------------------------------------------------------------ 3. distances
@ti.kernel
def distance_to_seed_triangle(verts: ti.types.ndarray(), faces: ti.types.ndarray(), origin: vec3, h: float,
                              ny: ti.i32, nz: ti.i32, seed: ti.types.ndarray(dtype=ti.i32, ndim=1),
                              band_tri: ti.types.ndarray(dtype=ti.i32, ndim=1),
                              # outputs
                              tri: ti.types.ndarray(dtype=ti.i32, ndim=1), dist: ti.types.ndarray(ndim=1)):
    for node in range(seed.shape[0]):
        i = node // (ny * nz)
        j = (node // nz) % ny
        k = node % nz
        t = -1
        d = FAR
        if seed[node] >= 0:
            t = band_tri[seed[node]]
            d = triangle_distance(verts, faces, t, node_position(origin, h, i, j, k))
        tri[node] = t
        dist[node] = d


@ti.kernel
def refine_from_neighbours(verts: ti.types.ndarray(), faces: ti.types.ndarray(), origin: vec3, h: float,
                           nx: ti.i32, ny: ti.i32, nz: ti.i32, reach: float,
                           band_tri: ti.types.ndarray(dtype=ti.i32, ndim=1),
                           ring_start: ti.types.ndarray(dtype=ti.i32, ndim=1),
                           ring_faces: ti.types.ndarray(dtype=ti.i32, ndim=1),
                           tri_in: ti.types.ndarray(dtype=ti.i32, ndim=1), dist_in: ti.types.ndarray(ndim=1),
                           # outputs
                           tri_out: ti.types.ndarray(dtype=ti.i32, ndim=1), dist_out: ti.types.ndarray(ndim=1)):
    """A Jacobi pass of closest-triangle propagation for nodes near the surface but outside
    the exact band: keep the closest of the node's own and its 26 neighbours' triangles, then
    walk the mesh: try every triangle sharing a vertex with the best one, while that improves.
    (A thin triangle can be the closest one for a node although no band node near it has it.)"""
    for node in range(tri_in.shape[0]):
        best_t = tri_in[node]
        best_d = dist_in[node]
        if band_tri[node] < 0 and best_d < reach:
            i = node // (ny * nz)
            j = (node // nz) % ny
            k = node % nz
            p = node_position(origin, h, i, j, k)
            for nb in range(27):  # a runtime loop: one inlined distance routine, not 26
                a = i + nb // 9 - 1
                b = j + (nb // 3) % 3 - 1
                c = k + nb % 3 - 1
                if 0 <= a < nx and 0 <= b < ny and 0 <= c < nz:
                    t = tri_in[(a * ny + b) * nz + c]
                    if t != best_t and t >= 0:
                        d = triangle_distance(verts, faces, t, p)
                        if d < best_d:
                            best_d, best_t = d, t
            for _ in range(WALK_STEPS):
                centre = best_t
                for corner in range(3):
                    v = faces[centre, corner]
                    for r in range(ring_start[v], ring_start[v + 1]):
                        t = ring_faces[r]
                        if t != best_t:
                            d = triangle_distance(verts, faces, t, p)
                            if d < best_d:
                                best_d, best_t = d, t
                if best_t == centre:
                    break
        tri_out[node] = best_t
        dist_out[node] = best_d


# ------------------------------------------------------------------------ 4. sign
@ti.kernel
def count_crossings(tri_verts: ti.types.ndarray(), weight: ti.types.ndarray(dtype=ti.i32, ndim=1), origin: vec3,
                    h: float, nx: ti.i32, ny: ti.i32, nz: ti.i32, parity: ti.i32,
                    # outputs
                    count: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    """Rays along +x through every grid row (j, k): where triangle t crosses the row at x_c,
    count[first node beyond x_c] gets the crossing's winding contribution, +w entering
    (normal's x < 0), -w leaving; with `parity`, +1 for any crossing."""
    for t in range(weight.shape[0]):
        a = vertex(tri_verts, 3 * t)
        b = vertex(tri_verts, 3 * t + 1)
        c = vertex(tri_verts, 3 * t + 2)
        area = (b.y - a.y) * (c.z - a.z) - (b.z - a.z) * (c.y - a.y)  # normal's x component
        if area != 0.0:
            j0 = ti.max(ti.cast(ti.ceil((ti.min(a.y, b.y, c.y) - origin.y) / h), ti.i32), 0)
            j1 = ti.min(ti.cast(ti.floor((ti.max(a.y, b.y, c.y) - origin.y) / h), ti.i32), ny - 1)
            k0 = ti.max(ti.cast(ti.ceil((ti.min(a.z, b.z, c.z) - origin.z) / h), ti.i32), 0)
            k1 = ti.min(ti.cast(ti.floor((ti.max(a.z, b.z, c.z) - origin.z) / h), ti.i32), nz - 1)
            contribution = weight[t]
            if parity == 0:
                contribution = -weight[t] if area > 0.0 else weight[t]
            for j in range(j0, j1 + 1):
                for k in range(k0, k1 + 1):
                    py = origin.y + h * j
                    pz = origin.z + h * k
                    ea, sa = edge_function(b.y, b.z, c.y, c.z, py, pz)  # barycentric weight of a
                    eb, sb = edge_function(c.y, c.z, a.y, a.z, py, pz)
                    ec, sc = edge_function(a.y, a.z, b.y, b.z, py, pz)
                    if (sa > 0.0 and sb > 0.0 and sc > 0.0) or (sa < 0.0 and sb < 0.0 and sc < 0.0):
                        xc = (ea * a.x + eb * b.x + ec * c.x) / (ea + eb + ec)  # 0 <= weights (ties: 0)
                        i = ti.max(ti.cast(ti.floor((xc - origin.x) / h), ti.i32) + 1, 0)
                        if i < nx:
                            ti.atomic_add(count[(i * ny + j) * nz + k], contribution)


@ti.kernel
def sum_rows(nx: ti.i32, ny: ti.i32, nz: ti.i32, count: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    """Prefix sums along x: the crossings before each node, i.e. its ray winding number."""
    for r in range(ny * nz):
        total = 0
        for i in range(nx):
            total += count[i * ny * nz + r]
            count[i * ny * nz + r] = total


@ti.func
def solid_angle(a: vec3, b: vec3, c: vec3) -> float:
    """Signed solid angle of triangle abc seen from the origin (Van Oosterom & Strackee 1983)."""
    la = a.norm()
    lb = b.norm()
    lc = c.norm()
    det = a.dot(b.cross(c))
    den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb
    return 2.0 * ti.atan2(det, den)


@ti.kernel
def cone_winding(origin: vec3, h: float, ny: ti.i32, nz: ti.i32, loop_start: ti.types.ndarray(dtype=ti.i32, ndim=1),
                 loop_apex: ti.types.ndarray(), loop_area: ti.types.ndarray(), loop_radius: ti.types.ndarray(ndim=1),
                 edge_ends: ti.types.ndarray(), edge_net: ti.types.ndarray(dtype=ti.i32, ndim=1),
                 # outputs
                 winding: ti.types.ndarray(ndim=1)):
    """Adds to each node the winding number of the cones closing the boundary loops:
    sum over boundary edges (a, b) of net * solid angle(apex, a, b) / 4 pi, or for a loop far
    away its dipole term A . (apex - p) / |apex - p|^3 / 4 pi (A: the loop's area vector)."""
    for node in range(winding.shape[0]):
        i = node // (ny * nz)
        j = (node // nz) % ny
        k = node % nz
        p = node_position(origin, h, i, j, k)
        total = 0.0
        for loop in range(loop_radius.shape[0]):
            apex = vec3(loop_apex[loop, 0], loop_apex[loop, 1], loop_apex[loop, 2]) - p
            dist = apex.norm()
            if dist > DIPOLE_RATIO * loop_radius[loop]:
                area = vec3(loop_area[loop, 0], loop_area[loop, 1], loop_area[loop, 2])
                total += area.dot(apex) / (dist * dist * dist)
            else:
                for e in range(loop_start[loop], loop_start[loop + 1]):
                    a = vec3(edge_ends[e, 0], edge_ends[e, 1], edge_ends[e, 2]) - p
                    b = vec3(edge_ends[e, 3], edge_ends[e, 4], edge_ends[e, 5]) - p
                    total += edge_net[e] * solid_angle(apex, a, b)
        winding[node] += total / (4.0 * math.pi)


@ti.kernel
def combine(dist: ti.types.ndarray(ndim=1), winding: ti.types.ndarray(ndim=1), mode: ti.i32,
            # outputs
            phi: ti.types.ndarray(ndim=1)):
    for node in range(dist.shape[0]):
        inside = False
        if mode == SIGN_WINDING:
            inside = winding[node] > 0.5
        elif mode == SIGN_PARITY:
            inside = ti.cast(ti.round(winding[node]), ti.i32) % 2 != 0
        phi[node] = -dist[node] if inside else dist[node]


# ------------------------------------------------------------------------ host driver
@dataclass
class BakedGrid:
    values: np.ndarray       # (nx, ny, nz) signed (or unsigned) distances
    origin: np.ndarray       # node (0, 0, 0), local frame
    voxel_size: float
    sign_method: str
    seconds: float           # wall time of the bake, kernels and transfers


def boundary_loops(vertices: np.ndarray, faces: np.ndarray):
    """The boundary of the oriented triangle chain: undirected edges with a non-zero net
    count (+1 per face using it as lo->hi, -1 as hi->lo), grouped into connected loops.
    Returns (edges (E, 2) as lo->hi, net (E,), loop id per edge, number of loops)."""
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]).astype(np.int64)
    forward = directed[:, 0] < directed[:, 1]
    lo = np.where(forward, directed[:, 0], directed[:, 1])
    hi = np.where(forward, directed[:, 1], directed[:, 0])
    keys = lo * (len(vertices) + 1) + hi
    unique, inverse = np.unique(keys, return_inverse=True)
    net = np.zeros(len(unique), dtype=np.int64)
    np.add.at(net, inverse, np.where(forward, 1, -1))
    keep = net != 0
    edges = np.column_stack([unique[keep] // (len(vertices) + 1), unique[keep] % (len(vertices) + 1)])
    net = net[keep]
    if len(edges) == 0:
        return edges, net, np.zeros(0, dtype=np.int64), 0
    # Connected components of the boundary graph (union-find with path halving).
    parent = np.arange(len(vertices))

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for a, b in edges:
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[ra] = rb
    roots = np.array([find(a) for a in edges[:, 0]])
    _, loop = np.unique(roots, return_inverse=True)
    return edges, net, loop, int(loop.max()) + 1


def vertex_rings(n_vertices: int, faces: np.ndarray):
    """The faces around each vertex, as CSR arrays (start (V + 1,), faces)."""
    owner = faces.ravel().astype(np.int64)
    order = np.argsort(owner, kind="stable")
    start = np.searchsorted(owner[order], np.arange(n_vertices + 1)).astype(np.int32)
    return start, (order // 3).astype(np.int32)


def _loop_arrays(vertices, edges, net, loop, n_loops, dtype):
    order = np.argsort(loop, kind="stable")
    edges, net, loop = edges[order], net[order], loop[order]
    start = np.searchsorted(loop, np.arange(n_loops + 1)).astype(np.int32)
    a = vertices[edges[:, 0]]
    b = vertices[edges[:, 1]]
    apex = np.zeros((n_loops, 3))
    np.add.at(apex, loop, 0.5 * (a + b))
    apex /= np.bincount(loop, minlength=n_loops)[:, None]
    radius = np.zeros(n_loops)
    np.maximum.at(radius, loop, np.maximum(np.linalg.norm(a - apex[loop], axis=1),
                                           np.linalg.norm(b - apex[loop], axis=1)))
    area = np.zeros((n_loops, 3))
    np.add.at(area, loop, 0.5 * net[:, None] * np.cross(a - apex[loop], b - apex[loop]))
    return (start, apex.astype(dtype), area.astype(dtype), radius.astype(dtype),
            np.ascontiguousarray(np.hstack([a, b]), dtype=dtype), net.astype(np.int32))


def bake_grid(vertices: np.ndarray, faces: np.ndarray, origin, voxel_size: float, dims, sign: str,
              dtype=np.float64) -> BakedGrid:
    """Signed distance grid of the mesh (vertices (V, 3), faces (F, 3)) on the nodes
    origin + voxel_size * (i, j, k), 0 <= (i, j, k) < dims. sign: "winding" (winding number
    from ray crossings; the generalized winding number when the mesh has boundary edges),
    "parity" (ray crossings mod 2) or "none" (unsigned distance)."""
    started = time.perf_counter()
    nx, ny, nz = (int(d) for d in dims)
    n_nodes = nx * ny * nz
    h = float(voxel_size)
    o = vec3(*[float(x) for x in origin])
    verts = np.ascontiguousarray(vertices, dtype=dtype)
    tris = np.ascontiguousarray(faces, dtype=np.int32)

    # 1. narrow band
    key = np.full(n_nodes, np.iinfo(np.int64).max, dtype=np.int64)
    rasterise_band(verts, tris, o, h, nx, ny, nz, BAND_CELLS * h, key)
    band_tri = np.empty(n_nodes, dtype=np.int32)
    f = np.empty(n_nodes, dtype=dtype)
    seed = np.empty(n_nodes, dtype=np.int32)
    decode_band(key, band_tri, f, seed)
    del key

    # 2. nearest band node everywhere
    for axis, n in enumerate((nx, ny, nz)):
        rows = n_nodes // n
        transform_axis(axis, nx, ny, nz, f, seed, np.empty((rows, n), dtype=np.int32),
                       np.empty((rows, n), dtype=dtype), np.empty((rows, n), dtype=dtype),
                       np.empty((rows, n), dtype=np.int32))
    del f

    # 3. exact distance to the propagated triangle, refined near the surface
    tri = np.empty(n_nodes, dtype=np.int32)
    dist = np.empty(n_nodes, dtype=dtype)
    distance_to_seed_triangle(verts, tris, o, h, ny, nz, seed, band_tri, tri, dist)
    del seed
    tri2, dist2 = np.empty_like(tri), np.empty_like(dist)
    ring_start, ring_faces = vertex_rings(len(verts), tris)
    for _ in range(REFINE_PASSES):
        refine_from_neighbours(verts, tris, o, h, nx, ny, nz, REFINE_CELLS * h, band_tri, ring_start, ring_faces,
                               tri, dist, tri2, dist2)
        tri, tri2, dist, dist2 = tri2, tri, dist2, dist

    # 4. sign
    method = "none (unsigned distance)"
    mode = SIGN_NONE
    winding = np.zeros(n_nodes, dtype=dtype)
    if sign in ("winding", "parity"):
        edges, net, loop, n_loops = boundary_loops(verts, tris)
        tri_verts = verts[tris].reshape(-1, 3)
        weight = np.ones(len(tris), dtype=np.int32)
        mode = SIGN_PARITY if sign == "parity" else SIGN_WINDING
        loops = None
        if mode == SIGN_WINDING and n_loops:
            loops = _loop_arrays(verts, edges, net, loop, n_loops, dtype)
            start, apex, _, _, ends, net32 = loops
            # Cone triangles (apex, a, b) enter the ray count with weight -net (closed chain S - C).
            edge_loop = np.repeat(np.arange(n_loops), np.diff(start))
            cone = np.stack([apex[edge_loop], ends[:, :3], ends[:, 3:]], axis=1).reshape(-1, 3)
            tri_verts = np.concatenate([tri_verts, cone])
            weight = np.concatenate([weight, -net32])
        count = np.zeros(n_nodes, dtype=np.int32)
        count_crossings(np.ascontiguousarray(tri_verts, dtype=dtype), weight, o, h, nx, ny, nz,
                        int(mode == SIGN_PARITY), count)
        sum_rows(nx, ny, nz, count)
        winding = count.astype(dtype)
        if loops is not None:
            start, apex, area, radius, ends, net32 = loops
            cone_winding(o, h, ny, nz, start, apex, area, radius, ends, net32, winding)
            method = (f"generalized winding number (open mesh, {n_loops} boundary loop(s): "
                      f"ray crossings of the mesh closed by cones, plus the cones' solid angles)")
        elif mode == SIGN_WINDING:
            method = "winding number by ray crossings (closed mesh)"
        else:
            method = "ray crossing parity"
    phi = np.empty(n_nodes, dtype=dtype)
    combine(dist, winding, mode, phi)
    return BakedGrid(values=phi.reshape(nx, ny, nz).astype(np.float64), origin=np.asarray(origin, dtype=np.float64),
                     voxel_size=h, sign_method=method, seconds=time.perf_counter() - started)
