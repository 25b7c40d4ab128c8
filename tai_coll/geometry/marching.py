"""Trajectory crossing by root finding for shapes that need not be convex (grids, implicits).

PHYSICS.md 1, "root finding on phi along the segment". The particle center moves on
x0 -> x1 (local frame) and touches where phi(x) = r. Conservative advancement: if phi is
L-Lipschitz, no surface lies within (phi - r) / L of a clear point, so stepping t by
(phi - r) / (L |x1 - x0|) never steps over one, whatever the shape. Unlike the convex
shapes' routine (crossing.advance_crossing) there is no early out on a receding slope: a
non-convex surface can come back. A step that lands inside (a Lipschitz bound that was
too optimistic) is caught by bisection between the last clear and the first inside point.
If advancing runs out of iterations (a path grazing the surface), the end point is tested
and a miss reported when it is clear; interference at the end is caught there too.
"""

import taichi as ti

vec3 = ti.math.vec3

ADVANCE_ITERATIONS = 64
BISECT_ITERATIONS = 48
TOUCH_REL = 1e-4  # touching: within this fraction of the particle radius ...
TOUCH_ABS = 1e-7  # ... or this distance (m) for points

ADVANCE = 0
PROBE_END = 1
BISECT = 2


@ti.func
def march_crossing(evaluate: ti.template(), g: ti.template(), ci, x0: vec3, x1: vec3, r, step_scale):
    """First t in [0, 1] with phi(x0 + t (x1 - x0)) = r, where `evaluate(g, ci, p)` returns
    (phi, n) in the local frame and step_scale = 1 / L. Returns (hit, t, n)."""
    d = x1 - x0
    length = d.norm()
    tol = ti.max(TOUCH_REL * r, TOUCH_ABS)
    hit = False
    t = 1.0
    n = vec3(0.0, 1.0, 0.0)
    phase = ADVANCE
    lo = 0.0  # last parameter known to be clear
    hi = 1.0  # first parameter known to be inside (bisection)
    s = 0.0
    for it in range(ADVANCE_ITERATIONS + BISECT_ITERATIONS + 1):
        gap, n_s = evaluate(g, ci, x0 + s * d)
        gap -= r
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
            n = n_s
            s = 0.5 * (lo + hi)
        elif gap <= tol:
            hit, t, n = True, s, n_s
            break
        elif phase == PROBE_END or length == 0.0:
            break  # clear at the end after a grazing path: a miss
        else:
            lo = s
            s_next = s + gap * step_scale / length
            if s_next >= 1.0:
                break  # the rest of the segment lies in a clear ball
            s = s_next
            if it >= ADVANCE_ITERATIONS - 1:
                phase = PROBE_END
                s = 1.0
    if phase == BISECT:
        hit, t = True, hi
    return hit, t, n
