"""A particle's substep against a lone still plane, the contact of a floor or of a box's wall
(docs/physics.md 3.8): the elastic-then-contact scheme (resolve.resolve_passes) written out
for the one case where a single still plane can be met, without the general sweep over the
collider table.

The impulse kernel (impulse.py) takes this path only in tables without moving colliders, when
it knows from a query that the nearest collider is plane `ci` and that every other collider
is farther from the candidate than the candidate's step (the kept `others`): the general
sweep could then meet no collider but that plane. The path makes the general scheme's
decisions for it, with the same functions (the plane's distance and crossing, the approach
test and the law) on the same values, and commits only where the general scheme ends after
its first sweep: nothing met; an elastic pass that leaves the candidate in front of the
plane; a contact pass. Anything else (an elastic pass that needs a second sweep, a step too
long for the others' clearance) returns `done` False, and the caller runs the general scheme
on the same candidate. What it saves is the general scheme's square roots: a still
collider's surface velocity is zero, a plane's sweep needs no path length (its crossing
alone decides), and the clearances it reports take the other colliders' kept bound less an
upper bound of the step (the sum of the step's components), so they are valid, if shorter.
"""

import taichi as ti

from ..geometry.analytic import plane_heights_crossing
from ..types import vec3
from .detection import APPROACH_EPS, APPROACH_FLOOR, approaching
from .resolve import apply_law

ZERO = (0.0, 0.0, 0.0)


@ti.func
def plane_normal(c: ti.template(), ci, end_pose: bool) -> vec3:
    """The plane's unit normal at its end pose (or start pose): its rotation's second column,
    as geometry.dispatch.world_sdf takes it."""
    rotation = c.rotation0[ci]
    if end_pose:
        rotation = c.rotation1[ci]
    return vec3(rotation[0, 1], rotation[1, 1], rotation[2, 1])


@ti.func
def longest(d: vec3):
    """An upper bound of |d| without a square root: the sum of its components' sizes."""
    return ti.abs(d[0]) + ti.abs(d[1]) + ti.abs(d[2])


@ti.func
def approaches(v: vec3, n: vec3) -> bool:
    """detection.approaching(v, 0, n), the same answer, its square root taken only where the
    bounds |v_N| <= |v| <= longest(v) leave the answer open."""
    vn = v.dot(n)
    out = False
    if vn < -APPROACH_FLOOR:
        out = vn < -APPROACH_EPS * longest(v) - APPROACH_FLOOR
        if not out:
            out = approaching(v, vec3(ZERO), n)
    return out


@ti.func
def lone_plane_substep(c: ti.template(), ci, i, x0: vec3, v0: vec3, x1: vec3, v1: vec3, r, slop, dt, elastic_first,
                       others, wet_law: ti.template()):
    """Resolve particle i's candidate (x1, v1) from (x0, v0) against the still plane ci, the
    only collider within its reach (`others`: a lower bound of the other colliders' distance
    from x1, at least the step |x1 - x0|; x0 known clear of every collider). elastic_first:
    the scheme's elastic pass (restitution, on v0) comes first. Returns (done, x1, v1,
    clearance, apart, level, others) as resolve.resolve_passes returns them; done False: the
    general scheme must resolve this candidate (the other values are then meaningless)."""
    done = False
    clearance = -1.0
    apart = vec3(ZERO)
    level = 0.0
    left = others
    n1 = plane_normal(c, ci, True)
    gap1 = (x1 - c.center1[ci]).dot(n1) - r
    # detection.detect's tests for this plane. A clear end (gap1 >= 0) meets it only by
    # crossing it, which a sphere whose centre ends in front of it cannot: no contact.
    candidate = False
    n = n1
    t = 0.0
    if gap1 < 0.0:
        n = plane_normal(c, ci, False)
        gap0 = (x0 - c.center0[ci]).dot(n) - r
        candidate = gap0 >= -slop and gap1 < ti.min(gap0, 0.0)
        if candidate and gap0 >= 0.0:
            n = n1
            candidate, t = plane_heights_crossing((x0 - c.center1[ci]).dot(n1), (x1 - c.center1[ci]).dot(n1), r)
    found = False
    alt = False
    vs = vec3(ZERO)  # (a still collider's surface)
    if candidate:
        found = approaches(v0 if elastic_first else v1, n)
        alt = approaches(v1, n)
    met = x0 + t * (x1 - x0)
    if found and elastic_first:
        # the elastic pass: the law with restitution on v(t), its change added to the candidate
        v_new, _changed = apply_law(c, False, ci, i, 0.0, x0, r, v0, n, vs, c.material[ci][0], wet_law)
        dv = v_new - v0
        x1_elastic = x1 + dt * dv
        left = others - longest(x1_elastic - x1)
        ahead = n.dot(x1_elastic - met)
        if ahead > 0.0 and left >= longest(x1_elastic - x0):
            done = True
            x1, v1 = x1_elastic, v1 + dv
            clearance, apart, level = ti.min(ahead, left), n, n.dot(met)
    elif found or alt:
        # a contact pass (e = 0): the path to the contact, then the new velocity after it
        v_new, _changed = apply_law(c, False, ci, i, 0.0, x0, r, v1, n, vs, 0.0, wet_law)
        x1_contact = x0 + t * (x1 - x0) + (1.0 - t) * (vec3(ZERO) + dt * (v_new - vs))
        left = others - longest(x1_contact - x1)
        if left >= longest(x1_contact - x0):
            done = True
            x1, v1 = x1_contact, v_new
            apart, level = n, n.dot(met)
            clearance = ti.min(n.dot(x1) - level, left)
    elif gap1 <= others:
        # nothing met, and the plane is the nearest collider
        done = True
        clearance = gap1
        if gap1 >= 0.0:
            apart = n1
        level = apart.dot(x1) - gap1
    return done, x1, v1, clearance, apart, level, left
