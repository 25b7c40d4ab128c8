"""Graph-coloured Gauss-Seidel passes over particle pairs (docs/physics.md 5; the alternative
to the Jacobi passes of jacobi.py, and the default).

A Gauss-Seidel pass resolves one pair at a time and applies its impulse (or separation) to both
particles at once, so the next pair sees the result: support from a floor climbs a column of
particles within one pass instead of one particle per pass, and no pair's correction has to be
shared out against the others' (no over-compression, no relaxation by contact count). Each pair
is resolved once per pass, by the particle the grid sorted first (the lists hold only the
neighbours after a particle in the sorted entries: HashGrid.build(forward=True)); equal and
opposite changes split by inverse mass keep momentum (and, for positions, the centre of mass)
exactly. Every pair sees the changes of the pairs before it, also those of its own
particle's earlier pairs (summing a particle's corrections from several pairs, Jacobi-like, over-
shoots where two neighbours push it the same way: a particle wedged between others then jumps
from one side to the other every substep).

Pairs are resolved in parallel by colouring the hash grid's table (bucket coordinates: the low
bits of the cell coordinates, see hash_grid.bucket_of). A pair links particles in neighbouring
cells, so in neighbouring buckets: resolving the pairs a group of buckets owns reads and writes
particles within one bucket of the group. Two groups of one colour that are two buckets or more
apart along some axis never touch the same particle. The groups:
- on the CPU, slabs: the table cut along z (the sort's slowest axis) into an even number of
  slabs (at most MAX_SLABS, at least two buckets thick), in two colours, even and odd. A
  slab's particles are one range of the sorted entries, walked in order: memory is read as the
  sort laid it out, and the threads claim a colour's slabs one at a time from a counter.
  (Eight colours of 4 x 2 x 2-bucket units, the earlier layout, jumped through memory unit by
  unit, and Taichi's CPU loops give each thread one run of at least 512 indices, so a colour
  of fewer than 1,024 units ran on one thread: docs/design-notes.md, "Slabs".)
- on GPUs, units of 2 x 2 x 2 buckets in eight colours by the parities of the unit's
  coordinates: a unit is one thread's sequential work, so the smallest units give the most
  threads and the shortest chain of dependent pairs per colour.
The table is a power of two wide along each axis, at least 16 along x and 8 along y and z
(HashGrid): an even number of slabs or units along each, so the separation holds across its
wrap-around too. The groups of a colour run in parallel, each group's particles in sequence
(bucket order, then list order), the colours one after the other: the result does not depend
on thread timing or the thread count (it does depend on the layout, so a GPU's result differs
from the CPU's in the order pairs are met).

The colouring needs the buckets the neighbour lists were built from (HashGrid.build), unchanged.
"""

import taichi as ti

from ... import runtime
from ...neighbors.hash_grid import neighbour_of
from ...response.laws import TINY, pair_normal, respond
from ...types import ARRAY, GridArgs, ListArgs, ParticleArgs, ivec3, vec3
from .placement import placed_overlap
from .shock import fixed_shares
from .sleeping import is_asleep, shares, wake_pair

COLOURS = 8  # GPU units: the parities of their coordinates
#: The CPU's slabs: at most this many (two colours of half as many), at least two buckets thick
#: along z each. 8, 16 and 64 ran the 100k bed of tools/bench_warp.py alike (within this
#: machine's spread; measured before the threads claimed slabs); more let more threads share a
#: colour, and balance an uneven pile.
MAX_SLABS = 64
# A GPU unit's extent in buckets along x, y, z, as powers of two: 2 x 2 x 2, the smallest the
# colouring allows.
UNIT_BITS = (1, 1, 1)


#: Whether the later passes of a substep pass over quiet particles (_pass's sleep == QUIET);
#: exact, so the tests compare both ways.
QUIET_SKIP = True
#: _pass's `sleep`: 0, no particle sleeps; 1, some may; QUIET, some may and the later passes
#: pass over quiet particles.
QUIET = 2

#: Loop indices per claimer in the slab loop: Taichi 1.7 gives each CPU thread one run of at
#: least 512 indices, so a loop of threads x CLAIM_STRIDE gives every thread one run holding
#: one claimer, which takes slabs until none are left (see _pass).
CLAIM_STRIDE = 512

#: The passes' scratch (see _pass), one set per runtime, shared by every scene (none of it is
#: kept from one substep to the next, and a substep's passes run one after the other): the
#: slab loop's claiming (the CPU's thread count, `workers`, and the next slab of each colour,
#: `next`), and the quiet particles of QUIET (a byte a particle, `quiet`; woke[0]: a particle
#: woke since the elastic pass began; woke[1]: the elastic pass marked some particle quiet).
PassWork = ti.types.argpack(workers=ti.i32, next=ARRAY, quiet=ARRAY, woke=ARRAY)

_work = {}  # per runtime generation: (particles the marks hold, PassWork)


def colouring() -> dict:
    """The _pass layout for the arch Taichi runs on: slabs (their largest count) on the CPU, 0
    on GPUs, which colour units of unit_bits (see the module's notes)."""
    return dict(slabs=MAX_SLABS if runtime.info().arch == "cpu" else 0, unit_bits=UNIT_BITS)


def pass_work(capacity: int):
    """The running Taichi's PassWork, its marks for particles up to `capacity` (made once per
    runtime and grown as needed: every pass launch asks)."""
    info = runtime.info()
    held = _work.get(info.generation)
    if held is None or held[0] < capacity:
        _work.clear()
        held = _work[info.generation] = (capacity, PassWork(
            workers=ti.lang.impl.current_cfg().cpu_max_num_threads if info.arch == "cpu" else 1,
            next=ti.ndarray(ti.i32, shape=2), quiet=ti.ndarray(ti.i8, shape=max(capacity, 1)),
            woke=ti.ndarray(ti.i32, shape=2)))
    return held[1]


def _layout(capacity: int) -> dict:
    """_pass's layout and scratch arguments: colouring(), and pass_work(capacity)."""
    return dict(colouring(), work=pass_work(capacity))


@ti.func
def slab_count(bits: ivec3, slabs: ti.template()) -> ti.i32:
    """How many slabs the table of bits is cut into: one per two buckets along z, at most
    `slabs` (both powers of two, the table at least 8 buckets along z: an even count)."""
    return ti.min(1 << (bits.z - 1), slabs)


@ti.func
def slab_range(c, u, bits: ivec3, starts: ti.template(), slabs: ti.template()):
    """The entries of slab u of colour c (0: even slabs, 1: odd ones): its buckets are
    consecutive in the table, so one range of the sorted entries."""
    size = ((1 << bits.z) // slab_count(bits, slabs)) << (bits.x + bits.y)  # buckets in a slab
    first = (2 * u + c) * size
    return starts[first], starts[first + size]


@ti.func
def unit_origin(c, u, bits: ivec3, unit_bits: ti.template()) -> ti.i32:
    """The first bucket of unit u of colour c (0..7: the parities of the unit's coordinates
    along x, y, z), the unit's lowest corner."""
    unit = ivec3(unit_bits)
    parity = ivec3(c & 1, (c >> 1) & 1, (c >> 2) & 1)
    per = 1 << (bits - unit - 1)  # units of one colour along each axis
    index = ivec3(u % per.x, (u // per.x) % per.y, u // (per.x * per.y))
    corner = (2 * index + parity) << unit  # bucket coordinates
    return corner.x | (corner.y << bits.x) | (corner.z << (bits.x + bits.y))


@ti.func
def row_range(origin, r, bits: ivec3, starts: ti.template(), unit_bits: ti.template()):
    """Entries of row r of the unit at origin: its buckets along x, consecutive in the table,
    so one range of entries."""
    first = origin + ((r % (1 << unit_bits[1])) << bits.x) + ((r >> unit_bits[1]) << (bits.x + bits.y))
    return starts[first], starts[first + (1 << unit_bits[0])]


@ti.func
def may_approach(v_rel: vec3, d: vec3, d2):
    """Whether the law can change a pair with relative velocity v_rel and centre offset d
    (|d|^2 = d2): v_N = v_rel . d / |d| < 0, told without the normal's square root and
    division (most touching pairs of a resting pile are not approaching); a pair whose
    centres are within pair_normal's TINY goes on to the law (pair_normal picks its normal)."""
    return (v_rel.dot(d) < 0.0) | (d2 <= TINY * TINY)


ELASTIC, CONTACT, PROJECTION, SETTLE = 0, 1, 2, 3  # what a pass does (see _pass)
# SETTLE passes count pairs as touching up to this fraction beyond r_i + r_j (a projection
# leaves them at r_i + r_j, give or take round-off)
SETTLE_TOUCH = 1e-4


@ti.func
def _pair_shares(shock: ti.template(), particles: ti.template(), levels: ti.template(), i, j, mi, asleep_i, asleep_j):
    """i's and j's parts of the pair's change, by inverse mass (sleeping.shares; shock: the
    lower of the pair's support levels immovable, shock.fixed_shares)."""
    wi, wj = shares(mi, particles.mass[j], asleep_i != 0, asleep_j != 0)
    if ti.static(shock):
        wi, wj = fixed_shares(wi, wj, levels[i], levels[j])
    return wi, wj


@ti.func
def _particle_pairs(mode: ti.template(), placed: ti.template(), sleep: ti.template(), shock: ti.template(),
                    i, lists: ti.template(), particles: ti.template(), restitution, friction,
                    wet_friction, wet_law: ti.template(), relaxation, dt, push_distance, wake_speed, rest_speed,
                    levels: ti.template(), work: ti.template(),
                    v_test: ti.template(), x1: ti.template(), v1: ti.template()) -> ti.i32:
    """_pass's work on particle i: its pairs of the forward lists, one after the other, each
    seeing the changes of those before it (the arguments as _pass's). Returns 1 if any pair had
    something to do, else 0."""
    found = 0
    calm = 1  # (sleep == QUIET, elastic) every pair of i's so far was two sleeping particles
    ri = particles.radius[i]
    mi = particles.mass[i]
    xi = x1[i]
    vi = v_test[i]  # (projection: unused)
    moved = vec3(0.0)  # projection: i's displacement in this pass that velocity follows
    x_start = vec3(0.0)  # projection of placed particles: i's start position
    allowance_i = 0.0  # ... and its overlap allowance
    grown = 0.0  # ... and what it grows by in this pass
    own = 0  # elastic: whether i's own pairs changed its velocity in this pass
    asleep_i = 0
    if ti.static(sleep):
        asleep_i = ti.cast(is_asleep(particles, i), ti.i32)
    if ti.static(mode == PROJECTION and placed):
        x_start = particles.x[i]
        allowance_i = particles.allowance[i]
    for k in range(lists.neighbour_count[i]):
        j = neighbour_of(lists, i, k)
        asleep_j = 0
        if ti.static(sleep):
            asleep_j = ti.cast(is_asleep(particles, j), ti.i32)
            if (asleep_i & asleep_j) != 0:
                continue  # two sleeping particles: nothing to resolve, neither wakes the other
            calm = 0
        xj = x1[j]
        reach = ri + particles.radius[j]
        touch = reach * ti.static(1.0 + SETTLE_TOUCH if mode == SETTLE else 1.0)
        d = xi - xj
        d2 = d.norm_sqr()
        if ti.static(sleep):
            if ti.static(mode != PROJECTION):
                before = asleep_i | asleep_j
                asleep_i, asleep_j = wake_pair(particles, i, j, asleep_i, asleep_j, vi, v_test[j],
                                               d, d2, reach, wake_speed)
                if (asleep_i | asleep_j) != before:
                    work.woke[0] = 1  # (no quiet particle is passed over after a wake: see _pass)
        if ti.static(mode == PROJECTION and not placed):
            # without a branch: every listed pair is moved, by zero where it does not overlap (x + 0
            # is x), so the processor never guesses wrong whether a pair overlaps, which it
            # learns only at the end of the chain of the particle's pairs before it. The pass took
            # 15 % less time; the velocity passes, made the same way, took 60 % more: there most
            # touching pairs are not approaching, and with the branch they stay off the chain
            # (docs/design-notes.md, "Visiting a pair against resolving it")
            # (a pair of two sleeping particles was skipped above; the select keeps a pair's
            # arithmetic out of its particles' positions however far apart they are)
            overlaps = d2 < touch * touch
            nrm, dist = pair_normal(xi, xj, i, j)
            wi, wj = _pair_shares(shock, particles, levels, i, j, mi, asleep_i, asleep_j)
            move = ti.select(overlaps, ((reach - dist) * relaxation) * nrm, vec3(0.0))
            found |= ti.cast(overlaps, ti.i32)
            xi += wi * move
            moved += wi * move
            x1[j] = xj - wj * move
            v1[j] = v1[j] - (wj / dt) * move
        elif d2 < touch * touch and (asleep_i & asleep_j) == 0 and (
                ti.static(mode == PROJECTION) or may_approach(vi - v_test[j], d, d2)):
            nrm, dist = pair_normal(xi, xj, i, j)
            wi, wj = _pair_shares(shock, particles, levels, i, j, mi, asleep_i, asleep_j)
            if ti.static(mode == PROJECTION):
                # while a pair has an overlap allowance (one of the two was placed overlapping),
                # the overlap it had at the start of the substep (at x) is not a collision: it
                # goes by positions only, by at most push_distance a substep; what developed
                # since moves the velocities too (docs/physics.md 5.2.1)
                separate, followed = placed_overlap(reach - dist, reach, x_start, particles.x[j],
                                                    allowance_i + particles.allowance[j], push_distance)
                if separate > 0.0:
                    found = 1
                    move = (separate * relaxation) * nrm
                    push = move
                    if followed < separate:
                        # the rest moves the candidates only, not the velocities; a particle
                        # moved so gets that much allowance, so that overlap it is pushed into
                        # counts as placed too
                        push = (followed * relaxation) * nrm
                        shift = move - push
                        grown += wi * shift.norm()
                        particles.allowance[j] = particles.allowance[j] + wj * shift.norm()
                    xi += wi * move
                    moved += wi * push
                    x1[j] = xj - wj * move
                    v1[j] = v1[j] - (wj / dt) * push
            else:
                v_rel = vi - v_test[j]
                e_pair = restitution
                if ti.static(mode == SETTLE):
                    if v_rel.dot(nrm) > -rest_speed:
                        e_pair = 0.0  # (a resting contact's approach: see _pass)
                v_new, dvn = respond(v_rel, nrm, e_pair, friction, wet_friction, wet_law)
                if dvn > 0.0:
                    found = 1
                    change = (v_new - v_rel) * relaxation
                    vi += wi * change
                    vj = v_test[j] - wj * change
                    v_test[j] = vj
                    if ti.static(mode == ELASTIC):
                        own = 1
                        v1[j] = v1[j] - wj * change
                        x1[j] = xj - (dt * wj) * change
                        xi += (dt * wi) * change
                    elif ti.static(mode == CONTACT):
                        x1[j] = particles.x[j] + dt * vj
                        xi = particles.x[i] + dt * vi
    x1[i] = xi
    if ti.static(sleep == QUIET and mode == ELASTIC):
        work.quiet[i] = ti.cast(calm & asleep_i, ti.i8)
        if (calm & asleep_i) != 0 and work.woke[1] == 0:
            work.woke[1] = 1  # (some particle is quiet: the later passes look)
    if ti.static(mode == PROJECTION):
        v1[i] = v1[i] + moved / dt
        if ti.static(placed):
            particles.allowance[i] = particles.allowance[i] + grown
    elif ti.static(mode == ELASTIC):
        if own != 0:
            # (only then: with fast math the compiler may reorder v1 + (vi - v_test) and leave
            # round-off on a particle whose pairs did nothing)
            v1[i] = v1[i] + (vi - v_test[i])
            v_test[i] = vi
    else:
        v_test[i] = vi
    return found


@ti.kernel
def _pass(mode: ti.template(), placed: ti.template(), sleep: ti.template(), shock: ti.template(),
          slabs: ti.template(), unit_bits: ti.template(), work: PassWork, grid: GridArgs,
          lists: ListArgs, particles: ParticleArgs,
          restitution: float, friction: float, wet_friction: float, wet_law: ti.template(), relaxation: float,
          dt: float, push_distance: float, wake_speed: float, rest_speed: float, levels: ARRAY,
          # outputs
          changed: ARRAY,
          # in-out
          v_test: ARRAY, x1: ARRAY, v1: ARRAY):
    """One pass over the pairs of the forward neighbour lists touching at the candidates x1,
    in colour order (see the module's notes; the grid: the sort the lists were built from);
    changed[0]: whether any pair had something to do. Modes:
    ELASTIC, CONTACT: the law (restitution, Coulomb and wet friction) on the velocities v_test
        of each approaching pair, its change applied to both. ELASTIC (v_test = v(t)): the
        change added to v_test and to the candidates, v1 += dv, x1 += dt dv. CONTACT (v_test
        is v1, e = 0): v1 += dv, the candidate re-integrated, x1 = x + dt v1.
    PROJECTION: each overlapping pair moved apart along its normal, split by inverse mass,
        the velocities following the positions (v1 += dx / dt). With placed particles (placed:
        some overlap allowance is left, see collisions.py), overlap a pair was placed with and
        still had at the start of the substep moves the candidates only (the start positions x
        stay, so colliders still see the whole path), by at most push_distance a substep: no
        particle any speed. v_test unused.
    SETTLE (v_test is v1): the law (with restitution) on the velocities of the pairs touching
        at the final positions (within SETTLE_TOUCH), positions unchanged: no contact left at
        the end of the substep carries approaching velocity into the next. A pair approaching
        slower than rest_speed (twice gravity's increment a substep) is a resting contact, not
        a bounce: it gets e = 0 (docs/physics.md 5.3).
    sleep: 0, no particle sleeps; 1 or QUIET, some may be asleep (sleeping.py): a sleeping
        particle takes no part of a pair's change (sleeping.shares), two sleeping ones are
        skipped; the velocity passes (ELASTIC, CONTACT, SETTLE) wake a sleeping particle that a
        moving or just-woken one nears (sleeping.wake_pair; wake_speed: that pass's threshold),
        and record it in work.woke[0]. QUIET also: the elastic pass marks in work.quiet each
        particle that sleeps and whose listed pairs were all of two sleeping particles
        (work.woke[1]: some is), and the later passes of the substep pass over a quiet particle
        while no particle has woken since the elastic pass began (read as a group starts, and
        after each particle it resolves: groups running at once share no particle, so another
        group's wake cannot reach this group's pairs). Each of its pairs would be skipped
        anyway, so the results are the same to the bit, and a pile that mostly sleeps is walked
        once a substep instead of in every pass (docs/design-notes.md, "Quiet particles passed
        over").
    shock: the lower of a pair's support levels (shock.py; levels) is immovable.
    Writes to another particle are plain read-modify-writes (v1[j] = v1[j] - ...), not
    Taichi's `-=` on a global, which is an atomic (a compare-and-swap loop for floats on the
    CPU): the groups running at once share no particle. Divisions by the pair's mass sum are
    kept off the chain of dependent pairs (1 / (m_i + m_j) depends on the masses alone)."""
    changed[0] = 0
    work.next[0], work.next[1] = 0, 0
    if ti.static(mode == ELASTIC):
        # (the later passes pass over quiet particles only after an elastic pass that marked some
        # in this substep; every velocity pass records its wakes)
        work.woke[0], work.woke[1] = 0, 0
    # groups per colour: slabs (the CPU) or units (slabs 0: GPUs)
    groups = 1 << (grid.bits.x + grid.bits.y + grid.bits.z - unit_bits[0] - unit_bits[1] - unit_bits[2] - 3)
    if ti.static(slabs):
        groups = slab_count(grid.bits, slabs) // 2
    for c in ti.static(range(2 if slabs else COLOURS)):
        # units: one loop index a unit. Slabs: claimed one at a time by the CPU's threads from a
        # counter (a slab's cost follows its particles; the loop holds one index in CLAIM_STRIDE
        # that claims: Taichi's CPU loops hand each thread one run of at least 512 indices)
        for t in range(work.workers * CLAIM_STRIDE if ti.static(slabs) else groups):
            u = t
            if ti.static(slabs):
                u = groups
                if t % CLAIM_STRIDE == 0:
                    u = ti.atomic_add(work.next[c], 1)
            while u < groups:
                origin = 0
                if ti.static(not slabs):
                    origin = unit_origin(c, u, grid.bits, unit_bits)
                found = 0
                skipping = 0  # whether quiet particles are passed over (sleep == QUIET)
                if ti.static(sleep == QUIET and mode != ELASTIC):
                    skipping = ti.cast((work.woke[0] == 0) & (work.woke[1] != 0), ti.i32)
                for r in range(1 if ti.static(slabs) else 1 << (unit_bits[1] + unit_bits[2])):  # a unit's rows
                    begin, end = 0, 0
                    if ti.static(slabs):
                        begin, end = slab_range(c, u, grid.bits, grid.starts, slabs)
                    else:
                        begin, end = row_range(origin, r, grid.bits, grid.starts, unit_bits)
                    for slot in range(begin, end):
                        i = grid.entries[slot]
                        if ti.static(sleep == QUIET and mode != ELASTIC):
                            if skipping != 0 and work.quiet[i] != 0:
                                continue
                        found |= _particle_pairs(mode, placed, sleep, shock, i, lists, particles,
                                                 restitution, friction, wet_friction, wet_law, relaxation, dt,
                                                 push_distance, wake_speed, rest_speed, levels, work,
                                                 v_test, x1, v1)
                        if ti.static(sleep == QUIET and mode != ELASTIC and mode != PROJECTION):
                            if skipping != 0:
                                skipping = ti.cast(work.woke[0] == 0, ti.i32)
                if found != 0 and changed[0] == 0:
                    changed[0] = 1
                u = groups  # (units: done)
                if ti.static(slabs):
                    u = ti.atomic_add(work.next[c], 1)


def _sleep_mode(sleep: bool, pass_over: bool = True) -> int:
    """_pass's `sleep`: 0 while no particle may sleep; else QUIET where the pass may pass over
    quiet particles (QUIET_SKIP, and pass_over: not a pass with placed overlap or support
    levels, which walks every particle), 1 otherwise."""
    return (QUIET if QUIET_SKIP and pass_over else 1) if sleep else 0


def velocity_pass(elastic: bool, particles, grid, lists, law: dict, relaxation: float, dt: float,
                  changed, v_test, x1, v1, wake_speed: float | None = None):
    """An elastic pass (on v_test = v(t); law with restitution) or a contact pass (v_test = v1;
    law with e = 0) over the pairs of the forward lists; see _pass. particles: the store's
    pack; grid, lists: the sort and the lists built from it; law: restitution, friction,
    wet_friction and wet_law by name; wake_speed: m/s, None while no particle may sleep (with it,
    the later passes pass over quiet particles: _pass's QUIET)."""
    sleep = _sleep_mode(wake_speed is not None)
    _pass(mode=ELASTIC if elastic else CONTACT, placed=False, sleep=sleep, shock=False,
          **_layout(x1.shape[0]), grid=grid, lists=lists, particles=particles, **law, relaxation=relaxation, dt=dt,
          push_distance=0.0, wake_speed=wake_speed or 0.0, rest_speed=0.0, levels=changed,
          changed=changed, v_test=v_test, x1=x1, v1=v1)


def settle_pass(particles, grid, lists, law: dict, dt: float, changed, x1, v1, wake_speed: float | None = None,
                levels=None, rest_speed: float = 0.0):
    """A velocity pass at the final positions, positions unchanged; levels: support levels
    (shock.py) or None; rest_speed: m/s, slower approaches get e = 0; see _pass."""
    sleep = _sleep_mode(wake_speed is not None, pass_over=levels is None)
    _pass(mode=SETTLE, placed=False, sleep=sleep, shock=levels is not None, **_layout(x1.shape[0]),
          grid=grid, lists=lists, particles=particles, **law, relaxation=1.0, dt=dt, push_distance=0.0,
          wake_speed=wake_speed or 0.0, rest_speed=rest_speed, levels=changed if levels is None else levels,
          changed=changed, v_test=v1, x1=x1, v1=v1)


def projection_pass(particles, grid, lists, relaxation: float, dt: float, placed: bool, push_distance: float,
                    changed, x1, v1, sleep: bool = False, levels=None):
    """A projection pass over the pairs of the forward lists; placed: overlap allowances are
    left, push_distance (m) of them may go this substep; sleep: some particles may sleep;
    levels: support levels (shock.py) or None; see _pass."""
    sleep = _sleep_mode(sleep, pass_over=not placed and levels is None)
    _pass(mode=PROJECTION, placed=placed, sleep=sleep, shock=levels is not None, **_layout(x1.shape[0]), grid=grid,
          lists=lists, particles=particles, restitution=0.0, friction=0.0, wet_friction=0.0, wet_law=0,
          relaxation=relaxation, dt=dt, push_distance=push_distance, wake_speed=0.0, rest_speed=0.0,
          levels=changed if levels is None else levels, changed=changed,
          v_test=v1, x1=x1, v1=v1)
