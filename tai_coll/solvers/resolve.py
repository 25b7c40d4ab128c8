"""One particle's query and response against the collider table (docs/physics.md 2 and 3): the
collision law relative to a collider, the last resort for a particle found inside at the start
of a substep, and the schemes that resolve a candidate state, Implementations 1 to 3 as one
loop of passes (`resolve_passes`) and backing up time (`resolve_exact_time`). The impulse
solver's kernels (impulse.py) run them per particle.

Functions take the particle store and the collider table as argument packs (`p`, `c`:
types.ParticleArgs, types.ColliderArgs), `groups`, the compile-time mask of the collider kinds
compiled in, and `kinematic`, whether the table holds moving colliders (compile time: tables
without compile none of the relative-motion code in, docs/physics.md 3.6).
"""

import taichi as ti

from ..geometry import kinds
from ..response.exchange import body_law, body_stop, held
from ..response.laws import respond
from ..response.penalty import FIELD_NONE, apply_repulsion
from ..types import STAT_FAILSAFE, STAT_REPULSION, vec3
from .detection import carried, detect, earliest_approach, is_still, start_penetration, surface_velocity

# The last resort's settings as one kernel argument: the push fraction, then a repulsion
# field's kind (0: none, push instead), profile, strength, decay and range.
last_resort6 = ti.types.vector(6, float)

SIMPLE = 0
MICRO = 1
ELASTIC_CONTACT = 2
EXACT_TIME = 3
SCHEMES = {"simple": SIMPLE, "micro": MICRO, "elastic_contact": ELASTIC_CONTACT, "exact_time": EXACT_TIME}


@ti.func
def apply_law(c: ti.template(), kinematic: ti.template(), ci, i, inv_mass, x_ref: vec3, r, v: vec3, n: vec3,
              vs: vec3, restitution, wet_law: ti.template(), depth=0.0):
    """docs/physics.md 2 on the velocity relative to the collider's surface, with its material;
    against a rigid body, the two-body law (docs/physics.md 7.2) for particle i of inverse
    mass inv_mass centred at x_ref (radius r), which books the body's share in the ledger.
    Returns (the new velocity, whether the law changed it: a body this particle has already
    pushed away, as it sees the body, needs nothing more). depth: exchange.body_law's.
    Bodies move (`kinematic`): tables without moving colliders compile none of this in."""
    v_new = v
    changed = True
    body = False
    if ti.static(kinematic):
        body = c.body[ci] >= 0
    if body:
        v_new, changed = body_law(c, ci, i, inv_mass, x_ref, v, n, vs, x_ref - r * n, restitution, depth, wet_law)
    else:
        m = c.material[ci]
        v_rel, dvn = respond(v - vs, n, restitution, m[1], m[2], wet_law)
        v_new = vs + v_rel
    return v_new, changed


@ti.func
def repel_start_penetrations(p: ti.template(), c: ti.template(), groups: ti.template(), kinematic: ti.template(),
                             i, x0: vec3, v0: vec3, x1: vec3, v1: vec3, r, m, slop, dt, last_resort: last_resort6,
                             max_push_speed, wet_law: ti.template()):
    """Last resort (docs/physics.md 3.4, seed 001): a particle already inside a collider at
    time t keeps its penetration for this substep and is pushed out along the normal by
    last_resort[0] (the push fraction) x depth, at most max_push_speed x dt. The push moves
    the position only; the velocity gets the inelastic law (e = 0, friction as usual), so a
    particle freed from a collider does not fly off with the push as velocity. With a
    repulsion field in last_resort[1:] (seed 002), the field acts on the velocity, at gap
    -depth, instead. A moving collider that the particle entered within the last substep
    (start_penetration's `entered`) is a contact missed, not a penetration: the particle
    goes out through the face it came in by, the whole way at once, and moves on with the
    collider (e = 0), so a paddle's far face never pushes it out behind."""
    push = vec3(0.0, 0.0, 0.0)
    for ci in range(c.count):
        inside, depth, n, point, entered = start_penetration(c, groups, kinematic, ci, x0, v0, r, slop, dt)
        if inside and depth > 0.0:
            vs = surface_velocity(c, ci, point)
            held_here = False  # (held by its supports: the body is pushed out instead, exchange.body_law)
            if ti.static(kinematic):
                if c.body[ci] >= 0:
                    held_here = held(c, i, n, v1, vs)
            v1, changed = apply_law(c, kinematic, ci, i, 1.0 / m, x0, r, v1, n, vs, 0.0, wet_law, depth)
            field_kind = ti.cast(last_resort[1], ti.i32)
            if held_here:
                pass
            elif entered:
                push += depth * n
            elif field_kind == FIELD_NONE:
                push += ti.min(last_resort[0] * depth, max_push_speed * dt) * n
            else:
                v1 = vs + apply_repulsion(v1 - vs, n, -depth, m, dt, field_kind, ti.cast(last_resort[2], ti.i32),
                                          last_resort[3], last_resort[4], last_resort[5])
            x1 = x0 + dt * v1 + push
            ti.atomic_add(p.stats[STAT_REPULSION], 1)
    return x1, v1, push


@ti.func
def resolve_passes(p: ti.template(), c: ti.template(), groups: ti.template(), kinematic: ti.template(), i, inv_mass,
                   x0: vec3, push: vec3, v0: vec3, x1: vec3, v1: vec3, r, slop, dt, elastic_passes, contact_passes,
                   first_contact_elastic: ti.template(), failsafe: ti.template(), wet_law: ti.template()):
    """The simple, micro-collision and elastic-then-contact schemes as one loop.

    Elastic passes (Implementation 3): the law with restitution on the start velocity v(t);
    its change is added to the candidate (x1 += dt dv, v1 += dv).
    Contact passes: the law on the average velocity, then re-integration. The average
    velocity is v1 itself (recomputing it as (x1 - x0)/dt would add position round-off / dt,
    which in f32 is enough to fake an approach). A pass with restitution (the first of
    Implementations 1 and 2, when first_contact_elastic) re-integrates from the start,
    x1 = x0 + push + dt v_new; an inelastic one (e = 0: every other pass, so the loop ends)
    follows the path to the contact, at fraction `when` of the substep, and the new velocity
    after it, x1 = x0 + when (x1 - x0) + (1 - when) (push + dt v_new), so a particle stops on
    the surface it meets, at any dt (docs/physics.md 3.2). Against a moving collider all of
    this is done relative to it: x0 carried with the collider to its end pose, v - v_s
    (docs/physics.md 3.6); for still colliders the formulas above, without transforms.
    If contacts remain after the cap: the failsafe stops the particle relative to the collider.
    One call of `detect` serves every pass, which keeps the kernel small.
    A still, convex collider cannot be met again after its own pass once x1 lies in front of
    the plane tangent to it at the contact, which the pass's new velocity ensures for a contact
    pass and usually does for an elastic one; when no other collider is within reach either,
    the confirming sweep is skipped (it would find nothing).
    Returns (x1, v1, clearance of x1, or -1 when unknown, and with it a separating direction
    `apart` and level: the collider nearest x1 lies behind the plane apart . y = level, offset
    by the radius (detect's `apart`; after a skipped sweep the contact's tangent plane); the
    clearance from the other colliders; and the collider that direction belongs to, or -1).
    """
    v_start = v0
    elastic_left = elastic_passes
    contact_done = 0
    resolved = False
    clearance = -1.0
    apart = vec3(0.0, 0.0, 0.0)
    level = 0.0
    others = -1.0
    near_ci = -1
    last_vs = vec3(0.0, 0.0, 0.0)
    last_start = x0
    ci = -1
    n = vec3(0.0, 1.0, 0.0)
    vs = vec3(0.0, 0.0, 0.0)
    for _ in range(elastic_passes + contact_passes + 1):
        v_test = v_start
        if elastic_left == 0:
            v_test = v1
        ci, n, vs, when, ci_alt, n_alt, vs_alt, when_alt, near, nearest, nearest_apart, second = detect(
            c, groups, kinematic, x0, x1, v_test, v1, r, slop)
        if ci < 0 and elastic_left > 0 and ci_alt >= 0:
            # Nothing to bounce off, but the candidate velocity meets a contact: go straight to
            # the contact passes with what this sweep found.
            elastic_left = 0
            ci, n, vs, when = ci_alt, n_alt, vs_alt, when_alt
        if ci < 0:
            resolved = True
            clearance = near
            apart = nearest_apart
            level = apart.dot(x1) - near
            others = second
            near_ci = nearest
            break
        last_vs = vs
        start = x0  # where the path relative to the collider starts: x0, carried if it moves
        if ti.static(kinematic):
            start = carried(c, ci, x0)
        last_start = start
        restitution = c.material[ci][0]
        met = start + when * (x1 - start)  # the centre where the path meets the collider
        beyond = near if nearest != ci else second  # clearance from the other colliders at x1
        x1_before = x1
        if elastic_left > 0:
            elastic_left -= 1
            v_new, changed = apply_law(c, kinematic, ci, i, inv_mass, x0, r, v_start, n, vs, restitution, wet_law)
            dv = v_new - v_start
            v_start = v_new
            v1 += dv
            x1 += dt * dv
            # (a body's pose for the substep is a prediction, redone with the velocity its
            # particles leave it, docs/physics.md 7.1: the particle keeps x1 = x0 + dt v1)
            if ti.static(kinematic) and c.body[ci] < 0:
                # relative to the collider: the start carried with it rigidly (docs/physics.md
                # 3.6), not along its surface velocity at the contact, which a turning
                # collider's surface leaves behind (nothing changes for a still one)
                x1 += (start - x0) - dt * vs
            if ti.static(not kinematic):
                left = beyond - (x1 - x1_before).norm()
                ahead = n.dot(x1 - met)
                if (ahead > 0.0 and kinds.is_convex(c.kind[ci]) and push.norm_sqr() == 0.0
                        and left >= (x1 - x0).norm()):
                    resolved = True
                    clearance, apart, level, others, near_ci = ti.min(ahead, left), n, n.dot(met), left, ci
                    break
        else:
            if contact_done == contact_passes:
                break
            if ti.static(not first_contact_elastic):
                restitution = 0.0
            elif contact_done > 0:
                restitution = 0.0
            v1, changed = apply_law(c, kinematic, ci, i, inv_mass, x0, r, v1, n, vs, restitution, wet_law)
            if not changed:
                # a body this particle has pushed away, as it sees the body (docs/physics.md
                # 6.2); the table's pose for it is the prediction the body's new velocity redoes
                resolved = True
                break
            # Re-integrate relative to the collider (docs/physics.md 3.2 and 3.6). An inelastic
            # pass follows the relative path up to the contact, at fraction `when` of the
            # substep, and the new relative velocity after it: the particle ends on the surface
            # it met instead of where it stood at time t, which would leave it resting up to
            # |g| dt^2 above a floor. A pass with restitution re-integrates from the start,
            # x1 = x0 + dt v_new (Implementations 1 and 2). Still colliders skip the transforms.
            if restitution > 0.0:
                when = 0.0
            x1 = start + when * (x1_before - start) + (1.0 - when) * (push + dt * (v1 - vs))
            contact_done += 1
            # After its own contact pass x1 lies on the outer side of the plane tangent at the
            # contact (or no deeper than x0 did): skip the confirming sweep as above.
            left = beyond - (x1 - x1_before).norm()
            if (kinds.is_convex(c.kind[ci]) and is_still(c, ci) and push.norm_sqr() == 0.0
                    and left >= (x1 - x0).norm()):
                resolved = True
                apart, level, others, near_ci = n, n.dot(met), left, ci
                clearance = ti.min(n.dot(x1) - level, left)
                break
    if ti.static(failsafe):
        if not resolved:
            # Failsafe (docs/physics.md 3.4): stop relative to the collider, carried with it
            # (a body takes its share, exchange.body_stop)
            body = False
            if ti.static(kinematic):
                body = c.body[ci] >= 0
            x1 = last_start + push
            if body:
                v1 = body_stop(c, ci, i, inv_mass, x1, v1, n, last_vs, x1 - r * n)
            else:
                v1 = last_vs
            ti.atomic_add(p.stats[STAT_FAILSAFE], 1)
    return x1, v1, clearance, apart, level, others, near_ci


@ti.func
def resolve_exact_time(p: ti.template(), c: ti.template(), groups: ti.template(), kinematic: ti.template(), i,
                       inv_mass, x0: vec3, v1: vec3, r, slop, dt, max_iterations, rest_speed, wet_law: ti.template()):
    """Backing up time: move along the straight path to the first contact, apply the law
    there, go on for the remaining time. Approach speeds below rest_speed get e = 0, so a
    resting particle does not bounce on the velocity gravity gave it this substep."""
    x = x0
    v = v1
    remaining = dt
    done = False
    last_vs = vec3(0.0, 0.0, 0.0)
    for _ in range(max_iterations):
        x_end = x + remaining * v
        ci, t, n, vs = earliest_approach(c, groups, kinematic, x, x_end, v, 1.0 - remaining / dt, dt, r, slop)
        if ci < 0:
            x = x_end
            done = True
            break
        x = x + t * remaining * v
        restitution = 0.0
        if -(v - vs).dot(n) > rest_speed:
            restitution = c.material[ci][0]
        v, changed = apply_law(c, kinematic, ci, i, inv_mass, x, r, v, n, vs, restitution, wet_law)
        if not changed:  # a body this particle has pushed away (as in resolve_passes)
            x = x + (1.0 - t) * remaining * v
            done = True
            break
        remaining *= 1.0 - t
        last_vs = vs
    if not done:
        x = x + remaining * last_vs
        ti.atomic_add(p.stats[STAT_FAILSAFE], 1)
    return x, v


@ti.func
def resolve_particle(p: ti.template(), c: ti.template(), groups: ti.template(), kinematic: ti.template(), i, x0: vec3,
                     v0: vec3, x1: vec3, v1: vec3, dt, scheme: ti.template(), wet_law: ti.template(), max_iterations,
                     elastic_iterations, last_resort, max_push_speed, slop_fraction, rest_speed, clear_start):
    """Query and respond: resolve particle i's candidate (x1, v1) from its state (x0, v0) at
    time t against the colliders with the chosen scheme. Returns (x1, v1, clearance, apart,
    level, others, the collider `apart` belongs to): resolve_passes' (exact_time: clearance -1,
    unknown, and collider -1); and the last resort's push (zero unless x0 was inside a
    collider: repel_start_penetrations).
    clear_start: x0 is known to be clear of every collider (a kept clearance >= 0 at x0); with
    still colliders (not `kinematic`) the search for start penetrations is then skipped, as it
    could find none."""
    r = p.radius[i]
    inv_mass = 1.0 / p.mass[i]
    slop = slop_fraction * r
    clearance = -1.0
    apart = vec3(0.0, 0.0, 0.0)
    level = 0.0
    others = -1.0
    near_ci = -1
    push = vec3(0.0, 0.0, 0.0)
    search = True
    if ti.static(not kinematic):
        search = not clear_start
    if ti.static(scheme != SIMPLE):
        if search:
            x1, v1, push = repel_start_penetrations(p, c, groups, kinematic, i, x0, v0, x1, v1, r, p.mass[i], slop,
                                                    dt, last_resort, max_push_speed, wet_law)
    if ti.static(scheme == SIMPLE):
        x1, v1, clearance, apart, level, others, near_ci = resolve_passes(
            p, c, groups, kinematic, i, inv_mass, x0, push, v0, x1, v1, r, slop, dt, 0, 1, True, False, wet_law)
    elif ti.static(scheme == MICRO):
        x1, v1, clearance, apart, level, others, near_ci = resolve_passes(
            p, c, groups, kinematic, i, inv_mass, x0, push, v0, x1, v1, r, slop, dt, 0, max_iterations, True, True,
            wet_law)
    elif ti.static(scheme == ELASTIC_CONTACT):
        x1, v1, clearance, apart, level, others, near_ci = resolve_passes(
            p, c, groups, kinematic, i, inv_mass, x0, push, v0, x1, v1, r, slop, dt, elastic_iterations,
            max_iterations, False, True, wet_law)
    else:
        x1, v1 = resolve_exact_time(p, c, groups, kinematic, i, inv_mass, x0 + push, v1, r, slop, dt,
                                    max_iterations, rest_speed, wet_law)
    return x1, v1, clearance, apart, level, others, near_ci, push
