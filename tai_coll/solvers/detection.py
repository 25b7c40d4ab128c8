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
from ..types import mat3, vec3

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
def collider_sdf(c: ti.template(), groups: ti.template(), ci, x: vec3, end_pose: bool, reach=INFINITY):
    """phi and normal at x with the collider at the substep's end pose (or start pose)."""
    center = c.center0[ci]
    rotation = c.rotation0[ci]
    if end_pose:
        center = c.center1[ci]
        rotation = c.rotation1[ci]
    return world_sdf(c, groups, ci, c.kind[ci], c.params[ci], center, rotation, x, reach)


@ti.func
def approaching(v: vec3, vs: vec3, n: vec3) -> bool:
    """Relative normal velocity (v - vs) . n below zero, beyond the round-off of the speeds
    involved: a relative velocity that is pure round-off must not count as approach."""
    return (v - vs).dot(n) < -APPROACH_EPS * (v.norm() + vs.norm()) - APPROACH_FLOOR


@ti.func
def keep_two_smallest(first, first_id, first_n: vec3, second, value, value_id, value_n: vec3):
    """Running (smallest, its owner, its direction, second smallest) over a sequence of values."""
    if value < first:
        second = first
        first = value
        first_id = value_id
        first_n = value_n
    elif value < second:
        second = value
    return first, first_id, first_n, second


@ti.func
def carried(c: ti.template(), ci, x: vec3) -> vec3:
    """Where the point x, taken at time t, sits relative to the collider's end pose once
    carried along with the collider, c1 + R1 R0^T (x - c0): sweeping from there to x1 against
    the end pose is the particle's path relative to a moving collider. Exact for any rigid
    motion. Still colliders: x itself, without the transform (whose round-off would move a
    particle at rest)."""
    out = x
    if not is_still(c, ci):
        out = c.center1[ci] + c.rotation1[ci] @ (c.rotation0[ci].transpose() @ (x - c.center0[ci]))
    return out


@ti.func
def turned_by(w: vec3) -> mat3:
    """The rotation by |w| radians about w (Rodrigues: I + sin a K + (1 - cos a) K^2)."""
    angle = w.norm()
    rotation = ti.Matrix.identity(float, 3)
    if angle > 0.0:
        k = w / angle
        cross = ti.Matrix([[0.0, -k.z, k.y], [k.z, 0.0, -k.x], [-k.y, k.x, 0.0]])
        rotation += ti.sin(angle) * cross + (1.0 - ti.cos(angle)) * (cross @ cross)
    return rotation


@ti.func
def carried_from(c: ti.template(), ci, x: vec3, elapsed, dt) -> vec3:
    """`carried` for a point taken `elapsed` (a fraction of the substep dt) into the substep:
    the pose then is the start pose turned by w elapsed dt (w: the substep's angular
    velocity, R1 = exp(w dt) R0), its centre interpolated between c0 and c1."""
    out = x
    if not is_still(c, ci):
        center = c.center0[ci] + elapsed * (c.center1[ci] - c.center0[ci])
        back = turned_by(-elapsed * dt * c.angular_velocity[ci])  # R(elapsed)^T = R0^T exp(-w elapsed dt)
        out = c.center1[ci] + c.rotation1[ci] @ (c.rotation0[ci].transpose() @ (back @ (x - center)))
    return out


@ti.func
def carried_normal(c: ti.template(), ci, n: vec3) -> vec3:
    """A direction taken against the start pose, carried to the end pose (R1 R0^T n)."""
    out = n
    if not is_still(c, ci):
        out = c.rotation1[ci] @ (c.rotation0[ci].transpose() @ n)
    return out


@ti.func
def detect(c: ti.template(), groups: ti.template(), kinematic: ti.template(), x0: vec3, x1: vec3, v: vec3,
           v_alt: vec3, r, slop):
    """Returns the contact for velocity v: (collider or -1, outward normal, the surface's
    velocity there, when it is met: a fraction of the substep and of the path); the same for a
    second velocity v_alt from the same geometric sweep (the elastic pass tests v(t), the
    contact pass after it the candidate velocity: one sweep serves both when the first finds
    nothing to bounce off); and the clearance of x1 (a lower bound of the gap over the
    colliders, a moving collider's less the distance it carried x0), the collider it belongs
    to, its separating direction and the smallest over the others. kinematic: whether the
    table holds moving colliders (compile time: without, none of the relative-motion code is
    compiled in).

    The separating direction u (a unit vector, or zero for none) says more than the clearance
    g: the nearest collider lies wholly behind the plane u . y = u . x1 - g, offset by the
    radius, so a particle whose centre stays in front of it cannot touch that collider, however
    far it goes (docs/physics.md 3.7). It is the normal at x1 of a convex collider that x1 is
    clear of (phi is the exact distance outside the analytic shapes, and a convex set lies
    behind its tangent plane at the point nearest x1), or the direction from the bounding
    sphere's centre when that sphere decided the clearance; zero for other shapes.

    A collider is a candidate when
    - x1 interferes (phi(x1) < r) and lies deeper than x0 did: a particle resting or sliding
      within the slop band keeps its depth and is not processed again;
    - or x1 is clear but the path crosses the shape (continuous detection).
    The path is the particle's relative to the collider (docs/physics.md 3.6): from x0 carried
    with the collider to its end pose, to x1, against the end pose, so a collider that moves
    across a particle within the substep is met as a particle crossing it would be. A still
    collider's relative path is x0 -> x1 itself (no transform).
    Its contact is where the path first touches: x0 (carried) for a particle already in the
    band (normal at x0, fraction 0), else the crossing point (docs/physics.md 1). That normal,
    not the one at the deepest point x1, is what keeps a sliding particle on a curved surface
    and gives the right face at a box edge. Non-convex colliders (meshes, terrain) add one
    case: when x1 sinks deeper but the velocity no longer approaches that contact (it slid
    along one face of a concave crease into the next), the normal at x1 is used (fraction 0:
    nothing is known of where that face was met). Among candidates that `v` approaches, the
    earliest contact wins (ties: the deepest x1). x0 deeper than the slop: skipped, the
    last-resort repulsion owns it.
    """
    length = (x1 - x0).norm()
    clearance = INFINITY  # smallest gap lower bound over colliders, at x1
    nearest = -1          # the collider it belongs to
    apart = vec3(0.0, 0.0, 0.0)  # its separating direction (zero: none)
    second = INFINITY     # the smallest over the other colliders
    best_t = 2.0
    best_gap = 0.0
    found = -1
    found_n = vec3(0.0, 1.0, 0.0)
    found_vs = vec3(0.0, 0.0, 0.0)
    found_when = 0.0
    alt_t = 2.0
    alt_gap = 0.0
    alt = -1
    alt_n = vec3(0.0, 1.0, 0.0)
    alt_vs = vec3(0.0, 0.0, 0.0)
    alt_when = 0.0
    for ci in range(c.count):
        # The relative path: x0 carried with a moving collider to its end pose, then to x1.
        start = x0
        path = length
        carry = 0.0  # how far the collider carried x0: its clearance counts for a path that long less
        moving = False
        if ti.static(kinematic):
            moving = not is_still(c, ci)
            if moving:
                start = carried(c, ci, x0)
                path = (x1 - start).norm()
                carry = (start - x0).norm()
        off_center = x1 - c.center1[ci]
        distance = off_center.norm()
        reach = distance - c.params[ci][BOUND_SLOT] - r
        if reach >= path:
            clearance, nearest, apart, second = keep_two_smallest(clearance, nearest, apart, second, reach - carry,
                                                                  ci, off_center / distance)
            continue
        # k = 0: x1 against the end pose; k = 1: x0 against the start pose, only if needed.
        gap1 = 0.0
        gap0 = 0.0
        n0 = vec3(0.0, 1.0, 0.0)
        n1 = vec3(0.0, 1.0, 0.0)
        candidate = False
        for k in range(2):
            phi, n = collider_sdf(c, groups, ci, x1 if k == 0 else x0, k == 0, r + path)
            if k == 0:
                gap1, n1 = phi - r, n
                u = vec3(0.0, 0.0, 0.0)
                if kinds.is_convex(c.kind[ci]) and gap1 >= 0.0:
                    u = n
                clearance, nearest, apart, second = keep_two_smallest(clearance, nearest, apart, second, gap1 - carry,
                                                                      ci, u)
                # Interference, or a clear end that the path may still reach (phi is
                # 1-Lipschitz, so a gap beyond the path's length rules a crossing out).
                candidate = gap1 < path
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
            if ti.static(kinematic):
                if moving:
                    n = carried_normal(c, ci, n0)  # x0's normal, carried to the end pose with x0
            if gap0 >= 0.0:
                # Sweep the relative path against the end pose.
                hit, t_hit, n_hit = world_crossing(c, groups, ci, c.kind[ci], c.params[ci], c.center1[ci],
                                                   c.rotation1[ci], start, x1, r)
                candidate = hit
                t, n = t_hit, n_hit
            if candidate:
                vs = surface_velocity(c, ci, start + t * (x1 - start) - r * n)
                n_v = n
                n_alt = n
                when_v = t
                when_alt = t
                if gap1 < ti.min(gap0, 0.0) and not kinds.is_convex(c.kind[ci]):
                    # A concave crease: x1 sinks into another face than the one first met,
                    # which the velocity no longer approaches; respond to x1's face.
                    if not approaching(v, vs, n):
                        n_v = n1
                        when_v = 0.0
                    if not approaching(v_alt, vs, n):
                        n_alt = n1
                        when_alt = 0.0
                if (t < best_t or (t == best_t and gap1 < best_gap)) and approaching(v, vs, n_v):
                    found, best_t, best_gap, found_n, found_vs, found_when = ci, t, gap1, n_v, vs, when_v
                if (t < alt_t or (t == alt_t and gap1 < alt_gap)) and approaching(v_alt, vs, n_alt):
                    alt, alt_t, alt_gap, alt_n, alt_vs, alt_when = ci, t, gap1, n_alt, vs, when_alt
    return found, found_n, found_vs, found_when, alt, alt_n, alt_vs, alt_when, clearance, nearest, apart, second


@ti.func
def keep_out(c: ti.template(), groups: ti.template(), kinematic: ti.template(), x0: vec3, x1: vec3, r):
    """Move x1 out of each collider that is not a rigid body to no deeper than x0 was (or to
    the surface): for positions that another phase moved (particle-particle projection),
    where no velocity approaches the collider and the contact passes would leave the
    penetration alone. (Bodies: keep_out_of at the end of the substep, once they are
    committed to their poses: a body's predicted pose, where the particles' passes meet it,
    runs ahead of a body that they slow, and out of that pose a particle is pushed into its
    neighbours; docs/physics.md 7.2.)"""
    for ci in range(c.count):
        if c.body[ci] < 0:
            x1 = keep_out_of(c, groups, kinematic, ci, x0, x1, r)
    return x1


@ti.func
def keep_out_of(c: ti.template(), groups: ti.template(), kinematic: ti.template(), ci, x0: vec3, x1: vec3, r):
    """keep_out for collider ci: x1 moved out of its end pose to no deeper than x0 was in
    its start pose.

    Out along the normal at x1, unless that normal points along the particle's path relative
    to the collider while x0 was outside: then x1 lies past the middle of a thin or fast
    collider, whose nearest face is the far one, and it goes back out by the side it came
    from, onto the plane through x0's contact point with x0's normal (which, for a convex
    collider, clears it)."""
    if (x1 - c.center1[ci]).norm() - c.params[ci][BOUND_SLOT] < r:
        gap1 = 0.0
        n1 = vec3(0.0, 1.0, 0.0)
        for k in range(2):
            phi, n = collider_sdf(c, groups, ci, x1 if k == 0 else x0, k == 0, r)
            if k == 0:
                gap1, n1 = phi - r, n
                if gap1 >= 0.0:
                    break
            else:
                allowed = ti.min(phi - r, 0.0)
                if gap1 < allowed:
                    start = x0
                    n0 = n
                    if ti.static(kinematic):
                        start = carried(c, ci, x0)
                        n0 = carried_normal(c, ci, n)
                    if phi >= 0.0 and n1.dot(x1 - start) > 0.0 and n0.dot(n1) < 0.0:
                        # through to the far side: back to the plane of x0's contact
                        x1 += ti.max((start - x1).dot(n0) - (phi - r) + allowed, 0.0) * n0
                    else:
                        x1 += (allowed - gap1) * n1
    return x1


@ti.func
def start_penetration(c: ti.template(), groups: ti.template(), kinematic: ti.template(), ci, x0: vec3, v0: vec3,
                      r, slop, dt):
    """If x0 was inside collider ci at time t (beyond the slop), return (True, depth, normal,
    contact point, entered), relative to the end pose (x0 carried with the collider); else
    (False, ...).

    The normal is the nearest face's, and depth the distance to it. For a moving collider
    that the particle entered within the last substep (a substep back along its relative
    velocity, x0 - dt (v0 - v_s), it was clear), the face it came in by is taken instead:
    the normal at that earlier point, and depth the distance back out to the plane through
    its contact point (for a convex collider, clear of it); entered is True. A collider that
    overran the particle (a turn too fast for its straight relative path, a particle pushed
    into a plate) thus pushes it out in front, not through its far side."""
    inside = False
    entered = False
    phi = r
    n = vec3(0.0, 1.0, 0.0)
    point = x0
    depth = 0.0
    if (x0 - c.center0[ci]).norm() - c.params[ci][BOUND_SLOT] < r:  # else outside the bounding sphere
        if ti.static(not kinematic):
            phi, n = collider_sdf(c, groups, ci, x0, False, r)
            inside = phi < r - slop
            point = x0 - phi * n
        else:
            here = x0
            back = x0
            # k = 0: x0 against the start pose; k = 1: a substep back, against the end pose
            for k in range(2):
                phi_k, n_k = collider_sdf(c, groups, ci, x0 if k == 0 else back, k == 1, r)
                if k == 0:
                    phi, n = phi_k, n_k
                    inside = phi < r - slop
                    point = x0 - phi * n
                    if not inside or is_still(c, ci):
                        break
                    here = carried(c, ci, x0)
                    n = carried_normal(c, ci, n)
                    point = here - phi * n
                    back = here - dt * (v0 - surface_velocity(c, ci, here))
                elif phi_k >= r and n_k.dot(n) < 0.0:
                    # it came in by another face than the nearest: out by that one
                    entered = True
                    n = n_k
                    depth = ti.max((back - here).dot(n_k) - (phi_k - r), 0.0)
                    point = back - phi_k * n_k
    if not entered:
        depth = r - phi
    return inside, depth, n, point, entered


@ti.func
def earliest_approach(c: ti.template(), groups: ti.template(), kinematic: ti.template(), x0: vec3, x1: vec3,
                      v: vec3, elapsed, dt, r, slop):
    """For the exact-time scheme: the first collider that the path x0 -> x1 (starting at
    `elapsed`, a fraction of the substep dt) touches while approaching it, swept relative to
    each collider. Returns (collider or -1, fraction t of the path, normal, surface velocity)."""
    found = -1
    first_t = 2.0
    first_n = vec3(0.0, 1.0, 0.0)
    first_vs = vec3(0.0, 0.0, 0.0)
    for ci in range(c.count):
        start = x0
        if ti.static(kinematic):
            start = carried_from(c, ci, x0, elapsed, dt)
        phi, n0 = collider_sdf(c, groups, ci, start, True, r + (x1 - start).norm() + slop)
        if phi - r < (x1 - start).norm() + slop and phi >= r - slop:
            hit, t, n = world_crossing(c, groups, ci, c.kind[ci], c.params[ci], c.center1[ci], c.rotation1[ci], start,
                                       x1, r)
            if hit and t < first_t:
                vs = surface_velocity(c, ci, start + t * (x1 - start) - r * n)
                if approaching(v, vs, n):
                    found, first_t, first_n, first_vs = ci, t, n, vs
    return found, first_t, first_n, first_vs
