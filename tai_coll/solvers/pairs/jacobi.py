"""Jacobi passes over particle pairs (docs/physics.md 5): every particle reads the previous
iterate, in parallel, and sums its shares of its pairs' corrections.

A plain Jacobi sum over-corrects a particle with many contacts and over-compresses piles;
each pair's share is divided by the larger of the two particles' contact counts (the same
number on both sides, so the impulses stay equal and opposite) and over-relaxed by
`relaxation`, never beyond the full share (an isolated pair gets exactly its impulse). Its
result does not depend on the order of the particles (Gauss-Seidel's does, slightly).

Each pass is one launch of two parallel loops: the sums over the neighbour lists (full
lists: every pair in both particles' rows), then their application. A pass also counts each
particle's touching neighbours, the shares of the next pass, and says in changed[0] whether
it found anything to do.
"""

import taichi as ti

from ...neighbors.hash_grid import neighbour_of
from ...response.laws import pair_normal, respond
from ...types import ACTIVE, ARRAY, ListArgs, ParticleArgs, vec3
from .placement import placed_overlap


@ti.func
def pair_share(contacts: ti.template(), i, j, relaxation):
    """The pair's share of its full correction in a Jacobi pass: relaxation over the larger
    contact count of the two (the same number on both sides), at most 1. The counts are
    those of the previous pass (the positions move little between passes)."""
    return ti.min(1.0, relaxation / ti.max(contacts[i], contacts[j], 1))


@ti.kernel
def velocity_pass(particles: ParticleArgs, lists: ListArgs, contacts: ARRAY, v_test: ARRAY, restitution: float,
                  friction: float, wet_friction: float, wet_law: ti.template(), relaxation: float, dt: float,
                  elastic: ti.i32,
                  # outputs
                  dv: ARRAY, contacts_now: ARRAY, changed: ARRAY,
                  # in-out
                  v_start: ARRAY, x1: ARRAY, v1: ARRAY):
    """One velocity pass at the candidates x1, then its result applied. dv_i = sum over
    overlapping neighbours j of particle i's share of the pair impulse from the law on the
    velocities v_test; changed[0]: whether some particle had an approaching contact (0:
    nothing is applied). Applied: v1 += dv; elastic (the law acted on v(t) = v_test =
    v_start): v_start += dv and x1 += dt dv; contact: x1 = x + dt v1, re-integrated from the
    start."""
    changed[0] = 0
    for i in range(particles.count):
        acc = vec3(0.0, 0.0, 0.0)
        mi = particles.mass[i]
        n_touching = 0
        approaching = 0
        xi = x1[i]
        ri = particles.radius[i]
        vi = v_test[i]
        for k in range(lists.neighbour_count[i]):
            # every listed neighbour is evaluated and the touching, approaching ones kept
            # (selects, no branches: which ones they are is not predictable, and without
            # branches the processor overlaps the neighbours' arithmetic)
            j = neighbour_of(lists, i, k)
            xj = x1[j]
            reach = ri + particles.radius[j]
            touching = (xi - xj).norm_sqr() < reach * reach
            nrm, dist = pair_normal(xi, xj, i, j)
            v_rel = vi - v_test[j]
            v_new, dvn = respond(v_rel, nrm, restitution, friction, wet_friction, wet_law)
            approach = touching & (dvn > 0.0)
            # i's part of the pair impulse I = (v_new - v_rel) / (1/m_i + 1/m_j): I / m_i
            part = particles.mass[j] / (mi + particles.mass[j])
            acc += ti.select(approach, pair_share(contacts, i, j, relaxation) * part, 0.0) * (v_new - v_rel)
            n_touching += ti.cast(touching, ti.i32)
            approaching += ti.cast(approach, ti.i32)
        dv[i] = acc
        contacts_now[i] = n_touching
        if approaching > 0 and changed[0] == 0:
            changed[0] = 1  # read first: a shared line, written once, not an atomic per particle
    for i in range(particles.count):
        if changed[0] != 0 and particles.flags[i] == ACTIVE:
            v1[i] += dv[i]
            if elastic:
                v_start[i] += dv[i]  # the elastic law acted on v(t): x1 += dt dv
                x1[i] += dt * dv[i]
            else:
                x1[i] = particles.x[i] + dt * v1[i]  # contact: re-integrate from the start


@ti.kernel
def projection_pass(particles: ParticleArgs, lists: ListArgs, contacts: ARRAY, relaxation: float, dt: float,
                    placed: ti.template(), push_distance: float,
                    # outputs
                    dx: ARRAY, dx_followed: ARRAY, contacts_now: ARRAY, changed: ARRAY,
                    # in-out
                    x1: ARRAY, v1: ARRAY):
    """One projection pass at the candidates x1, then its result applied. dx_i = sum over
    overlapping neighbours j of particle i's share of moving the pair apart, split by
    inverse mass; changed[0]: whether some pair had overlap to remove (0: nothing left to
    project). Applied: x1 += dx, and the velocity follows the position (as in position-based
    dynamics: a pile held apart by projection is at rest, not moving into its neighbours),
    v1 += dx / dt. With placed particles (placed: some overlap allowance is left), overlap a
    pair was placed with and still had at the start of the substep (at x) moves positions only,
    the candidates only (the velocity does not follow), by at most push_distance a
    substep: the velocity follows dx_followed, the rest (docs/physics.md 5)."""
    # the positions a pass reads are those before it: dx is applied in a second loop
    changed[0] = 0
    for i in range(particles.count):
        acc = vec3(0.0, 0.0, 0.0)
        followed = vec3(0.0, 0.0, 0.0)
        mi = particles.mass[i]
        n_touching = 0
        separating = 0
        xi = x1[i]
        ri = particles.radius[i]
        for k in range(lists.neighbour_count[i]):  # branch-free, as in velocity_pass
            j = neighbour_of(lists, i, k)
            xj = x1[j]
            reach = ri + particles.radius[j]
            nrm, dist = pair_normal(xi, xj, i, j)
            overlap = reach - dist
            touching = overlap > 0.0
            if ti.static(not placed):
                # i's part of the separation: (1/m_i) / (1/m_i + 1/m_j)
                share = pair_share(contacts, i, j, relaxation) * overlap * particles.mass[j] / (mi + particles.mass[j])
                acc += ti.select(touching, share, 0.0) * nrm
                separating += ti.cast(touching, ti.i32)
            else:
                separate, developed = placed_overlap(overlap, reach, particles.x[i], particles.x[j],
                                                     particles.allowance[i] + particles.allowance[j], push_distance)
                part = pair_share(contacts, i, j, relaxation) * particles.mass[j] / (mi + particles.mass[j])
                moving = touching & (separate > 0.0)
                acc += ti.select(moving, part * separate, 0.0) * nrm
                followed += ti.select(moving, part * developed, 0.0) * nrm
                separating += ti.cast(moving, ti.i32)
            n_touching += ti.cast(touching, ti.i32)
        dx[i] = acc
        if ti.static(placed):
            dx_followed[i] = followed
        contacts_now[i] = n_touching
        if separating > 0 and changed[0] == 0:
            changed[0] = 1
    for i in range(particles.count):
        if changed[0] != 0 and particles.flags[i] == ACTIVE:
            x1[i] += dx[i]
            if ti.static(placed):
                v1[i] += dx_followed[i] / dt
                # the rest moves the candidate only; the particle gets that much allowance, so
                # that overlap it is pushed into counts as placed too
                shift = dx[i] - dx_followed[i]
                particles.allowance[i] += shift.norm()
            else:
                v1[i] += dx[i] / dt
