"""Trajectory crossing by root finding on phi along the segment: one loop for every shape
without a closed form (docs/physics.md 1, "root finding on phi along the segment").

The particle centre moves on x0 -> x1 (local frame) and touches where phi(x) = r. If phi is
L-Lipschitz, no surface lies within (phi - r) / L of a clear point, so stepping t by
(phi - r) / (L |x1 - x0|) never steps over one (conservative advancement). A step that lands
inside (a Lipschitz bound that was too optimistic) is caught by bisection between the last
clear and the first inside point. One SDF evaluation per iteration: each call site inlines
every shape it can evaluate, and kernel compile time grows with their number.

Two variants, chosen at compile time:
- convex shapes (box, cylinder, capsule; L = 1): along a line phi is convex, so once its slope
  n . d turns non-negative while still clear, the segment can never touch: stop early. When
  advancing runs out of patience on a grazing path, bisect on the sign of the slope toward
  the minimum of phi (clear at the minimum: a miss), then bisect the root.
- any shape (signed-distance grids, implicit functions): no early out on a receding slope,
  since a non-convex surface can come back. When advancing runs out of iterations (a path
  grazing the surface), the end point is tested and a miss reported when it is clear;
  interference at the end is caught there too.
"""

import taichi as ti

vec3 = ti.math.vec3

TOUCH_REL = 1e-4  # touching: within this fraction of the particle radius ...
TOUCH_ABS = 1e-7  # ... or this distance (m) for points

# Iteration caps of the phases, per variant.
CONVEX_ADVANCE_ITERATIONS = 48
CONVEX_SEARCH_ITERATIONS = 48
CONVEX_BISECT_ITERATIONS = 40
ADVANCE_ITERATIONS = 64
BISECT_ITERATIONS = 48

ADVANCE = 0
SEARCH = 1     # convex: bisection toward the minimum of phi on a grazing path
BISECT = 2
PROBE_END = 3  # any shape: the end point tested after a grazing path


@ti.func
def march_crossing(evaluate: ti.template(), g: ti.template(), ci, kind, params, x0: vec3, x1: vec3, r, step_scale,
                   convex: ti.template()):
    """First t in [0, 1] with phi(x0 + t (x1 - x0)) = r. `evaluate(g, ci, kind, params, p)`
    returns (phi, n) in the local frame; step_scale = 1 / L (1 for convex shapes); convex:
    the variant (see the module's notes). Returns (hit, t, n)."""
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
    advance_cap = ti.static(CONVEX_ADVANCE_ITERATIONS if convex else ADVANCE_ITERATIONS)
    iterations = ti.static(CONVEX_ADVANCE_ITERATIONS + CONVEX_SEARCH_ITERATIONS + CONVEX_BISECT_ITERATIONS
                           if convex else ADVANCE_ITERATIONS + BISECT_ITERATIONS + 1)
    for it in range(iterations):
        gap, n_s = evaluate(g, ci, kind, params, x0 + s * d)
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
            if ti.static(not convex):
                n = n_s
            s = 0.5 * (lo + hi)
        elif gap <= tol:
            hit, t, n = True, s, n_s
            break
        else:
            searching = False  # convex: bisecting toward the minimum of phi
            if ti.static(convex):
                receding = n_s.dot(d) >= 0.0 or length == 0.0  # moving away from the shape, or not at all
                if receding and phase == ADVANCE:
                    break  # clear and moving away from a convex shape: no contact ahead
                searching = receding or phase == SEARCH
                if searching:
                    if receding:
                        hi = s  # the minimum lies to the left
                    else:
                        lo = s  # ... or to the right
                    if hi - lo <= 1e-12:
                        break
                    s = 0.5 * (lo + hi)
            else:
                if phase == PROBE_END or length == 0.0:
                    break  # clear at the end after a grazing path: a miss
            if not searching:
                lo = s
                s_next = s + gap * step_scale / length
                if s_next >= 1.0:
                    break  # the rest of the segment lies in a clear ball
                s = s_next
                if it >= advance_cap - 1:
                    if ti.static(convex):
                        phase = SEARCH  # grazing: find the minimum of phi on [s, 1]
                        hi = 1.0
                        lo = s
                        s = 0.5 * (lo + hi)
                    else:
                        phase = PROBE_END
                        s = 1.0
    if phase == BISECT:
        hit, t = True, hi
    return hit, t, n
