"""Trajectory crossing: where a moving sphere of radius r first touches a collider.

PHYSICS.md 1, last column. The particle center moves on the segment x0 -> x1 (local frame);
it touches when phi(x) = r. Each function returns (hit, t, n): t in [0, 1] is the fraction
of the segment at first contact, n the outward normal there. A segment that starts in
contact (phi(x0) < r) reports hit at t = 0. Plane and sphere are solved in closed form
(linear and quadratic in t); box, cylinder and capsule by conservative advancement: phi is
1-Lipschitz, so stepping t by (phi - r) / |x1 - x0| can never step over the surface.
"""

import taichi as ti

from . import height_field, kinds, triangle_mesh
from .grid_sdf import grid_crossing
from .implicit_eval import implicit_crossing
from .sdf import local_sdf, vec3, vec4

# Conservative advancement: iteration cap, and how close (relative to the particle
# radius, or absolutely for points) counts as touching.
ADVANCE_ITERATIONS = 48
SEARCH_ITERATIONS = 48
BISECT_ITERATIONS = 40
ADVANCE = 0
SEARCH = 1
BISECT = 2
TOUCH_REL = 1e-4
TOUCH_ABS = 1e-7


@ti.func
def plane_crossing(x0: vec3, x1: vec3, r):
    d0 = x0.y - r
    d1 = x1.y - r
    hit = False
    t = 1.0
    if d0 < 0.0:
        hit, t = True, 0.0
    elif d1 < 0.0:
        hit, t = True, d0 / (d0 - d1)  # sign change of (x - P).n, linear in t
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


@ti.func
def advance_crossing(g: ti.template(), ci, kind: ti.i32, params: vec4, x0: vec3, x1: vec3, r):
    """First t with phi(x0 + t d) = r for the convex shapes (box, cylinder, capsule).

    Three phases around one SDF evaluation per iteration (each call site of `local_sdf`
    inlines all five shapes, and kernel compile time grows with their number):
    - advance: step t by (phi - r) / |d|, which never steps over the surface. Along a line
      phi is convex, so once its slope n . d turns non-negative while still clear, the
      segment can never touch: stop.
    - minimum search, when advancing runs out of patience on a grazing path: bisect on the
      sign of the slope toward the minimum of phi; clear at the minimum means a miss.
    - root bisection, between the last clear point and the first point found inside.
    """
    d = x1 - x0
    length = d.norm()
    tol = ti.max(TOUCH_REL * r, TOUCH_ABS)
    hit = False
    t = 1.0
    n = vec3(0.0, 1.0, 0.0)
    phase = ADVANCE
    lo = 0.0  # last parameter known to be clear
    hi = 1.0  # advance/bisect: first known inside; search: right end of the bracket
    s = 0.0   # parameter evaluated this iteration
    for it in range(ADVANCE_ITERATIONS + SEARCH_ITERATIONS + BISECT_ITERATIONS):
        gap, n_s = local_sdf(g, ci, kind, x0 + s * d, params)
        gap -= r
        slope = n_s.dot(d)
        if phase == BISECT:
            n = n_s
            if gap < 0.0:
                hi = s
            else:
                lo = s
            if hi - lo <= 1e-12:
                break
            s = 0.5 * (lo + hi)
        elif gap < 0.0:
            if s == 0.0:
                hit, t, n = True, 0.0, n_s  # starts in contact
                break
            phase = BISECT
            hi = s
            s = 0.5 * (lo + hi)
        elif gap <= tol:
            hit, t, n = True, s, n_s
            break
        elif slope >= 0.0 or length == 0.0:
            if phase == ADVANCE:
                break  # clear and moving away from a convex shape: no contact ahead
            hi = s  # search: the minimum lies to the left
            if hi - lo <= 1e-12:
                break
            s = 0.5 * (lo + hi)
        elif phase == ADVANCE:
            lo = s
            s_next = s + gap / length
            if s_next >= 1.0:
                break  # the rest of the segment lies inside a clear ball
            s = s_next
            if it >= ADVANCE_ITERATIONS - 1:
                phase = SEARCH  # grazing: find the minimum of phi on [s, 1]
                hi = 1.0
                lo = s
                s = 0.5 * (lo + hi)
        else:
            lo = s  # search: the minimum lies to the right
            if hi - lo <= 1e-12:
                break
            s = 0.5 * (lo + hi)
    if phase == BISECT:
        hit, t = True, hi
    return hit, t, n


@ti.func
def local_crossing(g: ti.template(), ci, kind: ti.i32, params: vec4, x0: vec3, x1: vec3, r):
    hit = False
    t = 1.0
    n = vec3(0.0, 1.0, 0.0)
    if ti.static(g.groups & kinds.GROUP_ANALYTIC):
        if kind == kinds.PLANE:
            hit, t, n = plane_crossing(x0, x1, r)
        elif kind == kinds.SPHERE:
            hit, t, n = sphere_crossing(x0, x1, params[0], r)
        elif kind == kinds.BOX or kind == kinds.CYLINDER or kind == kinds.CAPSULE:
            hit, t, n = advance_crossing(g, ci, kind, params, x0, x1, r)
    if ti.static(g.groups & kinds.GROUP_TRIANGLES):
        if kind == kinds.TRIANGLE_MESH:
            hit, t, n = triangle_mesh.mesh_crossing(g, ci, x0, x1, r)
    if ti.static(g.groups & kinds.GROUP_HEIGHT):
        if kind == kinds.HEIGHT_FIELD:
            hit, t, n = height_field.field_crossing(g, ci, x0, x1, r)
    if ti.static(g.groups & kinds.GROUP_GRID):
        if kind == kinds.SDF_GRID:
            hit, t, n = grid_crossing(g, ci, x0, x1, r)  # non-convex: no slope early-out
    if ti.static(g.groups & kinds.GROUP_IMPLICIT):
        hit, t, n = implicit_crossing(g, ci, kind, x0, x1, r)
    return hit, t, n


@ti.func
def world_crossing(g: ti.template(), ci, kind: ti.i32, params: vec4, center: vec3, rotation: ti.math.mat3,
                   x0: vec3, x1: vec3, r):
    Rt = rotation.transpose()
    hit, t, n = local_crossing(g, ci, kind, params, Rt @ (x0 - center), Rt @ (x1 - center), r)
    return hit, t, rotation @ n
