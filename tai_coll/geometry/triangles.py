"""Exact queries against single triangles, shared by triangle meshes and height fields.

docs/physics.md 1, last rows of the table. Every function is a pure @ti.func on vertices given
in one frame:

- `closest_on_triangle`: the closest point of a triangle (Ericson, Real-Time Collision
  Detection 5.1.5: Voronoi regions of vertices, edges and the face).
- `swept_sphere_triangle`: first contact of a sphere of radius R whose center moves on the
  segment x0 -> x0 + d, exactly: the sphere touches the triangle when its center reaches
  distance R, i.e. enters the triangle's Minkowski sum with a ball (a slab of half-width R
  over the face, capsules of radius R around the three edges; the capsules' end spheres
  cover the vertices). The face part is the segment against the plane offset by R on the
  start's side (the determinant test of Moller-Trumbore with an offset), then an inside
  test of the touching point; each edge is a segment-capsule intersection. Starting within
  R and moving closer reports t = 0; contacts the path only grazes or leaves are skipped.
  With R = 0 this is the plain segment-triangle test.
- `ray_x_crossing`: whether the line through q along x passes through a triangle, decided on
  the triangle's shadow in the yz plane with edge functions that are exactly antisymmetric
  under swapping an edge's ends, and ties broken by simulation of simplicity (q moved by
  (eps, eps^2) in (y, z)). A ray through a shared edge or vertex therefore counts exactly
  once over a closed mesh: the parity of the count tells inside from outside.

And the box tree that keeps nearest-point searches exact at any range, for a particle of
any radius (docs/physics.md 1.2), where cells alone would stop short (a point many cells
from the surface); triangle meshes and height fields use it.

- `box_tree` (host, numpy): a complete binary tree of bounding boxes over items
  (triangles, blocks of terrain cells), `per_leaf` to a leaf, each node split at the
  median of the items' centres along the axis where they spread most; `triangle_tree`
  builds it over a mesh's triangles, with a bounding sphere per triangle;
- `tree_nearest`: branch and bound down that tree, nearer child first, skipping every box
  no nearer than the best distance found so far. The tree is complete, so the walk needs
  no stack: the node's heap index and one bit per level (which child came first) say
  where to go next. `nearer_triangle` is the test of one triangle in a leaf.
"""

import numpy as np
import taichi as ti

vec3 = ti.math.vec3

TINY = 1e-30
MISS = 2.0  # a fraction beyond every segment: "no contact"
ENTER_EPS = 1e-6  # a path enters a contact when n . d < -ENTER_EPS |d| (relative round-off)


@ti.func
def closest_on_triangle(p: vec3, a: vec3, b: vec3, c: vec3) -> vec3:
    """The point of triangle abc closest to p (degenerate triangles included)."""
    ab = b - a
    ac = c - a
    ap = p - a
    d1 = ab.dot(ap)
    d2 = ac.dot(ap)
    bp = p - b
    d3 = ab.dot(bp)
    d4 = ac.dot(bp)
    cp = p - c
    d5 = ab.dot(cp)
    d6 = ac.dot(cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    q = a
    if d1 <= 0.0 and d2 <= 0.0:
        q = a  # vertex a
    elif d3 >= 0.0 and d4 <= d3:
        q = b  # vertex b
    elif d6 >= 0.0 and d5 <= d6:
        q = c  # vertex c
    elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        q = a + d1 / (d1 - d3) * ab  # edge ab
    elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        q = a + d2 / (d2 - d6) * ac  # edge ac
    elif va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        q = b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b)  # edge bc
    else:
        denom = va + vb + vc
        if ti.abs(denom) > TINY:
            q = a + (vb / denom) * ab + (vc / denom) * ac  # face interior
        else:
            q = a
    return q


@ti.func
def sphere_entry(x0: vec3, d: vec3, dd, center: vec3, R):
    """Smallest t >= 0 with |x0 + t d - center| = R while entering, else MISS."""
    oc = x0 - center
    b = d.dot(oc)
    c = oc.dot(oc) - R * R
    t = MISS
    disc = b * b - dd * c
    if dd > TINY and b < 0.0 and disc >= 0.0:
        root = (-b - ti.sqrt(disc)) / dd
        if root >= 0.0:
            t = root
    return t


@ti.func
def capsule_entry(x0: vec3, d: vec3, dd, a: vec3, b: vec3, R):
    """Smallest t >= 0 at which x0 + t d enters the capsule of radius R around segment ab,
    else MISS (Quilez's capsule intersection, for a direction d of any length). The body is
    an infinite cylinder clipped to the segment's span; a path entering the cylinder beyond
    one end, or moving along the axis, enters the end sphere on that side first, so only
    that one sphere is tested."""
    ba = b - a
    oa = x0 - a
    baba = ba.dot(ba)
    bard = ba.dot(d)
    baoa = ba.dot(oa)
    qa = baba * dd - bard * bard
    qb = baba * d.dot(oa) - baoa * bard
    qc = baba * oa.dot(oa) - baoa * baoa - R * R * baba
    t = MISS
    cap = a
    test_cap = False
    h = qb * qb - qa * qc
    if qa > TINY * baba * dd:
        if h >= 0.0:
            root = (-qb - ti.sqrt(h)) / qa
            y = baoa + root * bard
            if 0.0 < y and y < baba:
                if root >= 0.0:
                    t = root
            else:
                test_cap = True
                if y > 0.0:
                    cap = b
    else:
        test_cap = True  # moving along the edge: the end met first
        if bard < 0.0:
            cap = b
    if test_cap:
        t = sphere_entry(x0, d, dd, cap, R)
    return t


@ti.func
def segment_point(p: vec3, a: vec3, b: vec3) -> vec3:
    """The point of segment ab closest to p."""
    ab = b - a
    s = 0.0
    abab = ab.dot(ab)
    if abab > TINY:
        s = ti.math.clamp((p - a).dot(ab) / abab, 0.0, 1.0)
    return a + s * ab


@ti.func
def swept_sphere_triangle(x0: vec3, d: vec3, a: vec3, b: vec3, c: vec3, R):
    """First fraction t in [0, 1] at which a sphere of radius R centered on x0 + t d runs
    into triangle abc, and the contact normal (unit, from the triangle toward the center):
    (t, n), t = MISS when it does not. t = 0 when x0 already lies within R and moves closer.

    The start and each contact are classified by the part of the Minkowski sum they meet:
    the slab over the face (normal: the face normal on the start's side) or an edge's
    capsule (normal: from the edge's closest point). Contacts that the path only grazes or
    leaves (n . d >= -ENTER_EPS |d|) do not count: they cannot stop the particle, and at a
    concave crease, after a response has made the path tangent to one face, they would
    hide the face it runs into next."""
    t = MISS
    dd = d.dot(d)
    enter = -ENTER_EPS * ti.sqrt(dd)
    face = (b - a).cross(c - a)
    area2 = face.norm()
    n = vec3(0.0, 1.0, 0.0)
    side = 1.0
    if area2 > TINY:
        n = face / area2
        s0 = n.dot(x0 - a)
        if s0 < 0.0:
            side = -1.0
        # Face: the start itself when it lies within R of the plane, else the plane offset
        # by R toward the start; either counts when its point on the plane is inside.
        speed = side * n.dot(d)  # < 0: approaching the plane
        if speed < enter:
            tf = 0.0
            q = x0 - s0 * n
            if ti.abs(s0) >= R:
                tf = (ti.abs(s0) - R) / -speed
                q = x0 + tf * d - side * R * n
            if tf <= 1.0 and (face.dot((b - a).cross(q - a)) >= 0.0 and face.dot((c - b).cross(q - b)) >= 0.0
                              and face.dot((a - c).cross(q - c)) >= 0.0):
                t = tf
    normal = side * n
    # Edges and vertices: the three capsules (one call site, three passes).
    for e in range(3):
        p0 = a
        p1 = b
        if e == 1:
            p0, p1 = b, c
        elif e == 2:
            p0, p1 = c, a
        te = 0.0
        if (x0 - segment_point(x0, p0, p1)).norm() >= R:
            te = capsule_entry(x0, d, dd, p0, p1, R)
        if te < t:
            w = x0 + te * d
            w -= segment_point(w, p0, p1)
            length = w.norm()
            if length > TINY and w.dot(d) < enter * length:
                t = te
                normal = w / length
    if t > 1.0:
        t = MISS
    return t, normal


@ti.func
def edge_function(ay, az, by, bz, py, pz):
    """Twice the signed area of (a, b, p) in the (y, z) plane, and its sign with simulation
    of simplicity for p on the line (p taken at (y + eps, z + eps^2)). Computed from the
    edge's lexicographically smaller end, so the two triangles sharing an edge get exactly
    opposite values and a row through the edge is counted in exactly one of them."""
    flip = 1.0
    if ay > by or (ay == by and az > bz):
        ay, az, by, bz = by, bz, ay, az
        flip = -1.0
    e = (by - ay) * (pz - az) - (bz - az) * (py - ay)
    sign = e
    if e == 0.0:
        sign = -(bz - az)
        if sign == 0.0:
            sign = by - ay
    return flip * e, flip * sign


@ti.func
def ray_x_crossing(q: vec3, a: vec3, b: vec3, c: vec3):
    """Whether the line q + s (1, 0, 0) passes through triangle abc: (passes, x where it
    does); the ray toward +x crosses it when that x > q.x, the ray toward -x when x < q.x.

    Decided on the yz shadow by the edge functions e(p0, p1) = (p0 - q) x (p1 - q) (yz
    components) of the directed edges ab, bc, ca: inside when all three have one sign.
    Each is `edge_function` of the edge: exactly negated when the edge's ends swap (also
    where the compiler fuses a multiply and an add, as CUDA code does), a zero broken by
    moving q by (eps, eps^2) in (y, z) (simulation of simplicity); an edge that is a point in
    yz stays 0 and never counts. The hit's x interpolates the vertices with the edge
    functions as barycentric weights (each weighs the vertex opposite its edge), so it stays
    in the triangle's x range."""
    positive = 0
    negative = 0
    weighted = 0.0
    total = 0.0
    for k in range(3):
        p0, p1, opposite = a, b, c
        if k == 1:
            p0, p1, opposite = b, c, a
        elif k == 2:
            p0, p1, opposite = c, a, b
        e, key = edge_function(p0.y, p0.z, p1.y, p1.z, q.y, q.z)
        if key > 0.0:
            positive += 1
        elif key < 0.0:
            negative += 1
        weighted += e * opposite.x
        total += e
    x = (a.x + b.x + c.x) / 3.0
    if total != 0.0:
        x = weighted / total
    return positive == 3 or negative == 3, x


# ---------------------------------------------------------------------------- box tree

EMPTY = 1e30  # the box of a padding leaf runs from +EMPTY to -EMPTY: no search reaches it
INFINITY = 3e30  # farther than any box
TREE_LEAF = 4    # triangles per leaf of a triangle_tree


def box_tree(lo, hi, keys, per_leaf: int, dtype):
    """A complete binary tree of boxes over N items with boxes [lo, hi] ((N, 3) each; an
    infinite side may be given as -EMPTY or +EMPTY), split top-down at the median of `keys`
    ((N, 3) points, e.g. the items' centres) along the axis where they spread most.

    Returns (order, leaves, boxes): order (N,) int32 lists the items leaf by leaf (leaf k
    holds order[k per_leaf : (k + 1) per_leaf]); leaves, a power of two, is the number of
    leaves; boxes (2 leaves, 6) in `dtype` holds (lo, hi) of node i at row i, in heap order
    (root 1, children 2i and 2i + 1, leaf k at row leaves + k; row 0 unused). Boxes grow by
    a few units in the last place of `dtype`, so that they hold their items as the kernels
    compute them."""
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    count = len(lo)
    leaves = 1
    while leaves * per_leaf < count:
        leaves *= 2
    slots = leaves * per_leaf
    # Padding items (no key: they sort last in every node) fill the last leaves.
    keys = np.vstack([np.asarray(keys, dtype=np.float64), np.full((slots - count, 3), np.nan)])
    order = np.arange(slots)
    size = slots
    while size > per_leaf:
        node = np.arange(slots) // size
        starts = np.arange(0, slots, size)
        k = keys[order]
        spread = np.fmax.reduceat(k, starts, axis=0) - np.fmin.reduceat(k, starts, axis=0)
        axis = np.argmax(np.nan_to_num(spread, nan=-1.0), axis=1)[node]
        key = np.nan_to_num(k[np.arange(slots), axis], nan=np.inf)
        order = order[np.lexsort((key, node))]
        size //= 2
    slack = 4.0 * np.finfo(dtype).eps
    padded_lo = np.full((slots, 3), EMPTY)
    padded_hi = np.full((slots, 3), -EMPTY)
    real = order < count
    padded_lo[real] = lo[order[real]] - slack * (1.0 + np.abs(lo[order[real]]))
    padded_hi[real] = hi[order[real]] + slack * (1.0 + np.abs(hi[order[real]]))
    boxes = np.empty((2 * leaves, 6))
    boxes[0] = (EMPTY,) * 3 + (-EMPTY,) * 3
    boxes[leaves:, :3] = padded_lo.reshape(leaves, per_leaf, 3).min(axis=1)
    boxes[leaves:, 3:] = padded_hi.reshape(leaves, per_leaf, 3).max(axis=1)
    level = leaves // 2
    while level >= 1:
        boxes[level:2 * level, :3] = np.minimum(boxes[2 * level:4 * level:2, :3], boxes[2 * level + 1:4 * level:2, :3])
        boxes[level:2 * level, 3:] = np.maximum(boxes[2 * level:4 * level:2, 3:], boxes[2 * level + 1:4 * level:2, 3:])
        level //= 2
    return order[real].astype(np.int32), leaves, np.clip(boxes, -EMPTY, EMPTY).astype(dtype)


def triangle_tree(vertices, faces, dtype):
    """A mesh's triangles (vertices (V, 3) as the kernels read them, faces (F, 3)) under a
    box_tree of TREE_LEAF triangles a leaf: (spheres (F, 4) in dtype, centre and radius of
    a sphere around each triangle, rounded up so that it holds the triangle in dtype too;
    then box_tree's order, leaves, boxes)."""
    corners = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    centers = corners.mean(axis=1)
    radii = np.linalg.norm(corners - centers[:, None], axis=2).max(axis=1)
    spheres = np.column_stack([centers, radii * (1 + 1e-5) + 1e-7 * (1 + np.abs(centers).max(axis=1))])
    order, leaves, boxes = box_tree(corners.min(axis=1), corners.max(axis=1), centers, TREE_LEAF, dtype)
    return spheres.astype(dtype), order, leaves, boxes


@ti.func
def _pool_vertex(g: ti.template(), vertices, v) -> vec3:
    k = vertices + 3 * v
    return vec3(g.fpool[k], g.fpool[k + 1], g.fpool[k + 2])


@ti.func
def nearer_triangle(g: ti.template(), vertices, triangles, spheres, tri, p: vec3, best, point: vec3):
    """(best, point) improved by triangle `tri` of a mesh in the pools: vertex v at
    fpool[vertices + 3 v], the triangle's vertex indices at ipool[triangles + 3 tri], its
    bounding sphere at fpool[spheres + 4 tri] (the triangle is skipped when the sphere
    lies no nearer than best); and a lower bound on the triangle's distance (the distance
    itself, or the sphere's)."""
    k = spheres + 4 * tri
    low = (p - vec3(g.fpool[k], g.fpool[k + 1], g.fpool[k + 2])).norm() - g.fpool[k + 3]
    if low < best:
        t = triangles + 3 * tri
        found = closest_on_triangle(p, _pool_vertex(g, vertices, g.ipool[t]), _pool_vertex(g, vertices, g.ipool[t + 1]),
                                    _pool_vertex(g, vertices, g.ipool[t + 2]))
        low = (p - found).norm()
        if low < best:
            best, point = low, found
    return best, point, low


@ti.func
def box_gap(g: ti.template(), base, node, p: vec3):
    """Distance from p to the box of tree node `node`, whose boxes start at fpool[base]."""
    k = base + 6 * node
    lo = vec3(g.fpool[k], g.fpool[k + 1], g.fpool[k + 2])
    hi = vec3(g.fpool[k + 3], g.fpool[k + 4], g.fpool[k + 5])
    return ti.max(lo - p, p - hi, 0.0).norm()


@ti.func
def tree_nearest(g: ti.template(), ci, base, leaves, p: vec3, best, point: vec3, leaf_nearest: ti.template(),
                 seeded: ti.template(), certain):
    """The nearest item of a box_tree to p, if nearer than `best` (with its `point`), the
    distance already known or the farthest the caller needs to look: (distance, closest
    point, floor). `leaf_nearest(g, ci, leaf, p, best, point)` searches the items of one
    leaf and returns the improved (best, point) and a lower bound on the distance to its
    items. Exact: a box is skipped only when no point in it is nearer than `best`. When
    nothing nearer than the given best is found, `floor` (>= best) is a lower bound on the
    distance to every item: the least of the skipped boxes' gaps and the leaves' bounds.

    seeded (compile time): first call leaf_nearest with leaf -1, the caller's own first
    guess (the cells around p, say), and stop there when its best is within `certain` (the
    distance from p to everything that guess left out).

    The walk visits the nearer child first; `second` holds, per depth, whether the node on
    the current path is its parent's second child: after a node, the walk climbs over
    second children and moves to the first such sibling not yet visited."""
    node = 0 if ti.static(seeded) else 1  # node 0: the caller's guess, then the root
    depth = 0
    second = 0
    floor = INFINITY
    gap = 0.0
    known = 0  # whether `gap` is the current node's (node 0, the guess, has none)
    if ti.static(seeded):
        known = 1
    while True:
        if known == 0:
            gap = box_gap(g, base, node, p)
        known = 0
        descended = False
        if gap >= best:
            floor = ti.min(floor, gap)
        elif node == 0 or node >= leaves:
            best, point, low = leaf_nearest(g, ci, node - leaves if node != 0 else -1, p, best, point)
            floor = ti.min(floor, low)
        else:
            near = 2 * node
            gap = INFINITY
            for child in range(2 * node, 2 * node + 2):
                child_gap = box_gap(g, base, child, p)
                if child_gap < gap:
                    near, gap = child, child_gap
            node = near
            known = 1
            depth += 1
            second &= ~(1 << depth)
            descended = True
        if node == 0:
            if best <= certain:
                floor = ti.min(floor, certain)
                break
            node = 1
        elif not descended:
            while depth > 0 and ((second >> depth) & 1) == 1:
                node >>= 1
                depth -= 1
            if depth == 0:
                break
            node ^= 1
            second |= 1 << depth
    return best, point, floor
