"""DEM contact between particles (docs/physics.md 5): the penalty spring-damper of
docs/physics.md 4 between two particles, as forces (and, for spinning particles, torques) at
the substep's start, which the penalty solver's substep then applies with the colliders'.

f_n = k overlap - D (v_rel . n), only pushing, and friction bounded by mu f_n. The constants
use the pair's reduced mass m_a m_b / (m_a + m_b), the same on both sides, so f_ab = -f_ba and
momentum is conserved; each pair is evaluated from both sides (a gather, no atomics).
Friction is the regularised force of response/penalty.py, or with tangential springs a spring
per contact (springs.py). Spinning particles: friction acts on the slip of the two contact
points and turns both particles about the middle of the overlap, and rolling resistance
resists their relative rolling (docs/physics.md 6).

The force kernel comes in variants (`dem_force_kernel`): candidates from the hash grid,
sorted this substep and queried in bucket order, or from Verlet lists (neighbors/verlet.py);
with or without springs; for spinning particles or not. Each takes only the arrays it reads.
The candidates are gathered without branches into a small batch of touching ones
(`_gather`), and the batch's forces computed in a loop of their own (`_batch_forces`).
"""

import functools

import taichi as ti

from ...neighbors.hash_grid import cell_of, neighbour_of, query_span, query_spans
from ...response.laws import pair_normal
from ...response.penalty import SPHERE_INERTIA, friction_force, rolling_torque, spring_damper, tangential_spring
from ...types import ACTIVE, ARRAY, GridArgs, ListArgs, ParticleArgs, SpinArgs, Unused, vec3, vec4
from ..penalty import Forces, ForcesAndTorques, contact_constants
from .springs import HISTORY, RollingSprings, Springs

FORCE_BATCH = 16  # touching neighbours collected before their forces are computed


@functools.cache
def dem_law_type(precision: str):
    """The DEM law's constants as one argument pack, in the runtime's float precision: dt (s);
    stiffness, stiffness_per_mass, damping, damping_is_ratio (PenaltySolver.contact_law);
    the material's static, kinetic, viscous and rolling friction; the springs' k_t / k_n."""
    fp = ti.f64 if precision == "f64" else ti.f32
    return ti.types.argpack(dt=fp, stiffness=fp, stiffness_per_mass=ti.i32, damping=fp, damping_is_ratio=ti.i32,
                            static_friction=fp, kinetic_friction=fp, viscous_friction=fp, rolling_friction=fp,
                            tangential_ratio=fp)


@ti.func
def _pair_inertia(mass: ti.template(), i, j, ri, rj):
    """The pair's reduced moment of inertia 1 / (1/I_i + 1/I_j), I = 2/5 m r^2."""
    inertia_i = SPHERE_INERTIA * mass[i] * ri * ri
    inertia_j = SPHERE_INERTIA * mass[j] * rj * rj
    return inertia_i * inertia_j / (inertia_i + inertia_j)


@ti.func
def _regularised(vt: vec3, w_roll: vec3, fn, m_t, lever, mass: ti.template(), i, j, ri, rj, law: ti.template(),
                 spinning: ti.template()):
    """Friction without springs: the regularised force on the contact points' slip vt (mass
    m_t), and for spinning particles the capped torque against the relative rolling w_roll
    (rolling radius `lever`). Returns (force, rolling torque)."""
    force = friction_force(vt, fn, m_t, law.dt, law.static_friction, law.kinetic_friction, law.viscous_friction)
    roll_torque = vec3(0.0, 0.0, 0.0)
    if ti.static(spinning):
        roll_torque = rolling_torque(w_roll, fn, lever, _pair_inertia(mass, i, j, ri, rj), law.dt,
                                     law.rolling_friction)
    return force, roll_torque


@ti.func
def _batch_forces(i, own: vec4, batch: ti.template(), count, kept, carried, particles: ti.template(),
                  spin: ti.template(), candidates: ti.template(), ids: ti.template(), springs: ti.template(),
                  law: ti.template(), listed: ti.template(), with_springs: ti.template(), spinning: ti.template()):
    """The summed DEM forces and torques on particle i (position and radius `own`) from the
    touching neighbours batch[0..count): slots of the sorted grid (candidates: GridArgs), or
    when listed the neighbours' indices in the store (candidates: ListArgs, positions and
    radii from the store). with_springs: i's `kept` springs of the last substep are read from
    springs, this substep's written from index `carried` on (for spinning particles, the
    rolling springs likewise). Returns (force, torque, springs written so far)."""
    total = vec3(0.0, 0.0, 0.0)
    torque = vec3(0.0, 0.0, 0.0)
    for m in range(count):
        k = batch[m]
        j = k
        other = vec4(0.0, 0.0, 0.0, 0.0)
        if ti.static(listed):
            other = vec4(particles.x[k], particles.radius[k])
        else:
            j = candidates.entries[k]
            other = candidates.sorted_xr[k]
        nrm, dist = pair_normal(own.xyz, other.xyz, i, j)
        m_pair = particles.mass[i] * particles.mass[j] / (particles.mass[i] + particles.mass[j])
        stiff, damp = contact_constants(m_pair, law.stiffness, law.stiffness_per_mass, law.damping,
                                        law.damping_is_ratio)
        v_rel = particles.v[i] - particles.v[j]
        vn = v_rel.dot(nrm)
        overlap = own.w + other.w - dist
        # the spring presses only overlap beyond the pair's allowances: overlap a particle was
        # placed with goes by positions (placement.separate), its energy never stored in the
        # spring (docs/physics.md 5.2.1)
        depth = overlap - (particles.allowance[i] + particles.allowance[j])
        fn = ti.select(depth > 0.0, spring_damper(depth, vn, stiff, damp), 0.0)
        total += fn * nrm
        vt = v_rel - vn * nrm
        # the mass a tangential force at the contact sees: the reduced mass, 2/7 of it when the
        # particles spin (1/m_t = sum over both of 1/m + r^2/I, I = 2/5 m r^2)
        m_t = m_pair
        w_roll = vec3(0.0, 0.0, 0.0)
        lever = 0.0  # the rolling radius r_i r_j / (r_i + r_j), for spinning particles
        # levers from the centres to the contact point, the middle of the overlap: they add up to
        # the distance, so the pair's torques and the moment of its forces cancel (angular
        # momentum is kept)
        arm_i = own.w - 0.5 * overlap
        if ti.static(spinning):
            # slip of i's contact point (-arm_i n) against j's (+arm_j n)
            vt += nrm.cross(arm_i * spin.w[i] + (other.w - 0.5 * overlap) * spin.w[j])
            m_t = m_pair * (SPHERE_INERTIA / (1.0 + SPHERE_INERTIA))
            w_rel = spin.w[i] - spin.w[j]
            w_roll = w_rel - w_rel.dot(nrm) * nrm
            lever = own.w * other.w / (own.w + other.w)
        force = vec3(0.0, 0.0, 0.0)
        roll_torque = vec3(0.0, 0.0, 0.0)
        if ti.static(with_springs):
            partner = ids[j]
            spring = vec3(0.0, 0.0, 0.0)
            roll = vec3(0.0, 0.0, 0.0)
            found = -1
            for h in range(kept):
                if springs.partner[i, h] == partner:
                    found = h
            if found >= 0:
                spring = springs.stretch[i, found]
                if ti.static(spinning):
                    roll = springs.roll[i, found]
            if found >= 0 or carried < HISTORY:
                force, spring = tangential_spring(spring, nrm, vt, fn, stiff, damp, law.tangential_ratio, law.dt,
                                                  law.static_friction, law.kinetic_friction, law.viscous_friction)
                if ti.static(spinning):
                    # rolling resistance by a spring on the relative rotation since the contact
                    # formed, k_r = k_t r^2, capped at mu_r r |f_n| (Cundall-Strack's law again)
                    roll_torque, roll = tangential_spring(roll, nrm, w_roll, lever * fn, lever * lever * stiff,
                                                          lever * lever * damp, law.tangential_ratio, law.dt,
                                                          law.rolling_friction, law.rolling_friction, 0.0)
            else:  # a new contact and no room to remember it: regularised friction
                force, roll_torque = _regularised(vt, w_roll, fn, m_t, lever, particles.mass, i, j, own.w, other.w,
                                                  law, spinning)
            if carried < HISTORY:
                springs.next_partner[i, carried] = partner
                springs.next_stretch[i, carried] = spring
                if ti.static(spinning):
                    springs.next_roll[i, carried] = roll
                carried += 1
            else:
                ti.atomic_add(springs.overflow[0], 1)
        else:
            force, roll_torque = _regularised(vt, w_roll, fn, m_t, lever, particles.mass, i, j, own.w, other.w, law,
                                              spinning)
        total += force
        if ti.static(spinning):
            # the tangential force acts at i's contact point -arm_i n: torque (-arm_i n) x f
            torque += arm_i * force.cross(nrm) + roll_torque
    return total, torque, carried


@ti.func
def _gather(i, own: vec4, batch: ti.template(), touching, handle, other: vec4, skip, kept, carried, total: vec3,
            turn: vec3, particles: ti.template(), spin: ti.template(), candidates: ti.template(), ids: ti.template(),
            springs: ti.template(), law: ti.template(), listed: ti.template(), with_springs: ti.template(),
            spinning: ti.template()):
    """One candidate neighbour of particle i (at `other`: position and radius; skip: nonzero
    for i itself) into the batch, without branches (which candidates touch is not
    predictable): written at the batch's end, which only a touching one advances. A full
    batch (rare: many small neighbours) is emptied into total and turn by `_batch_forces`.
    Returns (touching, carried, total, turn)."""
    reach = own.w + other.w
    batch[touching] = handle
    touching += ti.cast((skip == 0) & ((own.xyz - other.xyz).norm_sqr() < reach * reach), ti.i32)
    if touching == FORCE_BATCH:
        part, twist, carried = _batch_forces(i, own, batch, touching, kept, carried, particles, spin, candidates,
                                             ids, springs, law, listed, with_springs, spinning)
        total += part
        turn += twist
        touching = 0
    return touching, carried, total, turn


@functools.cache
def dem_force_kernel(precision: str, listed: bool, with_springs: bool, spinning: bool):
    """The force kernel for candidates from Verlet lists (listed) or the grid, with tangential
    springs or not, for spinning particles or not. Its arguments: the store's pack, the
    candidates (ListArgs, or GridArgs with inv_cell), the store's public ids and the springs
    (Springs or RollingSprings) with springs, the spins (SpinArgs) for spinning particles, the
    law (dem_law_type); output: the loads (Forces, or ForcesAndTorques when spinning)."""
    CandidatesType = ListArgs if listed else GridArgs
    SpringsType = (RollingSprings if spinning else Springs) if with_springs else Unused
    SpinType = SpinArgs if spinning else Unused
    LoadsType = ForcesAndTorques if spinning else Forces
    Law = dem_law_type(precision)

    @ti.kernel
    def dem_forces(particles: ParticleArgs, candidates: CandidatesType, inv_cell: float, ids: ARRAY,
                   springs: SpringsType, spin: SpinType, law: Law,
                   # outputs
                   loads: LoadsType):
        if ti.static(listed):
            for i in range(particles.count):
                total = vec3(0.0, 0.0, 0.0)
                turn = vec3(0.0, 0.0, 0.0)
                carried = 0
                if particles.flags[i] == ACTIVE:
                    own = vec4(particles.x[i], particles.radius[i])
                    batch = ti.Vector.zero(ti.i32, FORCE_BATCH)
                    touching = 0
                    kept = 0
                    if ti.static(with_springs):
                        kept = springs.held[i]
                    for e in range(candidates.neighbour_count[i]):
                        j = neighbour_of(candidates, i, e)
                        touching, carried, total, turn = _gather(
                            i, own, batch, touching, j, vec4(particles.x[j], particles.radius[j]), 0, kept, carried,
                            total, turn, particles, spin, candidates, ids, springs, law, listed, with_springs, spinning)
                    part, twist, carried = _batch_forces(i, own, batch, touching, kept, carried, particles, spin,
                                                         candidates, ids, springs, law, listed, with_springs, spinning)
                    total += part
                    turn += twist
                _store_loads(i, total, turn, carried, springs, loads, with_springs, spinning)
        else:
            for slot in range(candidates.starts[candidates.n_buckets]):
                i = candidates.entries[slot]
                own = candidates.sorted_xr[slot]
                home = cell_of(own.xyz, inv_cell)
                total = vec3(0.0, 0.0, 0.0)
                turn = vec3(0.0, 0.0, 0.0)
                batch = ti.Vector.zero(ti.i32, FORCE_BATCH)
                touching = 0
                kept = 0
                if ti.static(with_springs):
                    kept = springs.held[i]
                carried = 0
                spans = query_spans(home, candidates.bits)
                for q in range(spans):
                    begin, end = query_span(home, q, spans, candidates.bits, candidates.starts)
                    for k in range(begin, end):
                        touching, carried, total, turn = _gather(
                            i, own, batch, touching, k, candidates.sorted_xr[k], k == slot, kept, carried, total, turn,
                            particles, spin, candidates, ids, springs, law, listed, with_springs, spinning)
                part, twist, carried = _batch_forces(i, own, batch, touching, kept, carried, particles, spin,
                                                     candidates, ids, springs, law, listed, with_springs, spinning)
                _store_loads(i, total + part, turn + twist, carried, springs, loads, with_springs, spinning)
            for i in range(particles.count):
                if particles.flags[i] != ACTIVE:
                    loads.force[i] = vec3(0.0, 0.0, 0.0)
                    if ti.static(spinning):
                        loads.torque[i] = vec3(0.0, 0.0, 0.0)

    return dem_forces


@ti.func
def _store_loads(i, total: vec3, turn: vec3, carried, springs: ti.template(), loads: ti.template(),
                 with_springs: ti.template(), spinning: ti.template()):
    """Particle i's summed force and (spinning) torque, and (springs) how many springs it wrote."""
    if ti.static(with_springs):
        springs.next_held[i] = carried
    loads.force[i] = total
    if ti.static(spinning):
        loads.torque[i] = turn
