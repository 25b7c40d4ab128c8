"""Particles hitting particles: two-body impulses over the hash grid's neighbour lists.

PHYSICS.md 2, two movable bodies: the law gives the wanted change of relative velocity,
the impulse I solves dv_rel = (1/m_a + 1/m_b) I and is applied as +I/m_a and -I/m_b, so
momentum is conserved exactly. PHYSICS.md 3's elastic-then-contact split carries over:

1. predict: candidates x1 = x + dt v1, v1 = v + dt g (symplectic Euler);
2. neighbours: the hash grid on the candidates, lists of particles within reach;
3. elastic pass: for pairs overlapping at the candidates, the law with restitution on the
   velocities at the start of the substep, its change added to the candidates;
4. contact passes (e = 0, friction as usual) on the candidate velocities, re-integrating
   x1 = x + dt v1 after each;
5. projection passes: overlap left after the velocity passes is removed by moving
   positions apart, split by inverse mass (momentum and the centre of mass unchanged);
   Gauss-Seidel then takes a settle pass: the law (with restitution: a pair that comes into
   contact just then still bounces) on the pairs touching at the final positions, positions
   unchanged, so no contact carries approaching velocity into the next substep;
6. colliders: the scene's solver resolves the candidates against the colliders last, so no
   particle ends inside a collider.

The passes visit the pairs in one of two ways (`method`):
- "gauss-seidel" (default): one pair after another, each pair's change applied to both
  particles before the next pair is seen, in parallel over a colouring of the grid
  (gauss_seidel.py). Support climbs a pile within a pass: 1 contact, 2 projection and a
  settle pass leave a deep pile a third of the overlap 4 + 4 Jacobi passes leave, and it
  settles sooner, in less time (a few of its jammed particles keep jittering: see
  the README's stillness figures).
- "jacobi": every particle reads the previous iterate, in parallel. A plain Jacobi sum
  over-corrects a particle with many contacts and over-compresses piles; each pair's share is
  divided by the larger of the two particles' contact counts (the same number on both sides,
  so the impulses stay equal and opposite) and over-relaxed by `relaxation`, never beyond the
  full share (an isolated pair gets exactly its impulse). Its result does not depend on the
  order of the particles (Gauss-Seidel's does, slightly: the store's reordering by cell
  changes the order in which pairs are resolved).
"""

import collections

import numpy as np
import taichi as ti

from .. import validate
from ..materials import Material
from ..neighbors.hash_grid import QUERY_RANGES, HashGrid, cell_of, query_range
from ..response.collide import WET_LAWS
from ..response.laws import pair_normal, respond
from ..response.penalty import SPHERE_INERTIA, friction_force, rolling_torque, spring_damper
from . import gauss_seidel
from .penalty import contact_constants
from ..scene import particles as P

vec3 = ti.math.vec3
ivec3 = ti.math.ivec3
vec4 = ti.math.vec4

# Substeps between reorderings of the store by cell: particles move little in a few
# substeps, so the order stays coherent, and the permutation's cost is spread.
REORDER_INTERVAL = 8
# Tangential springs (DEM): contacts whose spring a particle carries from one substep to the
# next; a particle touching more holds the rest by the regularised friction (friction_force)
# and reports them in `history_overflow`.
HISTORY = 12
TANGENTIAL_RATIO = 2.0 / 7.0  # default k_t / k_n (and D_t / D_n) of the tangential springs
# How the passes visit the pairs, and the defaults of each: (contact passes, projection passes,
# relaxation). Gauss-Seidel converges in fewer passes (see gauss_seidel.py).
METHODS = {"gauss-seidel": (1, 2, 1.0), "jacobi": (4, 4, 1.5)}
# (Gauss-Seidel's second contact pass left the 100k benchmark pile as it was after 1.0 to 2.5 s:
# kinetic energy, speeds and overlap within a few per cent, for a fifth more time per substep;
# see the README's tuning table.)


@ti.kernel
def _predict(x: ti.types.ndarray(), v: ti.types.ndarray(), flags: ti.types.ndarray(), n: ti.i32, gravity: vec3,
             dt: float, check: ti.i32, listed_at: ti.types.ndarray(), reach2: float,
             # outputs
             x1: ti.types.ndarray(), v1: ti.types.ndarray(), stale: ti.types.ndarray()):
    """The candidates, and (if check) in stale[0] whether the neighbour lists no longer hold:
    some candidate moved more than sqrt(reach2) from where the lists saw it (listed_at: x, y,
    z and 1 for a particle simulated then, 0 for one not), or its status changed since."""
    stale[0] = 0
    for i in range(n):
        vi = v[i]
        xi = x[i]
        active = flags[i] == P.ACTIVE
        if active:
            vi = vi + dt * gravity
            xi = xi + dt * vi
        v1[i] = vi
        x1[i] = xi
        if check and _left_lists(xi, active, listed_at[i], reach2):
            stale[0] = 1


@ti.func
def _left_lists(x: vec3, active, seen: vec4, reach2):
    """Whether a particle at x (active: simulated now) is no longer held by lists that saw it
    at seen.xyz (seen.w: 1 if it was simulated then, 0 if not): it moved more than
    sqrt(reach2) since, or its status changed."""
    return (active and (x - seen.xyz).norm_sqr() > reach2) or (active != (seen.w > 0.5))


@ti.kernel
def _moved(x: ti.types.ndarray(), flags: ti.types.ndarray(), n: ti.i32, listed_at: ti.types.ndarray(), reach2: float,
           # output
           stale: ti.types.ndarray()):
    """In stale[0], whether the DEM kernel's lists no longer hold: some particle moved more
    than sqrt(reach2) from where the lists saw it, or its status changed since (_left_lists)."""
    stale[0] = 0
    for i in range(n):
        if _left_lists(x[i], flags[i] == P.ACTIVE, listed_at[i], reach2):
            stale[0] = 1


@ti.kernel
def _mark_listed(x1: ti.types.ndarray(), flags: ti.types.ndarray(), n: ti.i32,
                 # outputs
                 listed_at: ti.types.ndarray()):
    for i in range(n):
        listed_at[i] = vec4(x1[i], ti.select(flags[i] == P.ACTIVE, 1.0, 0.0))


@ti.kernel
def _permute_history(order: ti.types.ndarray(), n: ti.i32, count: ti.types.ndarray(), partner: ti.types.ndarray(),
                     spring: ti.types.ndarray(), roll: ti.types.ndarray(), rolling: ti.template(),
                     # outputs: slot k gets the springs of slot order[k] (as ParticleStore.permute)
                     count2: ti.types.ndarray(), partner2: ti.types.ndarray(), spring2: ti.types.ndarray(),
                     roll2: ti.types.ndarray()):
    for k in range(n):
        i = order[k]
        count2[k] = count[i]
        for h in range(HISTORY):
            partner2[k, h] = partner[i, h]
            spring2[k, h] = spring[i, h]
            if ti.static(rolling):
                roll2[k, h] = roll[i, h]


@ti.func
def pair_share(contacts: ti.template(), i, j, relaxation):
    """The pair's share of its full correction in a Jacobi pass: relaxation over the larger
    contact count of the two (the same number on both sides), at most 1. The counts are
    those of the previous pass (the positions move little between passes)."""
    return ti.min(1.0, relaxation / ti.max(contacts[i], contacts[j], 1))


@ti.kernel
def _velocity_pass(x: ti.types.ndarray(), flags: ti.types.ndarray(), x1: ti.types.ndarray(),
                   v_test: ti.types.ndarray(), mass: ti.types.ndarray(), radius: ti.types.ndarray(), n: ti.i32,
                   neighbours: ti.types.ndarray(), neighbour_count: ti.types.ndarray(), contacts: ti.types.ndarray(),
                   restitution: float, friction: float, wet_friction: float, wet_law: ti.template(),
                   relaxation: float, dt: float, elastic: ti.i32,
                   # outputs
                   dv: ti.types.ndarray(), contacts_now: ti.types.ndarray(), changed: ti.types.ndarray(),
                   # in-out
                   v_start: ti.types.ndarray(), v1: ti.types.ndarray()):
    """One velocity pass, then its result applied, in one launch (two parallel loops, the
    second after the first). dv_i = sum over overlapping neighbours j of particle i's share
    of the pair impulse; the pass also counts those neighbours (the shares of the next pass),
    and in changed[0] the particles with an approaching contact (0: the pass did nothing,
    and nothing is applied). Applied: v1 += dv; elastic (the law acted on v(t) = v_test =
    v_start): v_start += dv and x1 += dt dv; contact: x1 = x + dt v1, re-integrated from the
    start."""
    changed[0] = 0
    for i in range(n):
        acc = vec3(0.0, 0.0, 0.0)
        mi = mass[i]
        count = 0
        approaching = 0
        xi = x1[i]
        ri = radius[i]
        vi = v_test[i]
        for k in range(neighbour_count[i]):
            # every listed neighbour is evaluated and the touching, approaching ones kept
            # (selects, no branches: which ones they are is not predictable, and without
            # branches the processor overlaps the neighbours' arithmetic)
            j = neighbours[i, k]
            xj = x1[j]
            reach = ri + radius[j]
            touching = (xi - xj).norm_sqr() < reach * reach
            nrm, dist = pair_normal(xi, xj, i, j)
            v_rel = vi - v_test[j]
            v_new, dvn = respond(v_rel, nrm, restitution, friction, wet_friction, wet_law)
            approach = touching & (dvn > 0.0)
            # i's part of the pair impulse I = (v_new - v_rel) / (1/m_i + 1/m_j): I / m_i
            part = mass[j] / (mi + mass[j])
            acc += ti.select(approach, pair_share(contacts, i, j, relaxation) * part, 0.0) * (v_new - v_rel)
            count += ti.cast(touching, ti.i32)
            approaching += ti.cast(approach, ti.i32)
        dv[i] = acc
        contacts_now[i] = count
        if approaching > 0 and changed[0] == 0:
            changed[0] = 1  # read first: a shared line, written once, not an atomic per particle
    for i in range(n):
        if changed[0] != 0 and flags[i] == P.ACTIVE:
            v1[i] += dv[i]
            if elastic:
                v_start[i] += dv[i]  # the elastic law acted on v(t): x1 += dt dv
                x1[i] += dt * dv[i]
            else:
                x1[i] = x[i] + dt * v1[i]  # contact: re-integrate from the start


@ti.kernel
def _projection_pass(flags: ti.types.ndarray(), x1: ti.types.ndarray(), mass: ti.types.ndarray(),
                     radius: ti.types.ndarray(), n: ti.i32, neighbours: ti.types.ndarray(),
                     neighbour_count: ti.types.ndarray(), contacts: ti.types.ndarray(), relaxation: float, dt: float,
                     # outputs
                     dx: ti.types.ndarray(), contacts_now: ti.types.ndarray(), changed: ti.types.ndarray(),
                     # in-out
                     v1: ti.types.ndarray()):
    """One projection pass, then its result applied, in one launch. dx_i = sum over
    overlapping neighbours j of particle i's share of moving the pair apart, split by
    inverse mass; counts as in _velocity_pass; changed[0]: particles with an overlap (0:
    nothing left to project). Applied: x1 += dx, and the velocity follows the position
    (as in position-based dynamics: a pile held apart by projection is at rest, not moving
    into its neighbours), v1 += dx / dt."""
    # the positions a pass reads are those before it: dx is applied in a second loop
    changed[0] = 0
    for i in range(n):
        acc = vec3(0.0, 0.0, 0.0)
        mi = mass[i]
        count = 0
        xi = x1[i]
        ri = radius[i]
        for k in range(neighbour_count[i]):  # branch-free, as in _velocity_pass
            j = neighbours[i, k]
            xj = x1[j]
            reach = ri + radius[j]
            nrm, dist = pair_normal(xi, xj, i, j)
            overlap = reach - dist
            touching = overlap > 0.0
            # i's part of the separation: (1/m_i) / (1/m_i + 1/m_j)
            share = pair_share(contacts, i, j, relaxation) * overlap * mass[j] / (mi + mass[j])
            acc += ti.select(touching, share, 0.0) * nrm
            count += ti.cast(touching, ti.i32)
        dx[i] = acc
        contacts_now[i] = count
        if count > 0 and changed[0] == 0:
            changed[0] = 1
    for i in range(n):
        if changed[0] != 0 and flags[i] == P.ACTIVE:
            x1[i] += dx[i]
            v1[i] += dx[i] / dt


@ti.kernel
def _overlap_stats(flags: ti.types.ndarray(), n: ti.i32, n_buckets: ti.i32, inv_cell: float, bits: ivec3,
                   starts: ti.types.ndarray(), entries: ti.types.ndarray(), sorted_xr: ti.types.ndarray(),
                   # outputs
                   stats: ti.types.ndarray()):
    """Per particle (max, sum, count) of its overlaps relative to the smaller radius of each
    pair, straight from the sorted grid (the host reduces them: no atomics per pair)."""
    for slot in range(starts[n_buckets]):
        own = sorted_xr[slot]
        home = cell_of(own.xyz, inv_cell)
        worst = 0.0
        total = 0.0
        count = 0
        for q in range(QUERY_RANGES):
            begin, end = query_range(home, q, bits, starts)
            for k in range(begin, end):
                other = sorted_xr[k]
                overlap = (own.w + other.w - (own.xyz - other.xyz).norm()) / ti.min(own.w, other.w)
                if k != slot and overlap > 0.0:
                    worst = ti.max(worst, overlap)
                    total += overlap
                    count += 1
        stats[entries[slot]] = vec3(worst, total, count)
    for i in range(n):
        if flags[i] != P.ACTIVE:
            stats[i] = vec3(0.0, 0.0, 0.0)


FORCE_BATCH = 16  # touching neighbours collected before their forces are computed


@ti.func
def tangential_spring(spring: vec3, nrm: vec3, vt: vec3, fn, stiff, damp, ratio, dt, static_friction,
                      kinetic_friction, viscous_friction):
    """Coulomb friction with a tangential spring (Cundall and Strack), PHYSICS.md 4's static
    friction held by the contact's own displacement: `spring` is the tangential displacement
    the contact has accumulated since it formed (zero for a new contact), projected onto
    the tangent plane of the current normal nrm and stretched by dt vt. (The contact plane
    turns by a small angle a per substep, and the projection shortens the spring by 1 -
    cos(a), second order in a; turning it with its length kept cost a square root and a
    division per contact: 8 % of the spinning pile's substep, measured.) The
    force -k_t spring - D_t vt (k_t = ratio k_n, D_t = ratio D_n) holds while it is at most
    mu_s f_n; beyond, the contact slides: kinetic friction mu_k f_n (plus the wet term
    mu_v f_n |vt|) along the same direction, and the spring is cut back to the length that
    gives that force. Every step is odd in (nrm, vt, spring), so the two particles of a
    pair, which each keep the pair's spring, see exactly opposite springs and forces.
    Returns (force, spring)."""
    spring = spring - spring.dot(nrm) * nrm + dt * vt
    kt = ratio * stiff
    dt_damp = ratio * damp
    force = -kt * spring - dt_damp * vt
    limit = static_friction * fn
    if force.norm_sqr() > limit * limit:
        slide = (kinetic_friction + viscous_friction * vt.norm()) * fn
        force *= slide / force.norm()
        spring = -(force + dt_damp * vt) / ti.max(kt, 1e-30)
    return force, spring


class _History:
    """One set of the tangential springs' arrays, as the force kernel reads and writes them:
    count[i] springs of particle i, partner[i, h] the public id of the particle the spring
    h touches, spring[i, h] its tangential displacement, roll[i, h] its rolling spring
    (rotation only)."""

    def __init__(self, count, partner, spring, roll):
        self.count, self.partner, self.spring, self.roll = count, partner, spring, roll


# What the DEM force kernel hands to `_batch_forces` (a tuple, so that the kernel can keep it
# in a compile-time name): the particles' velocities, masses, public ids and (rotation) spins,
# the contact constants (PenaltySolver.kernel_constants), the material's friction, the springs'
# ratio and sets (old, new: _History) with their overflow counter, the static switches (springs,
# rotation, listed) and the arrays the neighbours are read from (the store's x and radius if
# listed, else the grid's entries and sorted copy).
_DEM = collections.namedtuple("_DEM", "v mass ids spin dt stiffness per_mass damping is_ratio static_friction "
                              "kinetic_friction viscous_friction ratio rolling_friction old new history_overflow "
                              "springs rotation listed x radius entries sorted_xr")


@ti.func
def _pair_inertia(mass: ti.template(), i, j, ri, rj):
    """The pair's reduced moment of inertia 1 / (1/I_i + 1/I_j), I = 2/5 m r^2."""
    inertia_i = SPHERE_INERTIA * mass[i] * ri * ri
    inertia_j = SPHERE_INERTIA * mass[j] * rj * rj
    return inertia_i * inertia_j / (inertia_i + inertia_j)


@ti.func
def _regularised(vt: vec3, w_roll: vec3, fn, m_t, lever, i, j, ri, rj, law: ti.template()):
    """Friction without springs: the regularised force on the contact points' slip vt (mass
    m_t), and with rotation the capped torque against the relative rolling w_roll (rolling
    radius `lever`). Returns (force, rolling torque)."""
    force = friction_force(vt, fn, m_t, law.dt, law.static_friction, law.kinetic_friction, law.viscous_friction)
    roll_torque = vec3(0.0, 0.0, 0.0)
    if ti.static(law.rotation):
        roll_torque = rolling_torque(w_roll, fn, lever, _pair_inertia(law.mass, i, j, ri, rj), law.dt,
                                     law.rolling_friction)
    return force, roll_torque


@ti.func
def _batch_forces(i, own: vec4, batch: ti.template(), count, law: ti.template(), kept, carried):
    """The summed DEM forces and torques on particle i (position and radius `own`) from the
    touching neighbours batch[0..count): slots of the sorted grid, or with law.listed the
    neighbours' indices in the store. law: a _DEM. springs: tangential springs, i's `kept`
    springs of the last substep read from law.old, this substep's written to law.new from
    index `carried` on (with rotation, the rolling springs likewise). Returns (force,
    torque, springs written so far)."""
    total = vec3(0.0, 0.0, 0.0)
    torque = vec3(0.0, 0.0, 0.0)
    for m in range(count):
        k = batch[m]
        j = k
        other = vec4(0.0, 0.0, 0.0, 0.0)
        if ti.static(law.listed):
            other = vec4(law.x[k], law.radius[k])
        else:
            j = law.entries[k]
            other = law.sorted_xr[k]
        nrm, dist = pair_normal(own.xyz, other.xyz, i, j)
        m_pair = law.mass[i] * law.mass[j] / (law.mass[i] + law.mass[j])
        stiff, damp = contact_constants(m_pair, law.stiffness, law.per_mass, law.damping, law.is_ratio)
        v_rel = law.v[i] - law.v[j]
        vn = v_rel.dot(nrm)
        overlap = own.w + other.w - dist
        fn = spring_damper(overlap, vn, stiff, damp)
        total += fn * nrm
        vt = v_rel - vn * nrm
        # the mass a tangential force at the contact sees: the reduced mass, 2/7 of it when the
        # particles spin (1/m_t = sum over both of 1/m + r^2/I, I = 2/5 m r^2)
        m_t = m_pair
        w_roll = vec3(0.0, 0.0, 0.0)
        lever = 0.0  # the rolling radius r_i r_j / (r_i + r_j), with rotation
        # levers from the centres to the contact point, the middle of the overlap: they add up to
        # the distance, so the pair's torques and the moment of its forces cancel (angular
        # momentum is kept)
        arm_i = own.w - 0.5 * overlap
        if ti.static(law.rotation):
            # slip of i's contact point (-arm_i n) against j's (+arm_j n)
            vt += nrm.cross(arm_i * law.spin[i] + (other.w - 0.5 * overlap) * law.spin[j])
            m_t = m_pair * (SPHERE_INERTIA / (1.0 + SPHERE_INERTIA))
            w_rel = law.spin[i] - law.spin[j]
            w_roll = w_rel - w_rel.dot(nrm) * nrm
            lever = own.w * other.w / (own.w + other.w)
        force = vec3(0.0, 0.0, 0.0)
        roll_torque = vec3(0.0, 0.0, 0.0)
        if ti.static(law.springs):
            partner = law.ids[j]
            spring = vec3(0.0, 0.0, 0.0)
            roll = vec3(0.0, 0.0, 0.0)
            found = -1
            for h in range(kept):
                if law.old.partner[i, h] == partner:
                    found = h
            if found >= 0:
                spring = law.old.spring[i, found]
                if ti.static(law.rotation):
                    roll = law.old.roll[i, found]
            if found >= 0 or carried < HISTORY:
                force, spring = tangential_spring(spring, nrm, vt, fn, stiff, damp, law.ratio, law.dt,
                                                  law.static_friction, law.kinetic_friction, law.viscous_friction)
                if ti.static(law.rotation):
                    # rolling resistance by a spring on the relative rotation since the contact
                    # formed, k_r = k_t r^2, capped at mu_r r |f_n| (Cundall-Strack's law again)
                    roll_torque, roll = tangential_spring(roll, nrm, w_roll, lever * fn, lever * lever * stiff,
                                                          lever * lever * damp, law.ratio, law.dt,
                                                          law.rolling_friction, law.rolling_friction, 0.0)
            else:  # a new contact and no room to remember it: regularised friction
                force, roll_torque = _regularised(vt, w_roll, fn, m_t, lever, i, j, own.w, other.w, law)
            if carried < HISTORY:
                law.new.partner[i, carried] = partner
                law.new.spring[i, carried] = spring
                if ti.static(law.rotation):
                    law.new.roll[i, carried] = roll
                carried += 1
            else:
                ti.atomic_add(law.history_overflow[0], 1)
        else:
            force, roll_torque = _regularised(vt, w_roll, fn, m_t, lever, i, j, own.w, other.w, law)
        total += force
        if ti.static(law.rotation):
            # the tangential force acts at i's contact point -arm_i n: torque (-arm_i n) x f
            torque += arm_i * force.cross(nrm) + roll_torque
    return total, torque, carried


@ti.func
def _gather(i, own: vec4, batch: ti.template(), touching, handle, other: vec4, skip, law: ti.template(), kept,
            carried, total: vec3, turn: vec3):
    """One candidate neighbour of particle i (at `other`: position and radius; skip: nonzero
    for i itself) into the batch, without branches (which candidates touch is not
    predictable): written at the batch's end, which only a touching one advances. A full
    batch (rare: many small neighbours) is emptied into total and turn by `_batch_forces`.
    Returns (touching, carried, total, turn)."""
    reach = own.w + other.w
    batch[touching] = handle
    touching += ti.cast((skip == 0) & ((own.xyz - other.xyz).norm_sqr() < reach * reach), ti.i32)
    if touching == FORCE_BATCH:
        part, twist, carried = _batch_forces(i, own, batch, touching, law, kept, carried)
        total += part
        turn += twist
        touching = 0
    return touching, carried, total, turn


@ti.kernel
def _pair_forces(listed: ti.template(), v: ti.types.ndarray(), mass: ti.types.ndarray(),
                 flags: ti.types.ndarray(), n: ti.i32,
                 # the grid (listed: the store's positions, radii and the neighbour lists instead)
                 n_buckets: ti.i32, inv_cell: float, bits: ivec3, starts: ti.types.ndarray(),
                 entries: ti.types.ndarray(), sorted_xr: ti.types.ndarray(), x: ti.types.ndarray(),
                 radius: ti.types.ndarray(), neighbours: ti.types.ndarray(), neighbour_count: ti.types.ndarray(),
                 dt: float, stiffness: float, per_mass: ti.i32, damping: float, is_ratio: ti.i32,
                 static_friction: float, kinetic_friction: float, viscous_friction: float, springs: ti.template(),
                 ratio: float, ids: ti.types.ndarray(), rotation: ti.template(), spin: ti.types.ndarray(),
                 rolling_friction: float,
                 # springs only (roll: with rotation too): last substep's
                 count: ti.types.ndarray(), partner: ti.types.ndarray(), spring: ti.types.ndarray(),
                 roll: ti.types.ndarray(),
                 # outputs: this substep's springs (springs only), forces and (rotation) torques
                 count2: ti.types.ndarray(), partner2: ti.types.ndarray(), spring2: ti.types.ndarray(),
                 roll2: ti.types.ndarray(), history_overflow: ti.types.ndarray(), force: ti.types.ndarray(),
                 torque: ti.types.ndarray()):
    """DEM contact (PHYSICS.md 4 between two particles): a spring-damper on the overlap,
    f_n = k overlap - D (v_rel . n), only pushing, and friction bounded by mu f_n. The
    constants use the pair's reduced mass m_a m_b / (m_a + m_b), the same on both sides,
    so f_ab = -f_ba and momentum is conserved. Forces are at the substep's start, so the
    grid, sorted this substep, is queried directly, in bucket order; listed: the
    candidates are instead the neighbour lists (Verlet lists: built with a skin and kept
    while no particle has moved more than half of it, see ParticleCollisions' skin), each
    particle in the store's order. The candidates are gathered without branches into a
    small batch of touching ones (`_gather`), and the batch's forces computed in a loop of
    their own (`_batch_forces`).
    springs: friction by tangential springs (tangential_spring), each particle's springs
    carried from one substep to the next in its row of partner (the partner's public id)
    and spring, read from last substep's arrays and written with the contacts touching now
    to the other set (count2, ...; a contact that ended is forgotten).
    rotation: the particles spin (spin: angular velocities): friction acts on the slip of
    the contact points and turns both particles, and rolling resistance (rolling_friction,
    by a rolling spring per contact with springs, else rolling_torque) resists their
    relative rolling; torque[i] receives the sum."""
    law = ti.static(_DEM(v, mass, ids, spin, dt, stiffness, per_mass, damping, is_ratio, static_friction,
                         kinetic_friction, viscous_friction, ratio, rolling_friction,
                         _History(count, partner, spring, roll), _History(count2, partner2, spring2, roll2),
                         history_overflow, springs, rotation, listed, x, radius, entries, sorted_xr))
    if ti.static(listed):
        for i in range(n):
            total = vec3(0.0, 0.0, 0.0)
            turn = vec3(0.0, 0.0, 0.0)
            carried = 0
            if flags[i] == P.ACTIVE:
                own = vec4(x[i], radius[i])
                batch = ti.Vector.zero(ti.i32, FORCE_BATCH)
                touching = 0
                kept = 0
                if ti.static(springs):
                    kept = count[i]
                for e in range(neighbour_count[i]):
                    j = neighbours[i, e]
                    touching, carried, total, turn = _gather(i, own, batch, touching, j, vec4(x[j], radius[j]),
                                                             0, law, kept, carried, total, turn)
                part, twist, carried = _batch_forces(i, own, batch, touching, law, kept, carried)
                total += part
                turn += twist
            _store_forces(i, total, turn, carried, law, force, torque)
    else:
        for slot in range(starts[n_buckets]):
            i = entries[slot]
            own = sorted_xr[slot]
            home = cell_of(own.xyz, inv_cell)
            total = vec3(0.0, 0.0, 0.0)
            turn = vec3(0.0, 0.0, 0.0)
            batch = ti.Vector.zero(ti.i32, FORCE_BATCH)
            touching = 0
            kept = 0
            if ti.static(springs):
                kept = count[i]
            carried = 0
            for q in range(QUERY_RANGES):
                begin, end = query_range(home, q, bits, starts)
                for k in range(begin, end):
                    touching, carried, total, turn = _gather(i, own, batch, touching, k, sorted_xr[k], k == slot,
                                                             law, kept, carried, total, turn)
            part, twist, carried = _batch_forces(i, own, batch, touching, law, kept, carried)
            _store_forces(i, total + part, turn + twist, carried, law, force, torque)
        for i in range(n):
            if flags[i] != P.ACTIVE:
                force[i] = vec3(0.0, 0.0, 0.0)
                if ti.static(rotation):
                    torque[i] = vec3(0.0, 0.0, 0.0)


@ti.func
def _store_forces(i, total: vec3, turn: vec3, carried, law: ti.template(), force: ti.template(),
                  torque: ti.template()):
    """Particle i's summed force and (rotation) torque, and (springs) how many springs it wrote."""
    if ti.static(law.springs):
        law.new.count[i] = carried
    force[i] = total
    if ti.static(law.rotation):
        torque[i] = turn


class ParticleCollisions:
    """Settings and work arrays of particle-particle collisions (see `Scene.enable_particle_collisions`).

    material: restitution and friction between particles (tc.Material).
    method: "gauss-seidel" (default) or "jacobi": how the passes visit the pairs (see the
        module's notes).
    iterations: contact passes per substep (default 1 Gauss-Seidel, 4 Jacobi); more resolve
        piles better, cost more.
    projection_iterations: position passes removing remaining overlap (default 2
        Gauss-Seidel, 4 Jacobi).
    relaxation: over-relaxation of the contact and projection passes (1: none; up to 2;
        default 1 Gauss-Seidel, 1.5 Jacobi).
    margin: extra reach of the neighbour lists, as a fraction of the largest radius, so
        contacts created while the passes move particles are still seen (the passes move a
        particle by at most dt times its change of velocity; a contact missed in one substep
        is found in the next). Larger margins cost time: every listed neighbour is
        evaluated in every pass.
    skin: further reach of the lists (a fraction of the largest radius) so that they can be
        kept from one substep to the next (Verlet lists): they are rebuilt only once some
        particle's candidate position has moved more than skin / 2 from where the lists saw
        it (or a particle's status changed, or the store was written), so every pair within
        the margin is still listed. Pays where every particle is nearly still; where a few
        keep moving (a pile still settling) the lists are rebuilt anyway and every pass
        evaluates the longer lists. 0 (default): rebuilt every substep.
        Penalty (DEM) pairs: with a skin the force kernel reads lists of the pairs within
        r_i + r_j + skin, kept until some particle has moved skin / 2 (as above, at the
        substep's start positions), instead of querying the grid, sorted anew, every substep
        (skin 0, the default). DEM substeps are short, so the lists last many of them: on
        the benchmark pile (skin 0.2) the force substep costs about two thirds (README).
        Where a particle has more neighbours than the lists keep, the kernel queries the
        grid until they are next built (no contact is missed).
    reorder: before a rebuild of the lists (a DEM substep on the grid: every substep), at
        most every REORDER_INTERVAL builds, put the particle store in the order of the
        grid's cells (its last sort), so that neighbours lie near each other in memory: the
        passes read neighbours' data from the cache instead of all over the arrays. The
        public order (positions(), velocities(), ...) never changes.
    (The penalty variant needs no margin: its forces are evaluated once, at the substep's
    start.)
    tangential_springs: penalty (DEM) pairs only: friction by a spring per contact that
        remembers the contact's tangential displacement since it formed (Cundall and Strack;
        see tangential_spring), so static friction holds a contact still under a steady
        load, where the default regularised friction (friction_force) lets it slip by about
        dt^2 times the load's acceleration every substep: a DEM pile then creeps and keeps
        compacting. Costs HISTORY springs of memory per particle (196 B with the count,
        twice that: each substep reads last substep's set and writes the other) and about a
        quarter more kernel time per dense substep. Unless the solver spins particles
        (PenaltySolver(rotation=True)) nothing rolls, and static friction then holds up
        stacks real grains would topple (see the README); with spin, each contact also keeps
        a rolling spring (rolling resistance that holds, 144 B per particle more, twice with
        the second set). Default False.
    tangential_ratio: k_t / k_n and D_t / D_n of the tangential springs (default 2/7).
    """

    def __init__(self, *, material: Material | None = None, method: str = "gauss-seidel", iterations: int | None = None,
                 projection_iterations: int | None = None, relaxation: float | None = None, margin: float = 0.25,
                 skin: float = 0.0, reorder: bool = True, tangential_springs: bool = False,
                 tangential_ratio: float = TANGENTIAL_RATIO):
        if material is None:
            material = Material()
        elif not isinstance(material, Material):
            raise TypeError(f"material must be a tc.Material; got {type(material).__name__}")
        if not isinstance(reorder, (bool, np.bool_)):
            raise TypeError(f"reorder must be True or False; got {type(reorder).__name__}")
        if not isinstance(tangential_springs, (bool, np.bool_)):
            raise TypeError(f"tangential_springs must be True or False; got {type(tangential_springs).__name__}")
        if not isinstance(method, str) or method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(map(repr, METHODS))}; got {method!r}")
        self.material = material
        self.method = method
        defaults = METHODS[method]
        iterations = defaults[0] if iterations is None else iterations
        projection_iterations = defaults[1] if projection_iterations is None else projection_iterations
        relaxation = defaults[2] if relaxation is None else relaxation
        self.iterations = validate.integer("iterations", iterations, low=1)
        self.projection_iterations = validate.integer("projection_iterations", projection_iterations, low=0)
        self.relaxation = validate.real("relaxation", relaxation, low=0.0, high=2.0, low_open=True)
        self.margin = validate.real("margin", margin, low=0.0)
        self.skin = validate.real("skin", skin, low=0.0)
        self.reorder = bool(reorder)
        self.tangential_springs = bool(tangential_springs)
        self.tangential_ratio = validate.real("tangential_ratio", tangential_ratio, low=0.0, low_open=True)
        self.history = None  # the springs' arrays (count, partner ids, springs), with tangential_springs
        self._history_key = None  # the store's `edits` the springs describe (growth counts as an edit)
        self._history_overflow = ti.ndarray(ti.i32, shape=1)
        self._history_overflow.fill(0)
        self.grid = HashGrid()
        self.capacity = 0
        self.list_builds = 0  # substeps that built the neighbour lists (the others reused them)
        self._lists_key = None  # what the lists were built for (see _predict_and_list)
        self._since_reorder = REORDER_INTERVAL  # substeps since the store was last reordered
        self._sorted_key = None  # the store's (edits, count) when the grid last sorted it
        self._latest_counts = None  # the array with the latest per-particle contact counts
        self._lists_complete = True  # whether the DEM lists' last build kept every neighbour
        self._dem_dropped = 0  # neighbours the DEM lists left out (the grid's queries found them)

    def _ensure(self, capacity: int):
        """Work arrays as large as the particle store (so whole-array copies line up)."""
        if capacity == self.capacity:
            return
        self.capacity = capacity
        self.x1 = ti.Vector.ndarray(3, float, shape=capacity)
        self.v1 = ti.Vector.ndarray(3, float, shape=capacity)
        self.v_start = ti.Vector.ndarray(3, float, shape=capacity)
        self.delta = ti.Vector.ndarray(3, float, shape=capacity)
        self.contacts = ti.ndarray(ti.i32, shape=capacity)
        self.listed_at = None  # allocated when a skin keeps the lists (see _predict_and_list)
        self._stand_in = ti.Vector.ndarray(4, float, shape=1)  # for listed_at without a skin
        self._stand_in_i = ti.ndarray(ti.i32, shape=1)
        self._no_lists = (ti.ndarray(ti.i32, shape=(1, 1)), self._stand_in_i)  # the DEM kernel on the grid
        # the springs' arrays without tangential springs (never read), and a torque array with rotation
        stand_in = (1, HISTORY)
        self._no_springs = (ti.ndarray(ti.i32, shape=1), ti.ndarray(ti.i32, shape=stand_in),
                            ti.Vector.ndarray(3, float, shape=stand_in), ti.Vector.ndarray(3, float, shape=stand_in))
        self.torque = None
        self.changed = ti.ndarray(ti.i32, shape=1)
        self._lists_key = None

    @property
    def forward_lists(self) -> bool:
        """Whether the neighbour lists hold each pair once (HashGrid.build's forward lists):
        what the Gauss-Seidel passes read; Jacobi's read every particle's full list."""
        return self.method == "gauss-seidel"

    def _changed(self) -> bool:
        """Whether the last pass had anything to do (a read from the device)."""
        return bool(self.changed[0])

    @property
    def neighbour_overflow(self) -> int:
        """Neighbours left out of full lists since the start, and contacts with them missed (a
        read from the device); more than NEIGHBOUR_CAPACITY particles within a particle's reach
        means particles far smaller than the largest, or a pile crushed far beyond its radii.
        (The DEM kernel's lists miss none: while they are full it queries the grid instead.)"""
        return self.grid.dropped() - self._dem_dropped

    def _sort(self, particles, x, cell_size: float):
        """The grid's counting sort of the store's particles (at positions x)."""
        query = self.grid.sort(x, particles.radius, particles.flags, particles.count, cell_size)
        self._sorted_key = (particles.edits, particles.count)
        return query

    def _reorder(self, particles):
        """Put the store in the order of the grid's last sort, if it sorted the store as it is
        (the particles have moved since, by a substep or a few: the order stays coherent),
        at most once every REORDER_INTERVAL substeps."""
        self._since_reorder += 1
        if (self.reorder and particles.count and self._since_reorder >= REORDER_INTERVAL
                and self._sorted_key == (particles.edits, particles.count)):
            particles.permute(self.grid.entries, particles.count)
            if self.history is not None and self._history_key is not None:
                # the springs move with their particles (partners are named by public id)
                rolling = self.history[3].shape[0] > 1
                _permute_history(self.grid.entries, particles.count, *self.history, rolling, *self._history_spare)
                self.history, self._history_spare = self._history_spare, self.history
                self._history_key = particles.edits
            self._since_reorder = 0

    def substep(self, scene, dt: float):
        """One substep of every particle: pairs first, then the scene's solver against colliders.
        With a penalty solver, pairs are DEM spring-dashpots: forces at the substep's start."""
        if hasattr(scene.solver, "kernel_constants"):
            self._penalty_substep(scene, dt)
        else:
            self._impulse_substep(scene, dt)

    @property
    def history_overflow(self) -> int:
        """Contacts a particle touched beyond the HISTORY whose tangential springs it keeps, summed
        over the substeps so far (a read from the device): these slid by the regularised
        friction instead."""
        return int(self._history_overflow[0])

    def _springs(self, particles, rotation: bool):
        """Fit the tangential springs' arrays (self.history: count, partner ids, tangential and,
        with rotation, rolling springs) to the store: allocated with its capacity, and
        emptied when the store was written from outside (added, moved or removed particles:
        a spring is only carried between the substeps of a run)."""
        key = particles.edits
        rolls = (particles.capacity if rotation else 1, HISTORY)
        if (self.history is None or self.history[0].shape[0] != particles.capacity
                or self.history[3].shape != rolls):
            shapes = (particles.capacity, HISTORY)
            make = lambda: (ti.ndarray(ti.i32, shape=particles.capacity), ti.ndarray(ti.i32, shape=shapes),
                            ti.Vector.ndarray(3, float, shape=shapes), ti.Vector.ndarray(3, float, shape=rolls))
            self.history, self._history_spare = make(), make()
            self._history_key = None
        if self._history_key != key:
            self.history[0].fill(0)
            self._history_key = key

    def _penalty_substep(self, scene, dt: float):
        particles = scene._particles
        n = particles.count
        self._ensure(particles.capacity)
        springs = self.tangential_springs
        rotation = scene.solver.rotation
        if springs:
            self._springs(particles, rotation)  # before the reordering, which moves them with the store
        if rotation:
            particles.enable_spin()  # (before the reordering, which moves the spins with the store)
            if self.torque is None or self.torque.shape[0] != particles.capacity:
                self.torque = ti.Vector.ndarray(3, float, shape=particles.capacity)
        listed = self.skin > 0.0 and self._dem_lists(scene, self.skin * scene._max_radius())
        if listed:
            query = (0, 1.0, ivec3(1, 1, 1), self._stand_in_i, self._stand_in_i, self._stand_in)
            lists = (self.grid.neighbours, self.grid.neighbour_count)
        else:
            if self.skin == 0.0:  # (with lists, the store is reordered when they are built)
                self._reorder(particles)
            query = self._sort(particles, particles.x, 2.0 * scene._max_radius())
            lists = self._no_lists
        history = self.history if springs else self._no_springs
        m = self.material
        torque = self.torque if rotation else self.delta
        spare = self._history_spare if springs else self._no_springs
        _pair_forces(listed, particles.v, particles.mass, particles.flags, n, *query, particles.x, particles.radius,
                     *lists, dt, *scene.solver.kernel_constants(), m.static_friction, m.friction, m.wet_friction,
                     springs, self.tangential_ratio, particles.ids, rotation,
                     particles.w if rotation else particles.v, m.rolling_friction, *history, *spare,
                     self._history_overflow, self.delta, torque)
        if springs:  # this substep's springs are the current ones
            self.history, self._history_spare = self._history_spare, self.history
        scene.solver.advance(scene, dt, 1, force=self.delta, torque=self.torque if rotation else None)

    def _dem_lists(self, scene, skin: float) -> bool:
        """The DEM kernel's Verlet lists: every pair closer than r_i + r_j + skin, built from the
        grid (at most every REORDER_INTERVAL builds after reordering the store by it) and kept
        until some particle has moved more than skin / 2 from where they saw it, or changed
        status, or the store was written. Returns whether they hold every such pair: False
        when a particle had more neighbours than the lists keep (the force kernel then queries
        the grid, sorted anew, until the next build)."""
        particles = scene._particles
        n = particles.count
        key = (particles.edits, n, skin, particles.capacity, "dem")
        if self.listed_at is None:
            self.listed_at = ti.Vector.ndarray(4, float, shape=self.capacity)
        if self._lists_key == key:
            _moved(particles.x, particles.flags, n, self.listed_at, (0.5 * skin) ** 2, self.changed)
            if not self._changed():
                return self._lists_complete
        self._reorder(particles)  # (swaps the store's arrays)
        dropped = self.grid.dropped()
        self.grid.build(particles.x, particles.radius, particles.flags, n, 2.0 * scene._max_radius() + skin, skin)
        self._sorted_key = (particles.edits, n)
        _mark_listed(particles.x, particles.flags, n, self.listed_at)
        self._lists_key = (particles.edits,) + key[1:]
        self._lists_complete = self.grid.dropped() == dropped
        self._dem_dropped += self.grid.dropped() - dropped  # (not missed: see neighbour_overflow)
        self.list_builds += 1
        return self._lists_complete

    def _predict_and_list(self, scene, dt: float, reach: float, skin: float):
        """Steps 1 and 2: the candidates, and neighbour lists of pairs within r_i + r_j + reach
        of each other at them, kept from earlier substeps while they still hold. Returns the
        array holding each particle's contact count at the candidates (for the first pass)."""
        particles = scene._particles
        n = particles.count
        key = (particles.edits, n, reach, skin, particles.capacity, self.method)
        keep = skin > 0.0
        if keep and self.listed_at is None:
            self.listed_at = ti.Vector.ndarray(4, float, shape=self.capacity)
        # without a skin the check is off and its array never read (a one-element stand-in)
        listed_at = self.listed_at if keep else self._stand_in
        rest = (n, vec3(*scene.gravity), dt, int(keep), listed_at, (0.5 * skin) ** 2, self.x1, self.v1, self.changed)
        if self._lists_key == key and keep:
            _predict(particles.x, particles.v, particles.flags, *rest)
            if not self._changed():
                return self._latest_counts
        self._reorder(particles)  # (swaps the store's arrays)
        _predict(particles.x, particles.v, particles.flags, *rest)
        self.grid.build(self.x1, particles.radius, particles.flags, n, 2.0 * scene._max_radius() + reach + skin,
                        reach + skin, forward=self.forward_lists)
        self._sorted_key = (particles.edits, n)
        if keep:
            _mark_listed(self.x1, particles.flags, n, self.listed_at)
        self._lists_key = (particles.edits,) + key[1:]
        self.list_builds += 1
        return self.grid.touching

    def _velocity_pass(self, particles, dt: float, law: tuple, elastic: bool) -> bool:
        """One velocity pass (elastic: on v(t), else a contact pass on the candidates' velocities);
        returns whether any pair approached."""
        x, mass, radius = particles.x, particles.mass, particles.radius
        grid = self.grid
        v_test = self.v_start if elastic else self.v1  # the velocities the law acts on
        if self.method == "gauss-seidel":
            # the elastic pass is not over-relaxed: an isolated pair bounces with e exactly
            gauss_seidel.velocity_pass(elastic, x, mass, radius, grid, law, 1.0 if elastic else self.relaxation, dt,
                                       self.changed, v_test, self.x1, self.v1)
        else:
            _velocity_pass(x, particles.flags, self.x1, v_test, mass, radius, particles.count, grid.neighbours,
                           grid.neighbour_count, self._counts[0], *law, self.relaxation, dt, int(elastic), self.delta,
                           self._counts[1], self.changed, self.v_start, self.v1)
        return self._passed()

    def _projection_pass(self, particles, dt: float) -> bool:
        """One projection pass; returns whether any pair overlapped."""
        mass, radius = particles.mass, particles.radius
        grid = self.grid
        if self.method == "gauss-seidel":
            gauss_seidel.projection_pass(mass, radius, grid, self.relaxation, dt, self.changed, self.x1, self.v1)
        else:
            _projection_pass(particles.flags, self.x1, mass, radius, particles.count, grid.neighbours,
                             grid.neighbour_count, self._counts[0], self.relaxation, dt, self.delta, self._counts[1],
                             self.changed, self.v1)
        return self._passed()

    def _passed(self) -> bool:
        """Whether the last pass had anything to do; a Jacobi pass that did passes its contact
        counts on to the next (see pair_share)."""
        changed = self._changed()
        if changed and self.method == "jacobi":
            self._counts.reverse()
        return changed

    def _impulse_substep(self, scene, dt: float):
        particles = scene._particles
        self._ensure(particles.capacity)
        r_max = scene._max_radius()
        m = self.material
        law = (m.restitution, m.friction, m.wet_friction, WET_LAWS["linear"])
        # 1. predict; 2. neighbours of the candidates (Jacobi: and their contact counts, which
        #    the first pass's shares use; each pass counts them for the next, into the other array)
        contacts = self._predict_and_list(scene, dt, self.margin * r_max, self.skin * r_max)
        self._counts = [contacts, self.contacts if contacts is not self.contacts else self.grid.touching]
        # 3. elastic pass on v(t)
        self.v_start.copy_from(particles.v)
        if not self._velocity_pass(particles, dt, law, elastic=True) and self.method == "jacobi":
            self._counts.reverse()  # (it counted the contacts all the same)
        #    ... and the colliders' own scheme (its elastic pass included) on the candidates
        solver = scene.solver
        solver.resolve_candidates(scene, dt, self.x1, self.v1, store_state=False)
        # 4. contact passes on the candidate velocities, e = 0, alternating with the colliders'
        #    contact passes: support from a floor reaches the top of a stack within a substep.
        #    A pass that finds no approaching pair ends the loop (the next would be the same);
        #    likewise a projection pass that finds no overlap.
        contact_law = (0.0,) + law[1:]
        for _ in range(self.iterations):
            if not self._velocity_pass(particles, dt, contact_law, elastic=False):
                break
            solver.resolve_candidates(scene, dt, self.x1, self.v1, contact_only=True, store_state=False)
        # 5. projection passes on positions
        for _ in range(self.projection_iterations):
            if not self._projection_pass(particles, dt):
                break
        if self.method == "gauss-seidel":
            # a last velocity pass at the final positions: without it, particles jammed deep in
            # a pile are thrown back and forth by the projection's velocity, towards a different
            # neighbour each substep (a jitter of period two substeps)
            gauss_seidel.settle_pass(particles.x, particles.mass, particles.radius, self.grid, law, dt,
                                     self.changed, self.x1, self.v1)
        # 6. colliders last, and the new state
        solver.resolve_candidates(scene, dt, self.x1, self.v1, contact_only=True)
        self._latest_counts = self._counts[0]

    def overlap(self, scene) -> dict:
        """Overlap between particles now, relative to the smaller radius of each pair:
        {"max": ..., "mean": ... over overlapping pairs, "pairs": count}."""
        particles = scene._particles
        n = particles.count
        query = self._sort(particles, particles.x, 2.0 * scene._max_radius())
        self._lists_key = None  # the sort replaced the buckets the lists (and their colouring) came from
        self._ensure(particles.capacity)
        _overlap_stats(particles.flags, n, *query, self.delta)
        stats = self.delta.to_numpy()[:n]
        mx = stats[:, 0].max(initial=0.0)
        total = stats[:, 1].sum(dtype=np.float64)
        pairs = stats[:, 2].sum(dtype=np.float64)
        return {"max": float(mx), "mean": float(total / pairs) if pairs else 0.0, "pairs": int(pairs // 2)}
