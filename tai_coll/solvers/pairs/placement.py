"""Overlap particles were placed with (docs/physics.md 5.2.1): spawned overlapping, added onto
others, moved onto others by set_positions. It is an error of position, not a collision, and
must not turn into speed.

When particles are placed, each is given an overlap allowance (m): at least half its deepest
overlap with a neighbour where either of the two was placed (overlap deeper than SLOP of the
pair's reach), so a pair's two allowances add up to at least its overlap. While a pair has one:
- impulse pairs (gauss_seidel.py, jacobi.py): the projection removes the overlap the pair had at
  the start of the substep by moving the candidates only, at most max_push_speed * dt a
  substep; the velocity does not follow it (the start positions stay, so the colliders still
  check the whole path from them). A particle moved so gains that much allowance, so that
  overlap it is pushed into counts as placed too and no speed leaks to third particles;
- DEM pairs (dem.py): the spring law acts on the overlap beyond the allowances.
Allowances shrink every substep (each particle's by SHRINK of max_push_speed * dt, a pair's by
twice that) and end at zero, where the pairs are back on the ordinary law.
In a crowd (particles spawned on top of each other), position pushes from many pairs at once
move particles into third ones by more than any pair's start overlap explains, and that overlap
would be followed by the velocity: a particle with an allowance leaves the projection passes
no faster than max_push_speed, or than it entered them (cap_push_velocity).
"""

import taichi as ti

from ...neighbors.hash_grid import QUERY_RANGES, cell_of, query_range
from ...types import ARRAY, GridArgs, ParticleArgs

#: The share of max_push_speed * dt by which each particle's allowance shrinks a substep.
SHRINK = 0.25
#: Overlap up to this fraction of r_i + r_j gets no allowance: resting contacts moved together
#: (a stack moved by set_positions) keep their ordinary law; a spawn that shallow leaves at most
#: SLOP (r_i + r_j) / dt.
SLOP = 0.01


@ti.func
def placed_overlap(overlap, reach, x_i, x_j, allowance_sum, push_distance):
    """A projection's split of a pair's overlap at the candidates (`overlap`, m) while
    allowances are left: (what it removes this substep, how much of that the velocity follows).
    x_i, x_j: the start positions; allowance_sum: the pair's two allowances. Overlap the pair had
    at the start goes by positions only, push_distance of it this substep, and only if the pair
    has an allowance; overlap that developed since is followed as usual."""
    before = ti.select(allowance_sum > 0.0, ti.max(reach - (x_i - x_j).norm(), 0.0), 0.0)
    separate = overlap - ti.max(before - push_distance, 0.0)
    return separate, ti.min(ti.max(overlap - before, 0.0), separate)


@ti.kernel
def _grant_allowances(grid: GridArgs, inv_cell: float, placed_from: ti.i32,
                      # in-out
                      allowance: ARRAY,
                      # outputs
                      largest: ARRAY):
    """Each particle's overlap allowance: at least half its deepest overlap with a neighbour
    where either of the two was placed (storage slot >= placed_from), so that a pair placed
    overlapping has allowances adding up to at least its overlap; largest[0]: the largest."""
    for slot in range(grid.starts[grid.n_buckets]):
        own = grid.sorted_xr[slot]
        i = grid.entries[slot]
        home = cell_of(own.xyz, inv_cell)
        worst = 0.0
        for q in range(QUERY_RANGES):
            begin, end = query_range(home, q, grid.bits, grid.starts)
            for k in range(begin, end):
                j = grid.entries[k]
                other = grid.sorted_xr[k]
                if k != slot and (i >= placed_from or j >= placed_from):
                    depth = own.w + other.w - (own.xyz - other.xyz).norm()
                    if depth > SLOP * (own.w + other.w):
                        worst = ti.max(worst, depth)
        if worst > 0.0:
            granted = ti.max(allowance[i], 0.5 * worst)
            allowance[i] = granted
            ti.atomic_max(largest[0], granted)


@ti.kernel
def _shrink_allowances(n: ti.i32, amount: float,
                       # in-out
                       allowance: ARRAY,
                       # outputs
                       largest: ARRAY):
    for i in range(n):
        left = ti.max(allowance[i] - amount, 0.0)
        allowance[i] = left
        ti.atomic_max(largest[0], left)


def grant_allowances(grid, n: int, placed_from: int, allowance, work) -> float:
    """Give the particles the grid has just sorted their overlap allowances (see
    _grant_allowances); work: a one-element array. Returns the largest allowance granted."""
    work.fill(0)
    _grant_allowances(grid=grid.args, inv_cell=grid.inv_cell, placed_from=placed_from, allowance=allowance,
                      largest=work)
    return float(work[0])


def shrink_allowances(n: int, amount: float, allowance, work) -> float:
    """Every allowance less `amount` (m), down to zero; work: a one-element array. Returns the
    largest allowance left."""
    work.fill(0)
    _shrink_allowances(n, amount, allowance, work)
    return float(work[0])


@ti.kernel
def cap_push_velocity(particles: ParticleArgs, v_before: ARRAY, cap: float,
                      # in-out
                      v1: ARRAY):
    """A particle with an overlap allowance leaves the projection passes no faster than `cap`
    (m/s) or than it entered them (v_before), whichever is more: the rest of its separation
    goes by positions only. (Capping what one substep adds would let a crowd's pushes add up
    over the substeps.)"""
    for i in range(particles.count):
        if particles.allowance[i] > 0.0:
            speed = v1[i].norm()
            limit = ti.max(v_before[i].norm(), cap)
            if speed > limit:
                v1[i] = v1[i] * (limit / speed)
