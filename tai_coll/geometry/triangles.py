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
"""

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
