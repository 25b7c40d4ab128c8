"""A particle's substep against a lone still plane, the contact of a floor or of a box's wall
(docs/physics.md 3.8): the elastic-then-contact scheme (resolve.resolve_passes) written out
for the one case where a single still plane can be met, without the general sweep over the
collider table.

The impulse kernel (impulse.py) takes this path only in tables without moving colliders, when
it knows from a query that the nearest collider is plane `ci` and that every other collider
is farther from the candidate than the candidate's step (the kept `others`): the general
sweep could then meet no collider but that plane. The path makes the general scheme's
decisions for it, with the same formulas (the plane's distance and crossing as
geometry.dispatch gives them, detection.approaching's test, resolve.apply_law) on the
same values, and commits only where the general scheme ends within two sweeps: nothing met; an
elastic pass that leaves the candidate in front of the plane; an elastic pass, then a second
sweep that meets nothing or one contact pass; a contact pass. Anything else (more elastic
passes, a contact whose result the others' bound does not clear) returns `done` False, and the
caller runs the general scheme on the same candidate. What it leaves out is the general
scheme's generality: a still collider's surface velocity is zero, a plane's sweep needs no
path length (its crossing alone decides), square roots are taken only where a bound leaves an
answer open, and the clearances it reports take the other colliders' kept bound less an upper
bound of the step (the sum of the step's components), so they are valid, if shorter. Its
results agree with the general scheme's to round-off (tests/test_physics.py).
"""

import taichi as ti

from ..geometry.analytic import plane_heights_crossing
from ..geometry.dispatch import world_plane
from ..types import vec3
from .detection import APPROACH_EPS, APPROACH_FLOOR, approaching
from .resolve import apply_law

ZERO = (0.0, 0.0, 0.0)


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
def sweep(c: ti.template(), ci, x0: vec3, x1: vec3, r, slop):
    """detection.detect's tests for plane ci alone, path x0 -> x1: (gap of x1, whether the path
    meets the plane, the normal there, when: a fraction of the substep). A clear end (gap >= 0)
    meets it only by crossing it, which a sphere whose centre ends in front of it cannot."""
    # (detection.detect's collider_sdf and world_crossing, for a plane: x1 against the end
    # pose, x0 against the start pose, the crossing against the end pose)
    phi1, n1 = world_plane(c.center1[ci], c.rotation1[ci], x1)
    gap1 = phi1 - r
    candidate = False
    n = n1
    t = 0.0
    if gap1 < 0.0:
        phi0, n0 = world_plane(c.center0[ci], c.rotation0[ci], x0)
        gap0 = phi0 - r
        n = n0
        candidate = gap0 >= -slop and gap1 < ti.min(gap0, 0.0)
        if candidate and gap0 >= 0.0:
            n = n1
            h0, _n = world_plane(c.center1[ci], c.rotation1[ci], x0)
            candidate, t = plane_heights_crossing(h0, phi1, r)
    return gap1, candidate, n, t


@ti.func
def lone_plane_substep(c: ti.template(), ci, i, x0: vec3, v0: vec3, x1: vec3, v1: vec3, r, slop, dt, elastic_passes,
                       others, wet_law: ti.template()):
    """Resolve particle i's candidate (x1, v1) from (x0, v0) against the still plane ci, the
    only collider within its reach (`others`: a lower bound of the other colliders' distance
    from x1, at least the step |x1 - x0|; x0 known clear of every collider). elastic_passes:
    the scheme's elastic passes (restitution, on v0), which come first (this path does one).
    Returns (done, x1, v1, clearance, apart, level, others) as resolve.resolve_passes returns
    them; done False: the general scheme must resolve this candidate (the other values are
    then meaningless).

    As resolve_passes: a sweep; the elastic pass where v(t) approaches (then, unless it leaves
    the candidate in front of the plane, a second sweep with the candidate's velocity); a
    contact pass where the candidate's velocity approaches. A contact pass whose result the
    bound on the others does not clear is left to the general scheme."""
    done = False
    clearance = -1.0
    apart = vec3(ZERO)
    level = 0.0
    left = others
    xc, vc = x1, v1  # the candidate as the passes leave it
    elastic = elastic_passes > 0
    vs = vec3(ZERO)  # (a still collider's surface)
    for _ in range(1 + ti.min(elastic_passes, 1)):  # (a sweep after an elastic pass; the count is
        gap1, candidate, n, t = sweep(c, ci, x0, xc, r, slop)  # not a constant, so the loop stays a loop)
        found = False
        alt = False
        if candidate:
            found = approaches(v0 if elastic else vc, n)
            alt = approaches(vc, n)
        met = x0 + t * (xc - x0)
        if not (found or alt):
            if gap1 <= left:
                # nothing met, and the plane is the nearest collider
                done = True
                clearance = gap1
                if gap1 >= 0.0:
                    apart = n
                level = apart.dot(xc) - gap1
            break
        # the elastic pass (the law with restitution on v(t), its change added to the
        # candidate) or a contact pass (e = 0 on the candidate's velocity: the path to the
        # contact, then the new velocity after it); one call of the law serves both
        bounce = found and elastic
        restitution = 0.0
        if bounce:
            restitution = c.material[ci][0]
        v_in = v0 if bounce else vc
        v_new, _changed = apply_law(c, False, ci, i, 0.0, x0, r, v_in, n, vs, restitution, wet_law)
        if bounce:
            dv = v_new - v0
            x1_elastic = xc + dt * dv
            left -= longest(x1_elastic - xc)
            ahead = n.dot(x1_elastic - met)
            xc, vc = x1_elastic, vc + dv
            elastic = False
            if ahead > 0.0 and left >= longest(xc - x0):
                done = True
                clearance, apart, level = ti.min(ahead, left), n, n.dot(met)
                break
            if elastic_passes > 1:
                break  # (another elastic pass follows: the general scheme's)
        else:
            x1_contact = x0 + t * (xc - x0) + (1.0 - t) * (vec3(ZERO) + dt * (v_new - vs))
            left -= longest(x1_contact - xc)
            xc, vc = x1_contact, v_new
            if left >= longest(xc - x0):
                done = True
                apart, level = n, n.dot(met)
                clearance = ti.min(n.dot(xc) - level, left)
            break
    if done:
        x1, v1 = xc, vc
    return done, x1, v1, clearance, apart, level, left
