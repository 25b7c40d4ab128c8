"""A particle's contact with a rigid body: the two-body law and the ledger of what bodies are
given (docs/physics.md 7.2).

A body is a collider with finite mass. Its contact with a particle takes the collider law
(docs/physics.md 2) on the relative velocity at the contact, then shares the change between
the two by their inverse masses: along d, the direction of the change the law wants, the
impulse J = |dv| / (1/m_p + 1/m_b + (a x d) . I_b^-1 (a x d)) d goes to the particle and -J
to the body, a the lever from the body's centre of mass to the particle's centre (the line
of action passes through the particle's centre, so angular momentum is exchanged exactly).
Seen by one particle, the body has the mass and inertia its table row gives, which are the
body's divided by the number of particles touching it (mass splitting, docs/physics.md 7.2):
many particles striking a body at once, each resolved in parallel against the body's
velocity at the start of the substep, then give it the mean of what each alone would have,
instead of their sum.

Kernels resolve particles in parallel, so nobody adds to a body during the substep: each
particle writes what it gave into its own two ledger slots (`c.ledger_*`, two bodies per
particle and substep), and `bodies/coupling.py` sums the ledger in a fixed order afterwards,
so the sums are the same bit for bit in every run on the CPU. A third body touched by one
particle in one substep goes to `c.body_total` by atomic adds (order-dependent round-off).
The particle's later passes in the substep see the body as its own impulses left it
(`seen_velocity`).
"""

import taichi as ti

from .laws import respond

# A ledger slot's body index, and the flag of a slot whose particle was held (`held`).
BODY_MASK = (1 << 24) - 1
HELD_BIT = 1 << 24

# (solvers/pairs/shock.py's: a level below NO_SUPPORT rests on a collider through contacts;
# a body lies on a particle when its outward normal there is within acos(SUPPORT_COS) of down)
NO_SUPPORT = 1 << 30
SUPPORT_COS = 0.25

vec3 = ti.math.vec3


@ti.func
def ledger_slot(c: ti.template(), i, b):
    """Particle i's ledger slot for body b (2 i or 2 i + 1; b may carry HELD_BIT, for a held
    contact's slot): the one it holds, or a free one it claims; -1 when both hold others."""
    slot = -1
    for s in ti.static(range(2)):
        if slot < 0:
            k = 2 * i + s
            entry = c.ledger_body[k]
            if entry == b:
                slot = k
            elif entry < 0:
                c.ledger_body[k] = b
                c.ledger_impulse[k] = vec3(0.0, 0.0, 0.0)
                c.ledger_torque[k] = vec3(0.0, 0.0, 0.0)
                slot = k
    return slot


@ti.func
def seen_velocity(c: ti.template(), ci, slot, vs: vec3, point: vec3) -> vec3:
    """The body's surface velocity at `point` as particle (ledger slot) `slot` has left it:
    vs, the table's, less what the particle's impulses so far this substep took from it."""
    out = vs
    if slot >= 0:
        out = vs - c.body_inv_mass[ci] * c.ledger_impulse[slot] - \
            (c.body_inv_inertia[ci] @ c.ledger_torque[slot]).cross(point - c.body_com[ci])
    return out


@ti.func
def held(c: ti.template(), i, n: vec3, v: vec3, vs: vec3) -> bool:
    """Whether particle i (velocity v), touching a body whose outward normal there is n and
    surface velocity vs, lies under it, is held by what it rests on (its support level,
    solvers/pairs/shock.py) and meets it slower than a resting contact: shock propagation
    (docs/physics.md 7.2) makes it immovable against the body. A faster blow is exchanged
    (the body pushes sand aside, a crate landing kicks it up). support_up holds the up
    direction times that resting speed."""
    out = False
    up = c.support_up[0]
    rest = up.norm()
    if rest > 0.0:  # (zero: off, and `support` may be a placeholder)
        out = c.support[i] < NO_SUPPORT and n.dot(up) < -SUPPORT_COS * rest and (v - vs).dot(n) > -rest
    return out


@ti.func
def body_law(c: ti.template(), ci, i, inv_mass, x_ref: vec3, v: vec3, n: vec3, vs: vec3, point: vec3, restitution,
             depth, wet_law: ti.template()):
    """docs/physics.md 7.2: particle i (inverse mass inv_mass; centre x_ref) at velocity v
    against body collider ci's surface at `point` (outward normal n, table surface velocity
    vs; depth: how deep the particle is inside, where known, else 0). Returns (the
    particle's new velocity, whether the law changed anything)."""
    b = c.body[ci]
    changed = False
    if held(c, i, n, v, vs):
        # Held by its supports, the particle does not move the body: it books the contact
        # instead of an impulse (point, and the normal scaled by 1 + depth), and
        # bodies/coupling.py hands each body's held contacts to the rigid solver, which stops
        # the body on them all at once (shock propagation). For the particle the body is a
        # moving collider like any other, met inelastically (its motion towards the body is
        # the passes' doing, pushed up out of its neighbours, not a blow).
        # (Its own slot, apart from what it gave the body while free earlier in the substep.)
        m = c.material[ci]
        v_rel, dvn = respond(v - vs, n, 0.0, m[1], m[2], wet_law)
        changed = dvn > 0.0
        v = vs + v_rel
        slot = ledger_slot(c, i, b | HELD_BIT)
        if slot >= 0:
            c.ledger_impulse[slot] = point
            c.ledger_torque[slot] = (1.0 + depth) * n
    else:
        v, changed = _exchange(c, ci, b, ledger_slot(c, i, b), inv_mass, x_ref, v, n, vs, point, restitution,
                               wet_law)
    return v, changed


@ti.func
def _exchange(c: ti.template(), ci, b, slot, inv_mass, x_ref: vec3, v: vec3, n: vec3, vs: vec3, point: vec3,
              restitution, wet_law: ti.template()):
    """body_law for a particle free to move: the impulse shared by inverse masses."""
    seen, inv_body, inv_inertia = _body_side(c, ci, slot, n, vs, point)
    m = c.material[ci]
    v_rel, dvn = respond(v - seen, n, restitution, m[1], m[2], wet_law)
    return _share(c, ci, b, slot, inv_mass, x_ref, v, seen + v_rel - v, inv_body, inv_inertia)


@ti.func
def _body_side(c: ti.template(), ci, slot, n: vec3, vs: vec3, point: vec3):
    """Body collider ci as particle (ledger slot) `slot` meets it at `point` with normal n:
    (its surface velocity as the particle left it, its inverse mass and world inverse inertia
    as the particle sees them). A body resting on what holds it, met from above (shock
    propagation, docs/physics.md 6.2), does not give way: infinite mass, and what the particle
    gives it, its supports take."""
    seen = vs
    inv_body = 0.0
    inv_inertia = ti.Matrix.zero(float, 3, 3)
    if n.dot(c.body_up[ci]) <= SUPPORT_COS:
        seen = seen_velocity(c, ci, slot, vs, point)
        inv_body = c.body_inv_mass[ci]
        inv_inertia = c.body_inv_inertia[ci]
    return seen, inv_body, inv_inertia


@ti.func
def _share(c: ti.template(), ci, b, slot, inv_mass, x_ref: vec3, v: vec3, delta: vec3, inv_body, inv_inertia):
    """The change `delta` the particle's velocity v would take from a body of infinite mass,
    shared with body b by inverse masses (docs/physics.md 7.2) and booked. Returns (the
    particle's new velocity, whether it changed)."""
    size = delta.norm()
    changed = False
    if size > 0.0:
        changed = True
        d = delta / size
        arm = x_ref - c.body_com[ci]
        ad = arm.cross(d)
        weight = inv_mass + inv_body + ad.dot(inv_inertia @ ad)
        impulse = (size / weight) * d
        v += inv_mass * impulse
        _book(c, b, slot, impulse, arm.cross(impulse))
    return v, changed


@ti.func
def body_stop(c: ti.template(), ci, i, inv_mass, x_ref: vec3, v: vec3, n: vec3, vs: vec3, point: vec3) -> vec3:
    """The failsafe against body collider ci (docs/physics.md 3.4 and 7.2): particle i stops
    relative to the body's surface at `point` as the two bodies share it, perfectly inelastic
    in every direction, and books the impulse. (Stopping it at the surface velocity alone, as
    against a collider of infinite mass, would give the body nothing: momentum was lost, 7 % of
    a 0.1 kg body's in a crowd.) A body resting on what holds it (n against body_up) does not
    give way. Returns the particle's new velocity."""
    b = c.body[ci]
    slot = ledger_slot(c, i, b)
    seen, inv_body, inv_inertia = _body_side(c, ci, slot, n, vs, point)
    v_new, _ = _share(c, ci, b, slot, inv_mass, x_ref, v, seen - v, inv_body, inv_inertia)
    return v_new


@ti.func
def _book(c: ti.template(), b, slot, impulse: vec3, torque: vec3):
    """What a particle gave body b: into its ledger slot, or (slot -1: both slots hold other
    bodies) into the body's shared sum."""
    if slot >= 0:
        c.ledger_impulse[slot] += impulse
        c.ledger_torque[slot] += torque
    else:
        ti.atomic_add(c.body_total[2 * b], impulse)
        ti.atomic_add(c.body_total[2 * b + 1], torque)


@ti.func
def record_force(c: ti.template(), ci, i, x_ref: vec3, impulse: vec3):
    """The penalty solver's share: `impulse` (N s, force times dt) given to particle i by
    body collider ci this substep; the body gets the opposite (docs/physics.md 7.3)."""
    b = c.body[ci]
    _book(c, b, ledger_slot(c, i, b), impulse, (x_ref - c.body_com[ci]).cross(impulse))
