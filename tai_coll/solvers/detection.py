"""Contact detection of one particle against the collider table (docs/physics.md 1 and 3).

Given the particle's start x0 (time t) and candidate x1 (time t + dt), report the collider
that matters most: the deepest interference at x1, else the earliest trajectory crossing of
x0 -> x1 (continuous detection, so a fast particle cannot tunnel through a thin shape).
Interference is tested against each collider's pose at t + dt. Colliders the particle was
already inside at time t (beyond the slop) are skipped: the last-resort repulsion owns them.

The collider table `c` is its argument pack (types.ColliderArgs) and `groups` the
compile-time mask of the collider kinds compiled in (geometry/dispatch.py). Each function
evaluates the SDF at one call site inside a loop: Taichi inlines every @ti.func call, and
each call of `world_sdf` carries every compiled shape into the kernel.
"""

import taichi as ti

from ..geometry import kinds
from ..geometry.dispatch import world_crossing, world_sdf
from ..types import vec3

# Relative size of a normal velocity component that counts as round-off, not approach.
APPROACH_EPS = 1e-6
APPROACH_FLOOR = 1e-12  # m/s
INFINITY = 1e30
BOUND_SLOT = 3  # params[3]: bounding-sphere radius (geometry.colliders.Collider.BOUND_SLOT)


@ti.func
def surface_velocity(c: ti.template(), ci, point: vec3) -> vec3:
    """Velocity of the collider's surface at `point`: v + w x (point - center)."""
    return c.velocity[ci] + c.angular_velocity[ci].cross(point - c.center1[ci])


@ti.func
def is_still(c: ti.template(), ci) -> bool:
    """The collider neither moves nor turns during this substep."""
    return c.velocity[ci].norm_sqr() == 0.0 and c.angular_velocity[ci].norm_sqr() == 0.0


@ti.func
def collider_sdf(c: ti.template(), groups: ti.template(), ci, x: vec3, end_pose: bool):
    """phi and normal at x with the collider at the substep's end pose (or start pose)."""
    center = c.center0[ci]
    rotation = c.rotation0[ci]
    if end_pose:
        center = c.center1[ci]
        rotation = c.rotation1[ci]
    return world_sdf(c, groups, ci, c.kind[ci], c.params[ci], center, rotation, x)


@ti.func
def approaching(v: vec3, vs: vec3, n: vec3) -> bool:
    """Relative normal velocity (v - vs) . n below zero, beyond the round-off of the speeds
    involved: a relative velocity that is pure round-off must not count as approach."""
    return (v - vs).dot(n) < -APPROACH_EPS * (v.norm() + vs.norm()) - APPROACH_FLOOR


@ti.func
def keep_two_smallest(first, first_id, second, value, value_id):
    """Running (smallest, its owner, second smallest) over a sequence of values."""
    if value < first:
        second = first
        first = value
        first_id = value_id
    elif value < second:
        second = value
    return first, first_id, second


@ti.func
def carried(c: ti.template(), ci, x: vec3, elapsed) -> vec3:
    """Where the point x, taken at `elapsed` (fraction of the substep), sits relative to the
    collider's end pose once carried along with the collider: sweeping from there to x1
    against the end pose is the particle's path relative to a moving collider. Exact at
    elapsed = 0; later, the translation is interpolated. Static colliders: x itself."""
    start = c.center0[ci] + elapsed * (c.center1[ci] - c.center0[ci])
    return c.center1[ci] + c.rotation1[ci] @ (c.rotation0[ci].transpose() @ (x - start))


@ti.func
def detect(c: ti.template(), groups: ti.template(), x0: vec3, x1: vec3, v: vec3, v_alt: vec3, r, slop):
    """Returns (collider index or -1, outward normal, surface velocity at the contact) for
    velocity v, the same for a second velocity v_alt from the same geometric sweep (the
    elastic pass tests v(t), the contact pass after it the candidate velocity: one sweep
    serves both when the first finds nothing to bounce off), and the clearance of x1.

    A collider is a candidate when
    - x1 interferes (phi(x1) < r) and lies deeper than x0 did: a particle resting or sliding
      within the slop band keeps its depth and is not processed again;
    - or x1 is clear but the segment x0 -> x1 crosses the shape (continuous detection).
    Its contact is where the segment first touches: x0 itself for a particle already in the
    band (normal at x0), else the crossing point (docs/physics.md 1). That normal, not the one at
    the deepest point x1, is what keeps a sliding particle on a curved surface and gives the
    right face at a box edge. Non-convex colliders (meshes, terrain) add one case: when x1
    sinks deeper but the velocity no longer approaches that contact (it slid along one face
    of a concave crease into the next), the normal at x1 is used. Among candidates that `v`
    approaches, the earliest contact wins (ties: the deepest x1). x0 deeper than the slop:
    skipped, the last-resort repulsion owns it.
    """
    length = (x1 - x0).norm()
    clearance = INFINITY  # smallest gap lower bound over colliders, at x1
    nearest = -1          # the collider it belongs to
    second = INFINITY     # the smallest over the other colliders
    best_t = 2.0
    best_gap = 0.0
    found = -1
    found_n = vec3(0.0, 1.0, 0.0)
    found_vs = vec3(0.0, 0.0, 0.0)
    alt_t = 2.0
    alt_gap = 0.0
    alt = -1
    alt_n = vec3(0.0, 1.0, 0.0)
    alt_vs = vec3(0.0, 0.0, 0.0)
    for ci in range(c.count):
        reach = (x1 - c.center1[ci]).norm() - c.params[ci][BOUND_SLOT] - r
        if reach >= length:
            clearance, nearest, second = keep_two_smallest(clearance, nearest, second, reach, ci)
            continue
        # k = 0: x1 against the end pose; k = 1: x0 against the start pose, only if needed.
        gap1 = 0.0
        gap0 = 0.0
        n0 = vec3(0.0, 1.0, 0.0)
        n1 = vec3(0.0, 1.0, 0.0)
        candidate = False
        for k in range(2):
            phi, n = collider_sdf(c, groups, ci, x1 if k == 0 else x0, k == 0)
            if k == 0:
                gap1, n1 = phi - r, n
                clearance, nearest, second = keep_two_smallest(clearance, nearest, second, gap1, ci)
                # Interference, or a clear end that the segment may still reach (phi is
                # 1-Lipschitz, so a gap beyond the segment's length rules a crossing out).
                candidate = gap1 < length
                if not candidate:
                    break
            else:
                gap0, n0 = phi - r, n
                if gap1 < 0.0:
                    candidate = gap0 >= -slop and gap1 < ti.min(gap0, 0.0)
                else:
                    candidate = gap0 >= 0.0
        if candidate:
            t = 0.0
            n = n0
            start = x0
            if gap0 >= 0.0:
                # Sweep the path relative to the collider, against its end pose.
                start = carried(c, ci, x0, 0.0)
                hit, t_hit, n_hit = world_crossing(c, groups, ci, c.kind[ci], c.params[ci], c.center1[ci],
                                                   c.rotation1[ci], start, x1, r)
                candidate = hit
                t, n = t_hit, n_hit
            if candidate:
                vs = surface_velocity(c, ci, start + t * (x1 - start) - r * n)
                n_v = n
                n_alt = n
                if gap1 < ti.min(gap0, 0.0) and not kinds.is_convex(c.kind[ci]):
                    # A concave crease: x1 sinks into another face than the one first met,
                    # which the velocity no longer approaches; respond to x1's face.
                    if not approaching(v, vs, n):
                        n_v = n1
                    if not approaching(v_alt, vs, n):
                        n_alt = n1
                if (t < best_t or (t == best_t and gap1 < best_gap)) and approaching(v, vs, n_v):
                    found, best_t, best_gap, found_n, found_vs = ci, t, gap1, n_v, vs
                if (t < alt_t or (t == alt_t and gap1 < alt_gap)) and approaching(v_alt, vs, n_alt):
                    alt, alt_t, alt_gap, alt_n, alt_vs = ci, t, gap1, n_alt, vs
    return found, found_n, found_vs, alt, alt_n, alt_vs, clearance, nearest, second


@ti.func
def keep_out(c: ti.template(), groups: ti.template(), x0: vec3, x1: vec3, r):
    """Move x1 out along each collider's normal to no deeper than x0 was (or to the surface):
    for positions that another phase moved (particle-particle projection), where no velocity
    approaches the collider and the contact passes would leave the penetration alone."""
    for ci in range(c.count):
        if (x1 - c.center1[ci]).norm() - c.params[ci][BOUND_SLOT] < r:
            gap1 = 0.0
            n1 = vec3(0.0, 1.0, 0.0)
            for k in range(2):
                phi, n = collider_sdf(c, groups, ci, x1 if k == 0 else x0, k == 0)
                if k == 0:
                    gap1, n1 = phi - r, n
                    if gap1 >= 0.0:
                        break
                else:
                    allowed = ti.min(phi - r, 0.0)
                    if gap1 < allowed:
                        x1 += (allowed - gap1) * n1
    return x1


@ti.func
def start_penetration(c: ti.template(), groups: ti.template(), ci, x0: vec3, r, slop):
    """If x0 was inside collider ci at time t (beyond the slop), return (True, depth, normal,
    contact point) measured against the end pose; else (False, ...)."""
    inside = False
    phi = r
    n = vec3(0.0, 1.0, 0.0)
    if (x0 - c.center0[ci]).norm() - c.params[ci][BOUND_SLOT] < r:  # else outside the bounding sphere
        for k in range(2):
            phi, n = collider_sdf(c, groups, ci, x0, k == 1)
            if k == 0:
                inside = phi < r - slop
                if not inside:
                    break
    return inside, r - phi, n, x0 - phi * n


@ti.func
def earliest_approach(c: ti.template(), groups: ti.template(), x0: vec3, x1: vec3, v: vec3, elapsed, r, slop):
    """For the exact-time scheme: the first collider that the path x0 -> x1 (starting at
    `elapsed`, a fraction of the substep) touches while approaching it, swept relative to
    each collider. Returns (collider or -1, fraction t of the path, normal, surface velocity)."""
    found = -1
    first_t = 2.0
    first_n = vec3(0.0, 1.0, 0.0)
    first_vs = vec3(0.0, 0.0, 0.0)
    for ci in range(c.count):
        start = carried(c, ci, x0, elapsed)
        phi, n0 = collider_sdf(c, groups, ci, start, True)
        if phi - r < (x1 - start).norm() + slop and phi >= r - slop:
            hit, t, n = world_crossing(c, groups, ci, c.kind[ci], c.params[ci], c.center1[ci], c.rotation1[ci], start,
                                       x1, r)
            if hit and t < first_t:
                vs = surface_velocity(c, ci, start + t * (x1 - start) - r * n)
                if approaching(v, vs, n):
                    found, first_t, first_n, first_vs = ci, t, n, vs
    return found, first_t, first_n, first_vs
