"""Shock propagation for piles of particles of very different masses (docs/physics.md 5.3.2).

Gauss-Seidel splits each pair's correction by inverse mass. Where a heavy particle rests on a
light one that rests on a floor, the light one takes nearly all of each correction, into the
floor; the floor pushes it back out; the heavy one moves by m_light / m_heavy of the overlap
per pass and sinks through (a 1e3 kg particle on a 1e-6 kg one ends with their centres
0.03 mm apart). Passes enough to converge would number in the mass ratio.

Shock propagation (after Guendelman, Bridson and Fedkiw 2003) gives each particle a support
level at the end of the substep's passes: 0 where it rests on a collider (touching one whose
outward normal points up, against gravity), k + 1 where it rests on a particle of level k (its
neighbour's centre lies below its own, within SUPPORT_COS of straight down), NO_SUPPORT
otherwise. Further projection passes and the settle pass then treat the lower level of a pair
as immovable: the upper particle takes the pair's whole correction, as it would from a floor.
Pairs of equal level (neighbours within a layer, or particles in flight) split by inverse mass
as before, so momentum is kept wherever no support is involved.

It runs only where masses differ by more than SHOCK_MASS_RATIO (piles of one mass settle
without it: docs/design-notes.md) and gravity is not zero (no up, no support).

DEM pairs (docs/physics.md 5.4) carry loads by their springs, and a spring on a light
particle cannot hold a heavy one (it would need a stiffness no explicit step of the light
particle's mass keeps stable). Under the same condition, after each DEM substep, `limit_passes`
removes the overlap of every pair beyond DEM_OVERLAP_LIMIT of the smaller radius by
positions, and stops such pairs' approach (inelastic), the lower support level of the pair
immovable: the spring keeps its law up to the limit, and nothing sinks through.
"""

import taichi as ti

from ...neighbors.hash_grid import neighbour_of
from ...response.laws import pair_normal
from ...types import ACTIVE, ARRAY, ColliderArgs, ListArgs, ParticleArgs, host_vector, vec3
from ..detection import collider_sdf
from .placement import off_colliders
from .sleeping import shares

# Particles whose masses differ by more than this ratio get shock propagation.
SHOCK_MASS_RATIO = 10.0
# A neighbour supports a particle when the direction from its centre to the particle's is
# within acos(SUPPORT_COS) (about 75 degrees) of up; a collider supports one when its outward
# normal is.
SUPPORT_COS = 0.25
# Contact for support: within this fraction of the radius (collider) or of r_i + r_j (pair)
# beyond touching (the passes leave resting contacts at touching, give or take round-off).
SUPPORT_TOUCH = 1e-2
NO_SUPPORT = 1 << 30
# Passes of the level propagation at most (each adds one level; a pile deeper than this many
# particles has its upper part unsupported, which is the plain split by mass).
MAX_LEVEL_PASSES = 64
# Shock projection passes at most (each pair resolved with its lower particle fixed; a pass
# that finds no overlap ends them).
SHOCK_PASSES = 16
#: DEM pairs with masses that differ by more than SHOCK_MASS_RATIO under gravity: the most a
#: pair may overlap, as a fraction of its smaller radius; beyond it, limit_passes removes the
#: rest. (A heavy particle resting on a light one stays within 2.5 % of the light one's radius
#: of touching it, and pushes it about as deep into a floor.)
DEM_OVERLAP_LIMIT = 0.025
#: limit_passes: the passes end once no pair overlaps by more than (1 + LIMIT_SLACK) times the
#: limit (each pass still removes every excess); PASSES_PER_LAUNCH of them run in one launch
#: (on the CPU a launch with the store's arrays costs more than a pass over a few thousand
#: particles).
LIMIT_SLACK = 0.1
PASSES_PER_LAUNCH = 4


@ti.kernel
def _support_from_colliders(particles: ParticleArgs, colliders: ColliderArgs, groups: ti.template(), x1: ARRAY,
                            up: vec3,
                            # outputs
                            levels: ARRAY):
    """levels[i] = 0 for an active particle touching (at its candidate x1) a collider whose
    outward normal points up, NO_SUPPORT for every other."""
    for i in range(particles.count):
        level = NO_SUPPORT
        if particles.flags[i] == ACTIVE:
            touch = particles.radius[i] * (1.0 + SUPPORT_TOUCH)
            for ci in range(colliders.count):
                phi, n = collider_sdf(colliders, groups, ci, x1[i], True, touch)
                if phi < touch and n.dot(up) > SUPPORT_COS:
                    level = 0
        levels[i] = level


@ti.kernel
def _propagate(particles: ParticleArgs, lists: ListArgs, x1: ARRAY, up: vec3,
               # outputs
               changed: ARRAY,
               # in-out
               levels: ARRAY):
    """One pass over the pairs of the lists (forward or full): a particle resting on a
    neighbour of level k gets level k + 1 if that is lower than its own. changed[0]: whether
    any did."""
    changed[0] = 0
    for i in range(particles.count):
        if particles.flags[i] == ACTIVE:
            ri = particles.radius[i]
            for k in range(lists.neighbour_count[i]):
                j = neighbour_of(lists, i, k)
                d = x1[i] - x1[j]
                touch = (ri + particles.radius[j]) * (1.0 + SUPPORT_TOUCH)
                d2 = d.norm_sqr()
                if d2 < touch * touch and d2 > 0.0:
                    height = d.dot(up) / ti.sqrt(d2)  # cosine of the angle of j -> i from up
                    below, above = j, i
                    if height < 0.0:
                        below, above = i, j
                    level = levels[below]
                    if ti.abs(height) > SUPPORT_COS and level < NO_SUPPORT and level + 1 < levels[above]:
                        ti.atomic_min(levels[above], level + 1)
                        changed[0] = 1


@ti.func
def fixed_shares(wi, wj, level_i, level_j):
    """A pair's parts (wi, wj, see sleeping.shares) with the lower support level immovable:
    the upper particle takes the whole change (none if it takes none already: asleep)."""
    si, sj = wi, wj
    if level_i < level_j:
        si, sj = 0.0, ti.select(wj > 0.0, 1.0, 0.0)
    elif level_j < level_i:
        si, sj = ti.select(wi > 0.0, 1.0, 0.0), 0.0
    return si, sj


def needed(world) -> bool:
    """Whether the scene's particles get shock propagation (Gauss-Seidel) or the DEM overlap
    limit: masses more than SHOCK_MASS_RATIO apart, under gravity."""
    lightest, heaviest = world.particles.mass_range
    return world.particles.count > 0 and heaviest > SHOCK_MASS_RATIO * lightest and any(world.gravity)


def support_levels(world, lists, x1, levels, changed) -> int:
    """Each particle's support level at the candidates x1 (the module's notes) into levels;
    returns the propagation passes it took."""
    gravity = world.gravity
    norm = sum(g * g for g in gravity) ** 0.5
    up = host_vector(-g / norm for g in gravity)
    table = world.colliders
    _support_from_colliders(world.particles.args, table.args, table.groups, x1, up, levels)
    for passes in range(1, MAX_LEVEL_PASSES + 1):
        _propagate(world.particles.args, lists, x1, up, changed, levels)
        if not changed[0]:
            return passes
    return MAX_LEVEL_PASSES


@ti.kernel
def limit_passes(particles: ParticleArgs, colliders: ColliderArgs, groups: ti.template(), lists: ListArgs,
                 levels: ARRAY, limit: float,
                 # work
                 counts: ARRAY, dx: ARRAY, dv: ARRAY,
                 # outputs
                 changed: ARRAY):
    """PASSES_PER_LAUNCH Jacobi passes over full neighbour lists (DEM pairs): every pair
    overlapping by more than `limit` of its smaller radius is moved apart by the excess, the
    lower support level immovable (fixed_shares), equal levels split by inverse mass, each
    pair's share divided by the larger count of such pairs of its two particles
    (jacobi.pair_share: a crowd converges without over-correcting), and not into a collider
    (placement.off_colliders: its spring would throw the particle back). The velocity does not
    follow the move: with DEM's small substeps, a correction over dt would be a large speed
    (a leftover of 1e-5 m in a substep of 1e-5 s is 1 m/s). Instead, the same shares stop the
    pair's approach (the normal relative velocity, inelastic: it only takes energy). Overlap
    covered by the pair's allowances (placed overlap, placement.py) is not the limit's: it goes
    by positions only. A frozen neighbour is immovable. changed[0]: whether the last pass found
    a pair beyond (1 + LIMIT_SLACK) times the limit."""
    for _ in ti.static(range(PASSES_PER_LAUNCH)):
        changed[0] = 0
        for i in range(particles.count):
            beyond = 0
            far = 0
            if particles.flags[i] == ACTIVE:
                ri = particles.radius[i]
                for k in range(lists.neighbour_count[i]):
                    j = neighbour_of(lists, i, k)
                    rj = particles.radius[j]
                    overlap = ri + rj - (particles.x[i] - particles.x[j]).norm()
                    # overlap a particle was placed with is the separation's (placement.py), by
                    # positions only: beyond the limit and the pair's allowances
                    allowed = limit * ti.min(ri, rj) + particles.allowance[i] + particles.allowance[j]
                    beyond += ti.cast(overlap > allowed, ti.i32)
                    far += ti.cast(overlap > (1.0 + LIMIT_SLACK) * allowed, ti.i32)
            counts[i] = beyond
            if far > 0 and changed[0] == 0:
                changed[0] = 1
        for i in range(particles.count):
            move = vec3(0.0, 0.0, 0.0)
            brake = vec3(0.0, 0.0, 0.0)
            if particles.flags[i] == ACTIVE and counts[i] > 0:
                ri = particles.radius[i]
                mi = particles.mass[i]
                for k in range(lists.neighbour_count[i]):
                    j = neighbour_of(lists, i, k)
                    rj = particles.radius[j]
                    nrm, dist = pair_normal(particles.x[i], particles.x[j], i, j)
                    excess = (ri + rj - dist - limit * ti.min(ri, rj)
                              - (particles.allowance[i] + particles.allowance[j]))
                    if excess > 0.0:
                        # by inverse mass; a frozen neighbour immovable, as a sleeping one is
                        wi, wj = shares(mi, particles.mass[j], False, particles.flags[j] != ACTIVE)
                        wi, wj = fixed_shares(wi, wj, levels[i], levels[j])
                        share = wi / ti.max(counts[i], counts[j], 1)
                        move += (share * excess) * nrm
                        vn = (particles.v[i] - particles.v[j]).dot(nrm)
                        brake -= (share * ti.min(vn, 0.0)) * nrm
                move = off_colliders(colliders, groups, particles.x[i], ri, move)
            dx[i] = move
            dv[i] = brake
        for i in range(particles.count):
            if particles.flags[i] == ACTIVE:
                particles.x[i] += dx[i]
                particles.v[i] += dv[i]
