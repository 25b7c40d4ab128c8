"""Impulse-based contact resolution: docs/physics.md 3, the ways of putting collisions into
time integration. Each particle is resolved independently (in parallel) against the colliders.

One substep of one particle reads as: integrate without collisions to a candidate (x1, v1);
accept penetrations that were already there at time t and push out with the last-resort
repulsion; then resolve the candidate with the chosen scheme:

- "simple"          Implementation 1: one pass of the law on the average velocity.
- "micro"           Implementation 2: repeat while x1 interferes, e = 0 after the first pass.
- "elastic_contact" Implementation 3 (default): the elastic law on v(t), then inelastic
                    contact passes on the average velocity. Solves the bouncing-block problem.
- "exact_time"      Backing up time: advance to each first contact along the straight path,
                    apply the law there, continue for the rest of the substep. Closed form for
                    planes and spheres, root finding for the other shapes.

Loops are capped; a particle still interfering after the cap gets the failsafe: it stops
relative to the collider (v = surface velocity, x1 = x carried with the collider).

Every contact is taken relative to its collider (docs/physics.md 3.6): the kernels compile
that code in only for a collider table with moving colliders (`kinematic`), so still scenes
run the plain formulas.

Kernels take the particle store and the collider table as argument packs (`p`, `c`:
types.ParticleArgs, types.ColliderArgs) and `groups`, the compile-time mask of the collider
kinds compiled in; the solver launches them with every argument named (`_law`).
"""


import numpy as np
import taichi as ti

from .. import validate
from ..geometry import kinds
from ..response.exchange import body_law, held
from ..response.laws import WET_LAWS, respond
from ..response.penalty import FIELD_NONE, apply_repulsion
from ..response.repulsion import RepulsionField, pack
from ..types import ACTIVE, ARRAY, NON_FINITE, STAT_FAILSAFE, STAT_REPULSION, ColliderArgs, ParticleArgs, vec3
from .base import Solver
from .detection import (carried, detect, earliest_approach, is_still, keep_out, start_penetration,
                        surface_velocity)
from .integrate import (flag, flight_path_bound, flight_stays_inside, free_flight, state_status, store,
                        symplectic_euler)

# The last resort's settings as one kernel argument: the push fraction, then a repulsion
# field's kind (0: none, push instead), profile, strength, decay and range.
last_resort6 = ti.types.vector(6, float)

#: A particle's kept clearance when the last launch found it at a fixed point of its substep
#: (impulse_substep). Negative, so every other reader takes it for "unknown" and queries.
AT_REST = -2.0

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
    Returns (x1, v1, clearance of x1, or -1 when unknown).
    """
    v_start = v0
    elastic_left = elastic_passes
    contact_done = 0
    resolved = False
    clearance = -1.0
    last_vs = vec3(0.0, 0.0, 0.0)
    last_start = x0
    ci = -1
    n = vec3(0.0, 1.0, 0.0)
    vs = vec3(0.0, 0.0, 0.0)
    for _ in range(elastic_passes + contact_passes + 1):
        v_test = v_start
        if elastic_left == 0:
            v_test = v1
        ci, n, vs, when, ci_alt, n_alt, vs_alt, when_alt, near, nearest, second = detect(c, groups, kinematic, x0, x1,
                                                                                          v_test, v1, r, slop)
        if ci < 0 and elastic_left > 0 and ci_alt >= 0:
            # Nothing to bounce off, but the candidate velocity meets a contact: go straight to
            # the contact passes with what this sweep found.
            elastic_left = 0
            ci, n, vs, when = ci_alt, n_alt, vs_alt, when_alt
        if ci < 0:
            resolved = True
            clearance = near
            break
        last_vs = vs
        start = x0  # where the path relative to the collider starts: x0, carried if it moves
        if ti.static(kinematic):
            start = carried(c, ci, x0)
        last_start = start
        restitution = c.material[ci][0]
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
        else:
            if contact_done == contact_passes:
                break
            if ti.static(not first_contact_elastic):
                restitution = 0.0
            elif contact_done > 0:
                restitution = 0.0
            x1_before = x1
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
            # A still, convex collider cannot be met again after its own contact pass: x1
            # now lies on the outer side of the plane tangent at the contact (or no deeper
            # than x0 did). When no other collider is within reach, skip the confirming sweep.
            others = near if nearest != ci else second
            if (kinds.is_convex(c.kind[ci]) and is_still(c, ci) and push.norm_sqr() == 0.0
                    and others - (x1 - x1_before).norm() >= (x1 - x0).norm()):
                resolved = True
                break
    if ti.static(failsafe):
        if not resolved:
            # Failsafe (docs/physics.md 3.4): stop relative to the collider, carried with it.
            v1 = last_vs
            x1 = last_start + push
            ti.atomic_add(p.stats[STAT_FAILSAFE], 1)
    return x1, v1, clearance


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
def try_free_flight(x0: vec3, v0: vec3, clearance, gravity: vec3, dt, k, use_domain: ti.template(), domain_lo: vec3,
                    domain_hi: vec3):
    """k substeps at once when the clearance covers their whole path (and, with a domain,
    every substep's end stays inside it). Returns (done, x_k, v_k, clearance left)."""
    done = False
    xk, vk = x0, v0
    left = clearance
    if clearance > 0.0:
        path = flight_path_bound(v0, gravity, dt, k) * (1.0 + 1e-5)
        if clearance > path:
            xk, vk = free_flight(x0, v0, gravity, dt, k)
            inside = True
            if ti.static(use_domain):
                inside = flight_stays_inside(x0, v0, gravity, dt, k, domain_lo, domain_hi)
            if inside and state_status(xk, vk, False, domain_lo, domain_hi) == ACTIVE:
                done = True
                left = clearance - path
    return done, xk, vk, left


@ti.kernel
def impulse_substep(particles: ParticleArgs, colliders: ColliderArgs, groups: ti.template(), kinematic: ti.template(),
                    clearances: ARRAY, reuse_clearance: ti.i32, reuse_rest: ti.i32, n_substeps: ti.i32, gravity: vec3,
                    dt: float,
                    scheme: ti.template(), wet_law: ti.template(), max_iterations: ti.i32, elastic_iterations: ti.i32,
                    last_resort: last_resort6, max_push_speed: float, slop_fraction: float, rest_speed: float,
                    use_domain: ti.template(), domain_lo: vec3, domain_hi: vec3):
    """n_substeps substeps of every active particle against colliders that hold still for the
    call; `clearances` (one per particle, in-out) are kept between launches. kinematic: the
    table holds moving colliders (compile time: their relative-motion code is compiled in).

    Particles are independent of each other here, so one launch runs several substeps and
    keeps each particle in registers, including its clearance: a lower bound on how far it
    can travel before it could touch a collider (phi is 1-Lipschitz). While the clearance
    exceeds the path of the remaining substeps, nothing can be touched and those substeps are
    plain integration, done in closed form at once (free_flight). The clearance is reused
    from the last launch when the host says nothing moved in between: neither the colliders
    nor the particles outside this kernel (reuse_clearance).
    A substep that leaves a particle's state bit for bit as it was (a particle at rest on a
    still collider: gravity's dv cancelled by the contact, x1 = x0) would do exactly the same
    in every later substep of the launch, so the particle is done: an exact shortcut, not an
    approximation (no sleeping thresholds). Its clearance is then written as AT_REST, and the
    next launch skips it without reading its state when the host says that launch's substeps
    are the same map (reuse_rest: the clearances hold, and gravity, dt and the law are those of
    this launch): a fixed point of the same map stays one. The state stays in registers
    between substeps and is written once."""
    for i in range(particles.count):
        if particles.flags[i] == ACTIVE and not (reuse_rest and clearances[i] == AT_REST):
            x0 = particles.x[i]
            v0 = particles.v[i]
            clearance = -1.0
            if reuse_clearance:
                clearance = clearances[i]
            # the common case first, kept small: the whole launch in free flight
            flown, xk, vk, left = try_free_flight(x0, v0, clearance, gravity, dt, n_substeps, use_domain,
                                                  domain_lo, domain_hi)
            if flown:
                particles.x[i] = xk
                particles.v[i] = vk
                clearances[i] = left
            else:
                status = ACTIVE
                at_rest = False
                s = 0
                while s < n_substeps:
                    if s > 0:  # the clearance may have been renewed by a query
                        flown, xk, vk, left = try_free_flight(x0, v0, clearance, gravity, dt, n_substeps - s,
                                                              use_domain, domain_lo, domain_hi)
                        if flown:
                            x0, v0, clearance = xk, vk, left
                            break
                    # one substep: free flight while the clearance lasts, else query and respond
                    x1, v1 = symplectic_euler(x0, v0, gravity, dt)
                    step = (x1 - x0).norm()
                    unchanged = False
                    if clearance > step:
                        clearance -= step
                    else:
                        x1, v1, clearance = resolve_particle(particles, colliders, groups, kinematic, i, x0, v0, x1,
                                                             v1, dt, scheme, wet_law, max_iterations,
                                                             elastic_iterations, last_resort, max_push_speed,
                                                             slop_fraction, rest_speed)
                        unchanged = all(x1 == x0) and all(v1 == v0)
                    status = state_status(x1, v1, use_domain, domain_lo, domain_hi)
                    if status == NON_FINITE:
                        break  # frozen at its last finite state
                    x0 = x1
                    v0 = v1
                    s += 1
                    if status != ACTIVE or unchanged:
                        at_rest = unchanged and status == ACTIVE
                        break
                particles.x[i] = x0
                particles.v[i] = v0
                clearances[i] = clearance
                if at_rest:
                    clearances[i] = AT_REST
                if status != ACTIVE:
                    flag(particles, i, status)


@ti.func
def resolve_particle(p: ti.template(), c: ti.template(), groups: ti.template(), kinematic: ti.template(), i, x0: vec3,
                     v0: vec3, x1: vec3, v1: vec3, dt, scheme: ti.template(), wet_law: ti.template(), max_iterations,
                     elastic_iterations, last_resort, max_push_speed, slop_fraction, rest_speed):
    """Query and respond: resolve particle i's candidate (x1, v1) from its state (x0, v0) at
    time t against the colliders with the chosen scheme. Returns (x1, v1, clearance)."""
    r = p.radius[i]
    inv_mass = 1.0 / p.mass[i]
    slop = slop_fraction * r
    clearance = -1.0
    push = vec3(0.0, 0.0, 0.0)
    if ti.static(scheme != SIMPLE):
        x1, v1, push = repel_start_penetrations(p, c, groups, kinematic, i, x0, v0, x1, v1, r, p.mass[i], slop, dt,
                                                last_resort, max_push_speed, wet_law)
    if ti.static(scheme == SIMPLE):
        x1, v1, clearance = resolve_passes(p, c, groups, kinematic, i, inv_mass, x0, push, v0, x1, v1, r, slop, dt,
                                           0, 1, True, False, wet_law)
    elif ti.static(scheme == MICRO):
        x1, v1, clearance = resolve_passes(p, c, groups, kinematic, i, inv_mass, x0, push, v0, x1, v1, r, slop, dt, 0,
                                           max_iterations, True, True, wet_law)
    elif ti.static(scheme == ELASTIC_CONTACT):
        x1, v1, clearance = resolve_passes(p, c, groups, kinematic, i, inv_mass, x0, push, v0, x1, v1, r, slop, dt,
                                           elastic_iterations, max_iterations, False, True, wet_law)
    else:
        x1, v1 = resolve_exact_time(p, c, groups, kinematic, i, inv_mass, x0 + push, v1, r, slop, dt,
                                    max_iterations, rest_speed, wet_law)
    return x1, v1, clearance


@ti.kernel
def impulse_resolve_candidates(particles: ParticleArgs, colliders: ColliderArgs, groups: ti.template(),
                               kinematic: ti.template(), clearances: ARRAY, reuse_clearance: ti.i32, dt: float,
                               scheme: ti.template(), wet_law: ti.template(), max_iterations: ti.i32,
                               elastic_iterations: ti.i32, last_resort: last_resort6, max_push_speed: float,
                               slop_fraction: float, rest_speed: float, use_domain: ti.template(), domain_lo: vec3,
                               domain_hi: vec3,
                               contact_only: ti.template(), store_state: ti.template(),
                               # in-out
                               candidate_x: ARRAY, candidate_v: ARRAY):
    """Resolve candidates that another phase (particle-particle contacts) produced: with the
    chosen scheme, or with contact passes only (e = 0) when contact_only; then either store
    them as the new state, or write them back as candidates for the next phase. A particle
    whose kept clearance (see impulse_substep) exceeds the way from x to its candidate
    cannot touch a collider: it is left as it is, without a query."""
    for i in range(particles.count):
        resolve_candidate(particles, colliders, groups, kinematic, i, clearances, reuse_clearance, candidate_x,
                          candidate_v, dt, scheme, wet_law, max_iterations, elastic_iterations, last_resort,
                          max_push_speed, slop_fraction, rest_speed, use_domain, domain_lo, domain_hi, contact_only,
                          store_state)


@ti.func
def resolve_candidate(p: ti.template(), c: ti.template(), groups: ti.template(), kinematic: ti.template(), i,
                      clearances: ti.template(), reuse_clearance, candidate_x: ti.template(),
                      candidate_v: ti.template(), dt,
                      scheme: ti.template(), wet_law: ti.template(), max_iterations, elastic_iterations, last_resort,
                      max_push_speed, slop_fraction, rest_speed, use_domain: ti.template(), domain_lo: vec3,
                      domain_hi: vec3, contact_only: ti.template(), store_state: ti.template()):
    if p.flags[i] == ACTIVE:
        x0 = p.x[i]
        v0 = p.v[i]
        x1 = candidate_x[i]
        v1 = candidate_v[i]
        way = (x1 - x0).norm()
        clearance = -1.0
        if reuse_clearance:
            clearance = clearances[i]
        if clearance > way:
            clearance -= way  # out of every collider's reach: nothing to resolve
        else:
            if ti.static(contact_only):
                r = p.radius[i]
                x1, v1, clearance = resolve_passes(p, c, groups, kinematic, i, 1.0 / p.mass[i], x0,
                                                   vec3(0.0, 0.0, 0.0), v0, x1, v1, r,
                                                   slop_fraction * r, dt, 0, max_iterations, False, True, wet_law)
                x_kept = keep_out(c, groups, kinematic, x0, x1, r)
                if any(x_kept != x1):
                    clearance = -1.0
                    # A position kept out of a collider keeps no velocity into it either: the
                    # contact passes leave motion within the slop alone, and a particle held
                    # against a ceiling (a body resting on a pile, docs/physics.md 7.2) would
                    # otherwise carry the push of its neighbours on as velocity.
                    out = x_kept - x1
                    into = v1.dot(out)
                    if into < 0.0:
                        v1 -= (into / out.norm_sqr()) * out
                x1 = x_kept
            else:
                x1, v1, clearance = resolve_particle(p, c, groups, kinematic, i, x0, v0, x1, v1, dt, scheme, wet_law,
                                                     max_iterations, elastic_iterations, last_resort, max_push_speed,
                                                     slop_fraction, rest_speed)
        if ti.static(store_state):
            store(p, i, x0, v0, x1, v1, use_domain, domain_lo, domain_hi)
            clearances[i] = clearance
        else:
            candidate_x[i] = x1
            candidate_v[i] = v1


class ImpulseSolver(Solver):
    """Resolve particle-collider contacts with impulses (docs/physics.md 2 and 3).

    scheme: "elastic_contact" (default, Implementation 3), "micro" (Implementation 2),
        "simple" (Implementation 1, kept for comparison: it fails for resting contact) or
        "exact_time" (backing up time; exact for planes and spheres).
    max_iterations: cap on the contact passes (and on events per substep for exact_time)
        before the failsafe. More passes resolve corners better and cost time in contact.
    elastic_iterations: how many times the elastic pass of Implementation 3 may repeat
        while the candidate still interferes.
    push_fraction: the last resort for a particle already inside a collider at the start of
        a substep: this fraction of the depth is recovered per substep, by moving the position
        along the normal (the velocity gets the inelastic law), at most max_push_speed * dt
        per substep.
    max_push_speed: m/s, the cap on that push.
    last_resort: None (the push above) or a `tc.RepulsionField` acting instead on the
        velocity of a particle found inside, at gap -depth (seed 002). A velocity field of
        strength s lets it leave at s m/s or more, a force field accelerates it out.
        Colliders' own repulsion fields (`add_collider(repulsion=...)`) are for the penalty
        solver; this solver ignores them, with a warning.
    slop: penetration, as a fraction of the particle radius, below which a particle still
        counts as outside (absorbs round-off at resting contacts).
    rest_speed: exact_time only: approach speeds (m/s) below this get e = 0. None: twice the
        speed gravity adds in one substep.
    wet_law: "linear" max(0, 1 - D dv_N) or "exponential" exp(-D dv_N) (seed 001).
    (`repulsion` and `repulsion_speed_limit` are the old names of push_fraction and
    max_push_speed.)
    """

    pair_model = "impulses"

    @validate.renamed_arguments(repulsion="push_fraction", repulsion_speed_limit="max_push_speed")
    def __init__(self, *, scheme: str = "elastic_contact", max_iterations: int = 8,
                 elastic_iterations: int = 1, push_fraction: float = 0.1, max_push_speed: float = 1.0,
                 slop: float = 1e-3, rest_speed: float | None = None, wet_law: str = "linear",
                 last_resort: RepulsionField | None = None):
        if scheme not in SCHEMES:
            raise ValueError(f"scheme must be one of {tuple(SCHEMES)}; got {scheme!r}")
        if wet_law not in WET_LAWS:
            raise ValueError(f"wet_law must be one of {tuple(WET_LAWS)}; got {wet_law!r}")
        self.scheme = scheme
        self.max_iterations = validate.integer("max_iterations", max_iterations, low=1)
        self.elastic_iterations = validate.integer("elastic_iterations", elastic_iterations, low=0)
        self.push_fraction = validate.real("push_fraction", push_fraction, low=0.0, high=1.0, low_open=True)
        self.max_push_speed = validate.real("max_push_speed", max_push_speed, low=0.0, low_open=True)
        self.slop = validate.real("slop", slop, low=0.0, high=0.5)
        self.rest_speed = validate.real("rest_speed", rest_speed, low=0.0, allow_none=True)
        self.wet_law = wet_law
        if last_resort is not None and not isinstance(last_resort, RepulsionField):
            raise TypeError(f"last_resort must be None or a tc.RepulsionField; got {type(last_resort).__name__}")
        self.last_resort = last_resort

    def __repr__(self):
        return f"ImpulseSolver(scheme={self.scheme!r}, max_iterations={self.max_iterations})"

    def check(self, world, dt: float) -> list[str]:
        """Warnings for the scene as it stands (called by Scene before stepping)."""
        fielded = [k for k, e in enumerate(world.colliders.entries) if e.repulsion is not None]
        if not fielded:
            return []
        return [f"ImpulseSolver ignores the repulsion fields of colliders {fielded}; they act with "
                "tc.PenaltySolver. ImpulseSolver(last_resort=tc.RepulsionField(...)) uses one as its last resort."]

    def _law(self, world, dt: float) -> dict:
        """The kernels' scheme, law and domain arguments, by name."""
        rest_speed = self.rest_speed if self.rest_speed is not None else 2.0 * float(np.linalg.norm(world.gravity)) * dt
        use_domain, lo, hi = world.domain_bounds()
        return dict(scheme=SCHEMES[self.scheme], wet_law=WET_LAWS[self.wet_law], max_iterations=self.max_iterations,
                    elastic_iterations=self.elastic_iterations,
                    last_resort=last_resort6(self.push_fraction, *pack(self.last_resort)),
                    max_push_speed=self.max_push_speed, slop_fraction=self.slop, rest_speed=rest_speed,
                    use_domain=use_domain, domain_lo=vec3(*lo), domain_hi=vec3(*hi))

    def resolve_candidates(self, world, dt: float, candidate_x, candidate_v, *, contact_only=False,
                           store_state=True):
        """Resolve candidate positions and velocities (arrays) from another phase against the
        colliders: with the scheme, or contact passes only; store the result as the
        particles' new state, or write it back to the candidate arrays."""
        store, table = world.particles, world.colliders
        reuse = store.clearances_hold(table)
        if store_state:
            store.mark_moved()
        impulse_resolve_candidates(particles=store.args, colliders=table.args, groups=table.groups,
                                   kinematic=table.has_kinematic, clearances=store.clearance,
                                   reuse_clearance=int(reuse), dt=dt,
                                   **self._law(world, dt), contact_only=contact_only, store_state=store_state,
                                   candidate_x=candidate_x, candidate_v=candidate_v)
        if store_state:
            store.clearances_written(table)

    def advance(self, world, dt: float, substeps: int = 1):
        """Advance every active particle by `substeps` substeps of dt against the colliders,
        which must keep their current poses for the whole call."""
        store, table = world.particles, world.colliders
        reuse = store.clearances_hold(table)
        law = self._law(world, dt)
        # the map one substep applies: particles at a fixed point of it stay there (AT_REST)
        same_map = (tuple(map(float, world.gravity)), float(dt), self.scheme, self.wet_law, self.max_iterations,
                    self.elastic_iterations, self.push_fraction, self.max_push_speed, self.slop,
                    float(law["rest_speed"]), repr(self.last_resort), repr(world.domain))
        reuse_rest = reuse and store.rest_map == same_map
        store.mark_moved()
        impulse_substep(particles=store.args, colliders=table.args, groups=table.groups,
                        kinematic=table.has_kinematic, clearances=store.clearance,
                        reuse_clearance=int(reuse), reuse_rest=int(reuse_rest), n_substeps=substeps,
                        gravity=vec3(*world.gravity), dt=dt, **law)
        store.clearances_written(table)
        store.rest_map = same_map

    def pair_substep(self, world, pairs, dt: float):
        """One substep with particle-particle impulses, the colliders resolved by this solver."""
        pairs.impulse_substep(world, self, dt)
