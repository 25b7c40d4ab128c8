"""Signed distance, outward normal and trajectory crossing of the analytic collider shapes,
in their local frames (docs/physics.md 1).

Every SDF takes a local point p and the shape's parameters and returns (phi, n): phi < 0
inside, phi > 0 outside, |phi| the distance to the surface, n the unit outward normal (the
gradient of phi). Local frames: the plane is y = 0 with normal +y; cylinder and capsule run
along the local y axis. These are the only copies of the formulas: the step kernels and the
host-side `signed_distance` / `normal` both reach them through geometry/dispatch.py.

Crossings return (hit, t, n) for a sphere of radius r whose centre moves on x0 -> x1: t in
[0, 1] the fraction of the segment at first contact, n the outward normal there, t = 0 for
a segment that starts in contact. The plane and the sphere are solved in closed form (linear
and quadratic in t); box, cylinder and capsule by conservative advancement (marching.py),
whose evaluator here is `convex_sdf`.
"""

import taichi as ti

from . import kinds

vec3 = ti.math.vec3
vec4 = ti.math.vec4

TINY = 1e-12


@ti.func
def sign_nonzero(a):
    """+1 for a >= 0, -1 otherwise: a face direction that is defined on the midplane too."""
    return 1.0 if a >= 0.0 else -1.0


@ti.func
def plane_sdf(p: vec3):
    return p.y, vec3(0.0, 1.0, 0.0)


@ti.func
def sphere_sdf(p: vec3, radius):
    length = p.norm()
    n = vec3(0.0, 1.0, 0.0)  # at the center every direction is closest; pick +y
    if length > TINY:
        n = p / length
    return length - radius, n


@ti.func
def box_sdf(p: vec3, half: vec3):
    q = ti.abs(p) - half
    outside = ti.max(q, 0.0)
    out_len = outside.norm()
    phi = 0.0
    n = vec3(0.0, 0.0, 0.0)
    if out_len > 0.0:
        # Outside: the gradient points from the closest surface point to p.
        phi = out_len
        n = vec3(sign_nonzero(p.x), sign_nonzero(p.y), sign_nonzero(p.z)) * outside / out_len
    else:
        # Inside (or on a face): the nearest face is the one with the largest q.
        phi = ti.max(q.x, q.y, q.z)
        if q.x >= q.y and q.x >= q.z:
            n = vec3(sign_nonzero(p.x), 0.0, 0.0)
        elif q.y >= q.z:
            n = vec3(0.0, sign_nonzero(p.y), 0.0)
        else:
            n = vec3(0.0, 0.0, sign_nonzero(p.z))
    return phi, n


@ti.func
def cylinder_sdf(p: vec3, radius, half_height):
    """Capped cylinder about the local y axis."""
    rho = ti.sqrt(p.x * p.x + p.z * p.z)
    radial = vec3(1.0, 0.0, 0.0)
    if rho > TINY:
        radial = vec3(p.x / rho, 0.0, p.z / rho)
    axial = vec3(0.0, sign_nonzero(p.y), 0.0)
    dr = rho - radius
    dy = ti.abs(p.y) - half_height
    phi = 0.0
    n = radial
    if dr > 0.0 and dy > 0.0:
        # Beyond the rim: distance to the circular edge.
        phi = ti.sqrt(dr * dr + dy * dy)
        n = (dr * radial + dy * axial) / phi
    elif dr >= dy:
        phi = dr  # the side wall is the nearest (or the only crossed) surface
        n = radial
    else:
        phi = dy
        n = axial
    return phi, n


@ti.func
def capsule_sdf(p: vec3, radius, half_height):
    """Segment from (0, -h, 0) to (0, h, 0), swept by a sphere of `radius`."""
    q = vec3(p.x, p.y - ti.math.clamp(p.y, -half_height, half_height), p.z)
    length = q.norm()
    n = vec3(1.0, 0.0, 0.0)  # on the axis every radial direction is closest; pick +x
    if length > TINY:
        n = q / length
    return length - radius, n


@ti.func
def convex_sdf(g: ti.template(), ci, kind, params: vec4, p: vec3):
    """(phi, n) of the shapes crossed by conservative advancement (box, cylinder, capsule):
    the evaluator marching.march_crossing takes for them (g and ci unused)."""
    phi = 0.0
    n = vec3(0.0, 1.0, 0.0)
    if kind == kinds.BOX:
        phi, n = box_sdf(p, vec3(params[0], params[1], params[2]))
    elif kind == kinds.CYLINDER:
        phi, n = cylinder_sdf(p, params[0], params[1])
    elif kind == kinds.CAPSULE:
        phi, n = capsule_sdf(p, params[0], params[1])
    return phi, n


@ti.func
def plane_heights_crossing(h0, h1, r):
    """First contact (hit, t) of a sphere of radius r whose centre goes from height h0 to h1
    above a plane."""
    d0 = h0 - r
    d1 = h1 - r
    hit = False
    t = 1.0
    if d0 < 0.0:
        hit, t = True, 0.0
    elif d1 < 0.0:
        hit, t = True, d0 / (d0 - d1)  # sign change of (x - P).n, linear in t
    return hit, t


@ti.func
def plane_crossing(x0: vec3, x1: vec3, r):
    hit, t = plane_heights_crossing(x0.y, x1.y, r)
    return hit, t, vec3(0.0, 1.0, 0.0)


@ti.func
def sphere_crossing(x0: vec3, x1: vec3, radius, r):
    # |x0 + t d|^2 = (R + r)^2  ->  a t^2 + 2 b t + c = 0, first root in [0, 1]
    R = radius + r
    d = x1 - x0
    a = d.dot(d)
    b = x0.dot(d)
    c = x0.dot(x0) - R * R
    hit = False
    t = 1.0
    if c < 0.0:
        hit, t = True, 0.0
    elif a > 0.0 and b < 0.0:
        disc = b * b - a * c
        if disc >= 0.0:
            # Root of the approaching branch, written to avoid cancellation: t = c / (-b + sqrt(disc)).
            root = c / (-b + ti.sqrt(disc))
            if root <= 1.0:
                hit, t = True, root
    p = x0 + t * d
    length = p.norm()
    n = vec3(0.0, 1.0, 0.0)
    if length > 1e-12:
        n = p / length
    return hit, t, n
