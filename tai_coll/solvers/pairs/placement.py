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
  overlap it is pushed into counts as placed too and no speed leaks to third particles.
  Allowances shrink every substep (each particle's by SHRINK of max_push_speed * dt, a pair's
  by twice that) and end at zero, where the pairs are back on the ordinary law. In a crowd
  (particles spawned on top of each other), position pushes from many pairs at once move
  particles into third ones by more than any pair's start overlap explains, and that overlap
  would be followed by the velocity: relative to its crowd's mean velocity, a particle leaves
  the projection passes no faster than max_push_speed, or than it entered them, and the crowd
  keeps its momentum (cap_push_velocity);
- DEM pairs (dem.py): the spring law acts on the overlap beyond the allowances, and at the end
  of each substep `separate` removes the placed part of the overlap by positions only, at most
  max_push_speed * dt a substep, one Jacobi pass so that crowds converge (coincident centres
  get a direction per pair, response.laws.coincident_axis, so a crowd spawned on one point
  spreads into a ball). The allowances then follow the overlap left, never more than half a
  particle's deepest overlap: the springs are pressed only by overlap that develops during the
  run, never by placed overlap the separation has not had time to remove (a fixed shrink, as
  for impulse pairs, pressed the springs of crowds faster than they could get apart, and the
  energy they stored threw 1,000 particles spawned on one point out at 120 m/s). An approach
  the springs do not meet (within the allowances) is stopped in the same pass. Each allowance also loses
  DEM_SHRINK of the push distance a substep where the separation does not move its particle,
  and all stay below a ceiling that comes down by DEM_CEILING of it a substep, so that they end
  where the particles cannot get apart (jammed, or too many in a closed box), the springs then
  taking the load no faster than that.
"""

import functools
import math

import taichi as ti

from ... import runtime
from ...neighbors.hash_grid import cell_of, neighbour_of, query_span, query_spans
from ...response.laws import TINY, pair_normal
from ...types import ACTIVE, ARRAY, ColliderArgs, GridArgs, ListArgs, ParticleArgs, vec3
from ..detection import BOUND_SLOT, collider_sdf

vec2 = ti.math.vec2

#: Impulse pairs: the share of max_push_speed * dt by which each particle's allowance shrinks a
#: substep.
SHRINK = 0.25
#: DEM pairs: the share of max_push_speed * dt by which a particle's allowance shrinks a
#: substep beyond the overlap the separation left it (`separate`): it ends the allowances of
#: particles the separation moves less than that, held or jammed.
DEM_SHRINK = 1.0 / 16.0
#: DEM pairs: the share of max_push_speed * dt by which the ceiling of every allowance comes
#: down a substep, from the largest one granted: no placed overlap outlasts it, even where the
#: separation keeps moving particles that cannot get apart (too many in a closed box). A pair's
#: spring is then pressed at most twice this share of the push speed faster than the pair can
#: give way, slowly enough for its load to come on as if at rest.
DEM_CEILING = 1.0 / 64.0
#: DEM pairs: allowances follow half the deepest overlap and this fraction of the radius more,
#: so that the pair that sets them stays clear of the edge where its spring-damper starts,
#: rather than on it, where the last bit of round-off (which fast math makes differ between the
#: pair's two sides) would decide whether its damper acts.
EDGE = 1e-4
#: DEM pairs: the over-relaxation of the separation's Jacobi shares (jacobi.pair_share).
DEM_RELAXATION = 1.0
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
        spans = query_spans(home, grid.bits)
        for q in range(spans):
            begin, end = query_span(home, q, spans, grid.bits, grid.starts)
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


# ---------------------------------------------------------------- impulse pairs: the crowds' cap
@ti.func
def _eligible(particles: ti.template(), i) -> bool:
    """Whether particle i may be part of a crowd: it is simulated and awake (a sleeping particle
    is immovable to the passes, and stays as it is)."""
    return (particles.flags[i] == ACTIVE) & (particles.rest[i] >= 0.0)


@ti.func
def _root(label: ti.template(), i):
    """The root of i's tree of labels (each label is at most its own index: the chains fall)."""
    r = i
    while label[r] != r:
        r = label[r]
    return r


@ti.kernel
def _crowds(particles: ParticleArgs, lists: ListArgs,
            # outputs
            label: ARRAY, member: ARRAY):
    """The crowds (see cap_push_velocity): member[i] = 1 for a particle in one, label[i] the
    smallest index in its crowd. Every listed pair of two eligible particles, at least one of
    them with an allowance, joins their trees (union-find with atomic_min: the larger root is
    hung under the smaller; where another thread hung it first, under `old`, the two trees of
    old and the smaller root are joined next). The trees depend on the threads' order, the
    labels they end with do not."""
    for i in range(particles.count):
        label[i] = i
        member[i] = ti.cast((particles.allowance[i] > 0.0) & _eligible(particles, i), ti.i32)
    for i in range(particles.count):
        if _eligible(particles, i):
            placed_i = particles.allowance[i] > 0.0
            for k in range(lists.neighbour_count[i]):
                j = neighbour_of(lists, i, k)
                if (placed_i or particles.allowance[j] > 0.0) and _eligible(particles, j):
                    member[i] = 1
                    member[j] = 1
                    a = i
                    b = j
                    while True:
                        a = _root(label, a)
                        b = _root(label, b)
                        if a == b:
                            break
                        high = ti.max(a, b)
                        low = ti.min(a, b)
                        old = ti.atomic_min(label[high], low)
                        if old == high:
                            break
                        a = old
                        b = low
    for i in range(particles.count):
        if member[i] != 0:
            label[i] = _root(label, i)


@ti.kernel
def _cap_crowds(particles: ParticleArgs, label: ARRAY, member: ARRAY, v_before: ARRAY, cap: float,
                serial: ti.template(),
                # work
                mass: ARRAY, momentum: ARRAY, kept: ARRAY, capped: ARRAY,
                # in-out
                v1: ARRAY):
    """The cap of cap_push_velocity on the crowds that `label` gives (see there). The sums over
    a crowd run in the store's order on the CPU (serial): the same sums to the bit every run.
    A crowd none of whose particles the cap slows is left as it is, to the bit."""
    for i in range(particles.count):
        mass[i] = 0.0
        momentum[i] = vec3(0.0, 0.0, 0.0)
        kept[i] = vec3(0.0, 0.0, 0.0)
        capped[i] = 0
    ti.loop_config(serialize=serial)
    for i in range(particles.count):
        c = label[i]
        if member[i] != 0:
            mass[c] += particles.mass[i]
            momentum[c] += particles.mass[i] * v1[i]
    for i in range(particles.count):  # the cap, relative to the crowd's mean velocity
        c = label[i]
        if member[i] != 0:
            mean = momentum[c] / mass[c]
            u = v1[i] - mean
            speed = u.norm()
            limit = ti.max((v_before[i] - mean).norm(), cap)
            if speed > limit:
                v1[i] = mean + u * (limit / speed)
                capped[c] = 1
    ti.loop_config(serialize=serial)
    for i in range(particles.count):
        c = label[i]
        if member[i] != 0:
            kept[c] += particles.mass[i] * v1[i]
    for i in range(particles.count):  # the momentum the cap took, back to the whole crowd
        c = label[i]
        if member[i] != 0:
            if capped[c] != 0:
                v1[i] += (momentum[c] - kept[c]) / mass[c]


class PushCap:
    """Impulse pairs: the work of cap_push_velocity, allocated when particles are first placed."""

    def __init__(self, capacity: int):
        self.v_before = ti.Vector.ndarray(3, float, shape=capacity)
        self.label = ti.ndarray(ti.i32, shape=capacity)
        self.mass = ti.ndarray(float, shape=capacity)
        self.momentum = ti.Vector.ndarray(3, float, shape=capacity)
        self.kept = ti.Vector.ndarray(3, float, shape=capacity)
        self.capped = ti.ndarray(ti.i32, shape=capacity)
        self.member = ti.ndarray(ti.i32, shape=capacity)

    def arrays(self) -> list:
        return [self.v_before, self.label, self.member, self.mass, self.momentum, self.kept, self.capped]

    def entering(self, v1):
        """Keep the velocities entering the projection passes."""
        self.v_before.copy_from(v1)


def cap_push_velocity(particles, lists, work: PushCap, cap: float, v1):
    """Impulse pairs, after the projection passes while allowances are left (docs/physics.md
    5.2.1): the pushes of a crowd's pairs add up, and the velocity follows overlap they push
    particles into. A crowd is a set of particles with allowances linked by the neighbour
    lists (`lists`, ListArgs), with the listed neighbours they pushed; relative to the crowd's
    mass-weighted mean velocity, each of its particles leaves no faster than `cap` (m/s) or than
    it entered the passes (work.v_before), whichever is more. Where that slowed any of a
    crowd's particles, the momentum it took is given back to all of them alike, which takes
    kinetic energy only (the mean of the relative velocities leaves them). v1: the velocities
    leaving the passes, capped in place. (A cap on each particle's own velocity did not keep
    momentum: a crowd of 100 spawned on one point drifted at up to a sixth of max_push_speed.)"""
    if math.isinf(cap):
        return
    args = particles.args
    _crowds(args, lists, work.label, work.member)
    _cap_crowds(args, work.label, work.member, work.v_before, cap, runtime.info().arch == "cpu", work.mass,
                work.momentum, work.kept, work.capped, v1)


# ---------------------------------------------------------------- DEM pairs: the separation
# the separation's walks over each particle's neighbours (see _visit)
_COUNT, _PUSH, _LEFT = 0, 1, 2


@ti.func
def _visit(stage: ti.template(), i, j, xi: vec3, ri, ai, particles: ti.template(), counts: ti.template(),
           dx: ti.template(), push_distance, pairs, push: vec3, brake: vec3, left: vec2):
    """Neighbour j of particle i (at xi, radius ri, allowance ai) in a walk of the separation:
    _COUNT counts i's pairs with placed overlap (`pairs`); _PUSH adds i's part of moving them
    apart (`push`) and of stopping those of them that approach within their allowances
    (`brake`, a change of velocity); _LEFT, after the move dx, keeps (i's deepest overlap, the
    most overlap the move pushed one of i's pairs into) in `left`. Returns (pairs, push,
    brake, left)."""
    rj = particles.radius[j]
    aj = particles.allowance[j]
    reach = ri + rj
    allowances = ai + aj
    nrm, dist = pair_normal(xi, particles.x[j], i, j)
    overlap = ti.max(reach - dist, 0.0)
    if ti.static(stage == _COUNT or stage == _PUSH):
        # the placed part of the overlap, what the pair's allowances cover (the spring presses the rest)
        placed = ti.min(overlap, allowances)
        if ti.static(stage == _COUNT):
            pairs += ti.cast(placed > 0.0, ti.i32)
        else:
            # the pair's share of its correction, as jacobi.pair_share's (the same on both
            # sides), at most push_distance a substep, i's part of it by inverse mass:
            # (1/m_i) / (1/m_i + 1/m_j)
            share = ti.min(1.0, DEM_RELAXATION / ti.max(counts[i], counts[j], 1))
            part = particles.mass[j] / (particles.mass[i] + particles.mass[j])
            push += (part * ti.min(share * placed, push_distance)) * nrm
            # an approach the spring does not meet (the overlap is within the allowances) is
            # stopped, a perfectly inelastic contact (it only takes energy): a particle with
            # allowance left that falls onto another is held, not let through
            vn = (particles.v[i] - particles.v[j]).dot(nrm)
            stopped = (placed > 0.0) & (overlap <= allowances) & (vn < 0.0)
            brake -= ti.select(stopped, share * part * vn, 0.0) * nrm
    if ti.static(stage == _LEFT):
        before = ti.max(reach - ((xi - dx[i]) - (particles.x[j] - dx[j])).norm(), 0.0)
        left = ti.max(left, vec2(overlap, overlap - before))
    return pairs, push, brake, left


@ti.func
def _walk(stage: ti.template(), i, slot, particles: ti.template(), candidates: ti.template(), inv_cell,
          counts: ti.template(), dx: ti.template(), push_distance, listed: ti.template()):
    """A walk of the separation (see _visit) over particle i's neighbours at their current
    positions: its row of the lists (listed), or the grid's cells around the one it was sorted
    into (at `slot`) at the substep's start. Returns (pairs, push, brake, left)."""
    xi = particles.x[i]
    ri = particles.radius[i]
    ai = particles.allowance[i]
    pairs = 0
    push = vec3(0.0, 0.0, 0.0)
    brake = vec3(0.0, 0.0, 0.0)
    left = vec2(0.0, 0.0)
    if ti.static(listed):
        for e in range(candidates.neighbour_count[i]):
            pairs, push, brake, left = _visit(stage, i, neighbour_of(candidates, i, e), xi, ri, ai, particles, counts,
                                              dx, push_distance, pairs, push, brake, left)
    else:
        home = cell_of(candidates.sorted_xr[slot].xyz, inv_cell)
        spans = query_spans(home, candidates.bits)
        for q in range(spans):
            begin, end = query_span(home, q, spans, candidates.bits, candidates.starts)
            for k in range(begin, end):
                if k != slot:
                    pairs, push, brake, left = _visit(stage, i, candidates.entries[k], xi, ri, ai, particles,
                                                      counts, dx, push_distance, pairs, push, brake, left)
    return pairs, push, brake, left


@ti.func
def off_colliders(c: ti.template(), groups: ti.template(), x: vec3, r, dx: vec3) -> vec3:
    """The move dx of a particle at x (radius r) less its part into the colliders it would
    touch at x + dx (their poses at the substep's end): the separation does not push particles
    into walls, whose springs would throw them back out."""
    for ci in range(c.count):
        if (x + dx - c.center1[ci]).norm() - c.params[ci][BOUND_SLOT] < r:
            phi, n = collider_sdf(c, groups, ci, x + dx, True, r)
            if phi < r:
                dx -= ti.min(dx.dot(n), 0.0) * n
    return dx


@ti.func
def _slots(particles: ti.template(), candidates: ti.template(), listed: ti.template()):
    """How many slots the walks go over: the store's particles (listed), or the grid's
    entries (the active particles)."""
    n = particles.count
    if ti.static(not listed):
        n = candidates.starts[candidates.n_buckets]
    return n


@ti.func
def _particle_at(slot, candidates: ti.template(), listed: ti.template()):
    """The particle at a slot of the walks (see _slots)."""
    i = slot
    if ti.static(not listed):
        i = candidates.entries[slot]
    return i


@functools.cache
def separation_kernel(listed: bool):
    """The DEM separation's kernel (see `separate`) for candidates from Verlet lists (listed:
    ListArgs) or from the grid sorted at the substep's start (GridArgs, with inv_cell)."""
    CandidatesType = ListArgs if listed else GridArgs

    @ti.kernel
    def separation(particles: ParticleArgs, candidates: CandidatesType, inv_cell: float, colliders: ColliderArgs,
                   groups: ti.template(), push_distance: float, shrink: float, ceiling: float,
                   # work
                   counts: ARRAY, dx: ARRAY, dv: ARRAY,
                   # outputs
                   largest: ARRAY):
        n = _slots(particles, candidates, listed)
        for slot in range(n):
            i = _particle_at(slot, candidates, listed)
            placed_pairs, _push, _brake, _left = _walk(_COUNT, i, slot, particles, candidates, inv_cell, counts,
                                                       dx, push_distance, listed)
            counts[i] = placed_pairs
        for slot in range(n):
            i = _particle_at(slot, candidates, listed)
            _pairs, push, brake, _left = _walk(_PUSH, i, slot, particles, candidates, inv_cell, counts, dx,
                                               push_distance, listed)
            dv[i] = brake
            # however many pairs push it, a particle moves at most push_distance
            move = push * ti.min(1.0, push_distance / ti.max(push.norm(), TINY))
            dx[i] = off_colliders(colliders, groups, particles.x[i], particles.radius[i], move)
        for i in range(particles.count):
            if particles.flags[i] == ACTIVE:
                particles.x[i] += dx[i]
                particles.v[i] += dv[i]
            else:
                dx[i] = vec3(0.0, 0.0, 0.0)
                particles.allowance[i] = 0.0  # (frozen: out of the pairs)
        for slot in range(n):
            i = _particle_at(slot, candidates, listed)
            _pairs, _push, _brake, left = _walk(_LEFT, i, slot, particles, candidates, inv_cell, counts, dx,
                                                push_distance, listed)
            # the overlap the move pushed a pair into is placed too (half of it on each side);
            # never more than half the deepest overlap left (and EDGE), nor the ceiling
            kept = ti.max(ti.min(particles.allowance[i] + 0.5 * ti.max(left[1], 0.0) - shrink,
                                 0.5 * left[0] + EDGE * particles.radius[i], ceiling), 0.0)
            particles.allowance[i] = kept
            ti.atomic_max(largest[0], kept)

    return separation


def separate(world, candidates, inv_cell: float, listed: bool, push_distance: float, shrink: float,
             ceiling: float, counts, dx, dv, work) -> float:
    """DEM pairs, at the end of a substep while allowances are left (docs/physics.md 5.2.1).
    The placed part of every pair's overlap (what its two allowances cover; the spring presses
    the rest) is removed by moving positions only: one Jacobi pass with the shares of
    jacobi.pair_share, so that a crowd converges, at most push_distance (m) of a pair's a
    substep, split by inverse mass, each particle moved at most push_distance and not into a
    collider. In the same pass, pairs that approach with their overlap within the allowances
    (which the spring does not meet) are stopped, perfectly inelastic (the only change of
    velocity). Then every allowance follows the overlap left: half the overlap the move pushed
    one of its pairs into is added, `shrink` (m) taken off, and it is at most half the
    particle's deepest overlap (what each side of a pair needs; EDGE of its radius more) and
    `ceiling` (m). So the springs are pressed by overlap that developed during the run, not
    by overlap the separation has not had time to remove. candidates: the neighbour lists
    (listed) or the grid sorted at the substep's start (inv_cell: its inverse cell size);
    counts (i32), dx, dv (vectors): work arrays as large as the store; work: a one-element
    array. Returns the largest allowance left."""
    work.fill(0)
    colliders = world.colliders
    separation_kernel(listed)(particles=world.particles.args, candidates=candidates, inv_cell=inv_cell,
                              colliders=colliders.args, groups=colliders.groups, push_distance=push_distance,
                              shrink=shrink, ceiling=ceiling, counts=counts, dx=dx, dv=dv, largest=work)
    return float(work[0])
