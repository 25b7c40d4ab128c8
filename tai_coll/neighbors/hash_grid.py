"""A spatial hash grid built by counting sort, and per-particle neighbour lists.

Cells are cubes of side `cell_size` (at least the largest particle diameter, so touching
particles are never more than one cell apart); a particle's cell is floor(x / cell_size),
so negative coordinates and particles far outside any initial bounds work the same way.
Cells map into a table of buckets (a grid that wraps around, see `bucket_of`); a bucket holds
any number of particles (no per-cell cap): a counting sort (tai_coll/sorting.py: counts, an
exclusive prefix sum, a scatter, each bucket sorted by index so the result does not depend on
thread timing) places every particle in one flat array.
A query visits the 27 cells around a particle (nine rows of three, each row one range of
entries where it does not wrap around the table, see `query_spans`) and keeps the particles
within reach (two cells can share a bucket, but never two cells near each other).
How the table's bits are shared among the axes follows the particles' extent in cells at each
sort (`table_bits`): a bed 127 cells wide and 6 deep gets 2^8 x 2^3 x 2^7 buckets, where an
even 2^6 along each axis would put four of its cells in every bucket and make each query read
four times the particles it needs.
Kernels that query the grid take its sort as `HashGrid.args` (types.GridArgs) and its lists
as `HashGrid.lists` (types.ListArgs).
"""

import numpy as np
import taichi as ti

from .. import runtime, sorting
from ..types import ACTIVE, ARRAY, GridArgs, ListArgs, ivec3, vec3, vec4

NEIGHBOUR_CAPACITY = 48  # neighbours kept per particle; more are counted as overflow
#: The most particles neighbour lists are made for: Taichi 1.7 computes an array element's
#: offset in 32-bit integers, and the lists hold NEIGHBOUR_CAPACITY ints a particle (a larger
#: array would be read and written at wrapped offsets). 44,739,242.
MAX_LISTED = (2**31 - 1) // NEIGHBOUR_CAPACITY
FULL, FORWARD_SORTED, FORWARD_RADIUS = 0, 1, 2  # which neighbours a list holds (see HashGrid.build)


@ti.func
def cell_of(x: vec3, inv_cell) -> ivec3:
    return ti.cast(ti.floor(x * inv_cell), ti.i32)


@ti.func
def bucket_of(cell: ivec3, bits: ivec3) -> ti.i32:
    """The bucket of a cell: the low bits of its three coordinates side by side (a grid of
    2^bits.x by 2^bits.y by 2^bits.z buckets that wraps around, so any integer cell, negative
    or far away, has one). Unlike a scrambling hash, cells next to each other get buckets
    next to each other: the 27 buckets of a query, and the particles of neighbouring cells,
    lie close together in memory. Cells a whole table width apart share a bucket; queries
    tell them apart by the cell each particle is in."""
    mask = (1 << bits) - 1
    return (cell.x & mask.x) | ((cell.y & mask.y) << bits.x) | ((cell.z & mask.z) << (bits.x + bits.y))


@ti.func
def count_step(x: ti.template(), flags: ti.template(), n, inv_cell, n_buckets, bits,
               # outputs
               bucket: ti.template(), rank: ti.template(), counts: ti.template()):
    for b in range(n_buckets + 1):
        counts[b] = 0
    for i in range(n):
        # particles no longer simulated go to a bucket of their own past the table's end,
        # which no query visits: the entries are then an ordering of all n particles
        h = n_buckets
        if flags[i] == ACTIVE:
            h = bucket_of(cell_of(x[i], inv_cell), bits)
        bucket[i] = h
        rank[i] = ti.atomic_add(counts[h], 1)


@ti.func
def scatter_step(bucket: ti.template(), rank: ti.template(), starts: ti.template(), n,
                 # outputs
                 entries: ti.template()):
    for i in range(n):
        entries[starts[bucket[i]] + rank[i]] = i


@ti.func
def gather_step(x: ti.template(), radius: ti.template(), entries: ti.template(), starts: ti.template(), n_buckets,
                # outputs
                sorted_xr: ti.template()):
    """Positions and radii (x, y, z, r) in bucket order: a query reads one 16-byte record per
    candidate, from memory that lies together instead of jumping through the particle arrays."""
    for k in range(starts[n_buckets]):
        i = entries[k]
        sorted_xr[k] = vec4(x[i], radius[i])


BOUND_BLOCKS = 256  # CPU: blocks of the cell-bounds reduction, each a serial scan of its share
BOUND_SHARE_GPU = 64  # GPU: particles a thread of the cell-bounds reduction scans


@ti.kernel
def _cell_bounds(x: ARRAY, flags: ARRAY, n: ti.i32, inv_cell: float, blocks: ti.i32, interleaved: ti.template(),
                 # output: the lowest cell along x, y, z, then the highest
                 bounds: ARRAY):
    """The range of cells the active particles occupy: `blocks` threads each take the extremes
    of its share of the particles (a run of them, or on a GPU every blocks-th one, so that
    neighbouring threads read neighbouring particles), then fold them into `bounds` with six
    atomics; no atomic a particle. (256 threads on a GPU, one run each, took 2.5 ms of a
    1M-particle bed's 10 ms substep on an H100.)"""
    for a in range(3):
        bounds[a] = 2147483647
        bounds[3 + a] = -2147483647
    per = (n + blocks - 1) // blocks
    for b in range(blocks):
        lo = ivec3(2147483647)
        hi = ivec3(-2147483647)
        for k in range(per):
            i = k * blocks + b if ti.static(interleaved) else b * per + k
            if i < n and flags[i] == ACTIVE:
                c = cell_of(x[i], inv_cell)
                lo = ti.min(lo, c)
                hi = ti.max(hi, c)
        if lo[0] <= hi[0]:  # (some particle of the share is active)
            for a in ti.static(range(3)):
                ti.atomic_min(bounds[a], lo[a])
                ti.atomic_max(bounds[3 + a], hi[a])


def cell_span(x, flags, n: int, inv_cell: float, bounds, interleaved: bool):
    """The lowest and the highest cell (two int arrays of 3) the active particles among the
    first n occupy, None if none is; `bounds`: a work array of 6 ints. interleaved: the GPU's
    share of particles a thread (see _cell_bounds), else the CPU's runs."""
    blocks = (n + BOUND_SHARE_GPU - 1) // BOUND_SHARE_GPU if interleaved else BOUND_BLOCKS
    _cell_bounds(x=x, flags=flags, n=n, inv_cell=inv_cell, blocks=max(blocks, 1), interleaved=interleaved,
                 bounds=bounds)
    found = runtime.read_small(bounds)
    lo, hi = found[:3], found[3:]
    return None if np.any(hi < lo) else (lo, hi)


#: The fewest bits a table gives an axis: 16 x 8 x 8 buckets, which the colouring of the
#: Gauss-Seidel passes needs (an even number of its units along each axis) and which keeps the
#: 27 cells of a query in 27 distinct buckets.
MIN_BITS = (4, 3, 3)


def table_bits(extent, total_bits: int) -> tuple:
    """Bits of the bucket table per axis for particles spanning extent[a] cells along axis a
    (None: unknown), out of total_bits: each axis as many as its extent plus the query's cell
    on either side needs, at least MIN_BITS; where they add up to more than total_bits, a bit
    at a time comes off the axis holding the most, so the axes wrap alike. Bits that no
    axis needs are left unused (fewer, fuller buckets: the Gauss-Seidel passes visit every
    bucket of the table)."""
    if extent is None:
        return ((total_bits + 2) // 3, total_bits // 3, (total_bits + 1) // 3)
    bits = [max(low, int(np.ceil(np.log2(int(e) + 2)))) for low, e in zip(MIN_BITS, extent)]
    while sum(bits) > total_bits:
        # of the axes holding the most, z before y before x: rows along x stay whole (a query
        # reads a row of three cells as one range unless it wraps; measured on the 100k bed,
        # 2^8 x 2^3 x 2^7 buckets ran its passes 1.2 times as fast as 2^7 x 2^3 x 2^8)
        axis = max((a for a in range(3) if bits[a] > MIN_BITS[a]), key=lambda a: (bits[a], a))
        bits[axis] -= 1
    return tuple(bits)


@ti.kernel
def _sort(x: ARRAY, radius: ARRAY, flags: ARRAY, n: ti.i32, inv_cell: float, n_buckets: ti.i32, bits: ivec3,
          scan_block: ti.template(),
          # outputs
          bucket: ARRAY, rank: ARRAY, counts: ARRAY, block_sums: ARRAY, starts: ARRAY, entries: ARRAY,
          sorted_xr: ARRAY):
    """The counting sort in one launch: its steps' parallel loops run one after the other."""
    count_step(x, flags, n, inv_cell, n_buckets, bits, bucket, rank, counts)
    sorting.exclusive_scan(counts, n_buckets + 1, block_sums, scan_block, starts)
    scatter_step(bucket, rank, starts, n, entries)
    sorting.sort_bins(starts, n_buckets + 1, entries)
    gather_step(x, radius, entries, starts, n_buckets, sorted_xr)


@ti.func
def query_spans(home: ivec3, bits: ivec3) -> ti.i32:
    """How many ranges of entries a query around cell `home` reads (see query_span): the 27
    cells around it lie in nine rows of three along x, and three cells in a row have three
    buckets in a row, one range of entries, unless the row wraps around the table's edge
    along x. Whether the rows wrap depends on home.x alone, the same for all nine: 9 ranges,
    one a row, or 27, one a cell. Loop `for q in range(query_spans(home, bits))`."""
    mask = (1 << bits.x) - 1
    return ti.select(((home.x - 1) & mask) > mask - 2, 27, 9)


@ti.func
def row_bucket(home: ivec3, q, bits: ivec3) -> ti.i32:
    """The first of the three buckets of row q (dy = q // 3 - 1, dz = q % 3 - 1) of a query
    around cell `home` whose rows do not wrap along x (query_spans 9)."""
    return bucket_of(home + ivec3(-1, q // 3 - 1, q % 3 - 1), bits)


@ti.func
def query_span(home: ivec3, q, spans, bits: ivec3, starts: ti.template()):
    """Entries begin..end of range q of a query around cell `home` (spans: query_spans):
    the rows at dy = q // 3 - 1, dz = q % 3 - 1 (9 spans), or cell q % 3 of row q // 3
    (27). The same entries, in the same order, either way."""
    begin = 0
    end = 0
    if spans == 9:
        first = row_bucket(home, q, bits)
        begin = starts[first]
        end = starts[first + 3]
    else:
        row = q // 3
        h = bucket_of(home + ivec3(q % 3 - 1, row // 3 - 1, row % 3 - 1), bits)
        begin = starts[h]
        end = starts[h + 1]
    return begin, end


@ti.func
def _scan_row(begin, end, slot, base, xi: vec3, ri, margin, margin_radii, forward: ti.template(), found, touch,
              sorted_xr: ti.template(), entries: ti.template(), local: ti.template(), kept: ti.template(),
              neighbours: ti.template()):
    """Entries begin..end within reach (r_i + r_j + margin + margin_radii min(r_i, r_j)) of
    the particle at `slot` (position xi, radius ri): append their slots to `kept`; count those
    touching it. forward (compile time): FORWARD_SORTED, entries begin..end all lie after
    `slot`; FORWARD_RADIUS, lists owned by the smaller particle: only the larger ones (or, of
    equal radius, those sorted after it) are kept. Other cells may share these buckets
    (cells a table width apart), but their particles are at least a table width minus two cells
    away (three cells or more, see HashGrid), beyond reach, so the distance test alone tells
    them apart. local (compile time; the CPU's way): the slots go to `kept`, a local array, and
    the caller copies them to i's list; branch-free, since most candidates are out of reach
    and which ones is not predictable: every candidate is written at the array's end (its
    spare last place once full) and only those in reach advance it. Writing the lists
    directly, to memory the compiler cannot tell apart from the grid's arrays, made it reload
    their addresses for every candidate: the kernel took 1.5 times as long on the CPU. On a
    GPU a local array that large lives in slow memory, so there each kept one goes straight
    to `neighbours` (from `base` on)."""
    for k in range(begin, end):
        other = sorted_xr[k]
        d2 = (xi - other.xyz).norm_sqr()
        contact = ri + other.w
        reach = contact + margin + margin_radii * ti.min(ri, other.w)
        keep = d2 < reach * reach
        if ti.static(forward == FULL):
            keep &= k != slot
        elif ti.static(forward == FORWARD_RADIUS):
            keep &= (k != slot) & ((other.w > ri) | ((other.w == ri) & (k > slot)))
        if ti.static(local):
            kept[ti.min(found, NEIGHBOUR_CAPACITY)] = k
        elif keep and found < NEIGHBOUR_CAPACITY:
            neighbours[base + found] = entries[k]
        found += ti.cast(keep, ti.i32)
        touch += ti.cast(keep & (d2 < contact * contact), ti.i32)
    return found, touch


@ti.func
def neighbour_of(lists: ti.template(), i, k):
    """Particle i's k-th listed neighbour (k < lists.neighbour_count[i])."""
    return lists.neighbours[lists.first[i] + k]


#: Particles whose lists the CPU packs together (see _neighbours); GPUs give each particle its
#: own NEIGHBOUR_CAPACITY places.
PACKED_BLOCK = 16


@ti.func
def _awake_near(home: ivec3, bits: ivec3, awake: ti.template()) -> ti.i32:
    """Whether any of the 27 buckets around cell `home` holds an awake particle (awake: a mark
    a bucket, see _neighbours' awake_only)."""
    near = 0
    for c in range(27):
        near |= ti.cast(awake[bucket_of(home + ivec3(c % 3 - 1, c // 3 % 3 - 1, c // 9 - 1), bits)], ti.i32)
    return near


@ti.kernel
def _neighbours(grid: GridArgs, flags: ARRAY, n: ti.i32, inv_cell: float, margin: float, margin_radii: float,
                forward: ti.template(), local: ti.template(), block: ti.template(),
                awake_only: ti.template(), rest: ARRAY,
                # outputs
                lists: ListArgs, touching: ARRAY, overflow: ARRAY, listed_any: ARRAY, awake: ARRAY):
    """Each particle's neighbours within r_i + r_j + margin + margin_radii min(r_i, r_j)
    (forward: FORWARD_SORTED, only those after it in the sorted entries; FORWARD_RADIUS, only
    those larger than it or, of equal radius, after it), and how many of them touch it.
    local: the CPU's way of collecting them (see _scan_row). listed_any[0]: whether any
    particle listed a neighbour.
    The lists of `block` particles in a row of the sorted entries share the block's
    block x NEIGHBOUR_CAPACITY places, one after the other (first[i]: where particle i's
    begin): the passes, which walk the particles in that order, then read their lists from
    consecutive memory instead of a row of NEIGHBOUR_CAPACITY places each, mostly empty
    (measured: docs/design-notes.md, "Packed neighbour lists"). Where they start depends on
    the lists before them in the block alone, not on thread timing.
    awake_only (compile time): a sleeping particle (rest < 0, sleeping.py) with no awake particle
    in the 27 buckets around it lists nothing, so that the lists hold every pair with an awake
    particle, and of the pairs of two sleeping ones only some (awake: a mark a bucket, work)."""
    listed_any[0] = 0
    total = grid.starts[grid.n_buckets]
    if ti.static(awake_only):
        for h in range(grid.n_buckets):
            awake[h] = ti.cast(0, ti.i8)
        for k in range(total):  # (threads may mark a bucket at once: with the same value)
            if rest[grid.entries[k]] >= 0.0:
                awake[bucket_of(cell_of(grid.sorted_xr[k].xyz, inv_cell), grid.bits)] = ti.cast(1, ti.i8)
    for b in range((total + block - 1) // block):
        base = b * block * NEIGHBOUR_CAPACITY
        # One particle per iteration, visited in bucket order (its own data and the cells
        # around it were just read by its bucket neighbours).
        for slot in range(b * block, ti.min(b * block + block, total)):
            i = grid.entries[slot]
            found = 0
            touch = 0
            own = grid.sorted_xr[slot]
            xi = own.xyz
            home = cell_of(xi, inv_cell)
            kept = ti.Vector([0] * (NEIGHBOUR_CAPACITY + 1 if ti.static(local) else 1), ti.i32)  # their slots
            # forward lists: only the entries after this one (most rows end before it)
            after = slot + 1 if ti.static(forward == FORWARD_SORTED) else 0
            spans = query_spans(home, grid.bits)
            own_bucket = bucket_of(home, grid.bits)
            if ti.static(awake_only):
                if rest[i] < 0.0 and _awake_near(home, grid.bits, awake) == 0:
                    spans = 0  # (asleep among sleeping particles only: no pair of it acts)
            for q in range(spans):
                if ti.static(forward == FORWARD_SORTED):
                    # a row of buckets wholly before the particle's own holds no entry after it: no
                    # need to read where its entries are (rows that wrap around the table along y or
                    # z lie after it, and are read; 6 % off the kernel in a dense pile)
                    if spans == 9 and row_bucket(home, q, grid.bits) + 3 <= own_bucket:
                        continue
                begin, end = query_span(home, q, spans, grid.bits, grid.starts)
                found, touch = _scan_row(ti.max(begin, after), end, slot, base, xi, own.w, margin, margin_radii,
                                         forward, found, touch, grid.sorted_xr, grid.entries, local, kept,
                                         lists.neighbours)
            if found > NEIGHBOUR_CAPACITY:
                ti.atomic_add(overflow[0], found - NEIGHBOUR_CAPACITY)
                found = NEIGHBOUR_CAPACITY
            if ti.static(local):
                for q in range(found):
                    lists.neighbours[base + q] = grid.entries[kept[q]]
            lists.first[i] = base
            lists.neighbour_count[i] = found
            touching[i] = touch
            base += found
            if found > 0 and listed_any[0] == 0:
                listed_any[0] = 1  # (read first: one shared line, written once)
    for i in range(n):
        if flags[i] != ACTIVE:
            lists.first[i] = 0
            lists.neighbour_count[i] = 0
            touching[i] = 0


class HashGrid:
    """Buckets, their starts, the sorted entries (with a copy of positions and radii in that
    order) and the neighbour lists of up to `capacity` particles; arrays grow with the
    particle count, never per step. The table is at least 8 buckets wide along each axis
    (capacity >= 1024: 2^11 buckets or more), so the 27 cells of a query fall in 27 distinct
    buckets and a cell sharing a bucket with one of them is at least 5 cells away."""

    def __init__(self):
        self.capacity = 0
        self.list_capacity = 0
        self.forward = False  # whether the lists hold each pair once (see build)
        self.n_buckets = 0
        self.inv_cell = 1.0  # 1 / cell size of the last sort
        self.overflow = ti.ndarray(ti.i32, shape=1)
        self.overflow.fill(0)
        self.listed = ti.ndarray(ti.i32, shape=1)  # whether the last build listed any pair
        self.listed.fill(1)
        self._bounds = None  # a work array of _cell_bounds (see _extent)
        self._args = self._lists = None  # the argument packs (see args, lists)

    def _ensure(self, n: int):
        if n <= self.capacity:
            return
        capacity = max(n, min(2 * self.capacity, MAX_LISTED), 1024)  # (growth stops at the lists' limit)
        self.capacity = capacity
        # about half the buckets empty: short probes; a power of two: the bucket is a mask
        self.total_bits = int(np.ceil(np.log2(2 * capacity)))
        self.n_buckets = 1 << self.total_bits
        self.bits = ivec3(*table_bits(None, self.total_bits))
        self.bucket = ti.ndarray(ti.i32, shape=capacity)
        self.rank = ti.ndarray(ti.i32, shape=capacity)
        self.entries = ti.ndarray(ti.i32, shape=capacity)
        self.sorted_xr = ti.Vector.ndarray(4, float, shape=capacity)
        # one bucket more than the table: the particles no longer simulated (see count_step)
        self.counts = ti.ndarray(ti.i32, shape=self.n_buckets + 1)
        self.starts = ti.ndarray(ti.i32, shape=self.n_buckets + 2)
        self.block_sums = ti.ndarray(ti.i32, shape=sorting.scan_blocks(self.n_buckets))
        self._args = None

    def _ensure_lists(self):
        """The neighbour lists, only for users of `build` (kernels that query the grid
        themselves need the sort alone)."""
        if self.list_capacity == self.capacity:
            return
        if self.capacity > MAX_LISTED:  # (the scene refuses such counts first: Scene.enable_particle_collisions)
            raise ValueError(f"particles: neighbour lists hold at most {MAX_LISTED:,} particles; got {self.capacity:,}")
        self.list_capacity = self.capacity
        self.neighbours = ti.ndarray(ti.i32, shape=self.capacity * NEIGHBOUR_CAPACITY)
        self.first = ti.ndarray(ti.i32, shape=self.capacity)
        self.neighbour_count = ti.ndarray(ti.i32, shape=self.capacity)
        self.touching = ti.ndarray(ti.i32, shape=self.capacity)
        self.awake = None  # a mark a bucket for lists of the awake (see build), made when first asked for
        self._lists = None

    @property
    def args(self) -> GridArgs:
        """The sort as kernels that query the grid take it (types.GridArgs; with `inv_cell`)."""
        if self._args is None:
            self._args = GridArgs(n_buckets=self.n_buckets, bits=self.bits, starts=self.starts, entries=self.entries,
                                  sorted_xr=self.sorted_xr)
        return self._args

    @property
    def lists(self) -> ListArgs:
        """The neighbour lists of the last `build` as kernels take them (types.ListArgs)."""
        if self._lists is None:
            self._lists = ListArgs(neighbours=self.neighbours, first=self.first, neighbour_count=self.neighbour_count)
        return self._lists

    def arrays(self) -> list:
        """Every array the grid holds (for memory accounting)."""
        lists = [self.neighbours, self.first, self.neighbour_count, self.touching] if self.list_capacity else []
        lists += [self.awake] if self.list_capacity and self.awake is not None else []
        return [self.bucket, self.rank, self.entries, self.sorted_xr, self.counts, self.starts, self.block_sums] + lists

    def build(self, x, radius, flags, n: int, cell_size: float, margin: float, forward: bool = False,
              margin_radii: float = 0.0, by_radius: bool = False, awake_only=None):
        """Sort the first n particles (positions x, an array) into buckets and collect, for
        each, the particles closer than r_i + r_j + margin + margin_radii min(r_i, r_j) (needs
        cell_size >= 2 r_max + margin + margin_radii r_max), and how many of them touch it
        (closer than r_i + r_j) in `touching`. forward: each pair once, in the list of the one
        sorted first, or with by_radius in the list of the smaller one (of equal radii, the one
        sorted first: a large particle among many small ones then lists few, and each small one
        lists it); `touching` then counts the listed ones.
        awake_only: None, or the particles' rest times (sleeping.py): a sleeping particle with
        no awake one within the 27 cells around it lists nothing (lists of the awake: the pairs
        of two sleeping particles are left out where nothing awake is near)."""
        self.sort(x, radius, flags, n, cell_size)
        self.relist(flags, n, margin, forward, margin_radii, by_radius, awake_only)

    def relist(self, flags, n: int, margin: float, forward: bool = False, margin_radii: float = 0.0,
               by_radius: bool = False, awake_only=None):
        """The neighbour lists of `build` again, from its sort (the arguments as build's)."""
        self._ensure_lists()
        self.forward = bool(forward)
        mode = (FORWARD_RADIUS if by_radius else FORWARD_SORTED) if forward else FULL
        cpu = runtime.info().arch == "cpu"
        if awake_only is not None and self.awake is None:
            self.awake = ti.ndarray(ti.i8, shape=self.n_buckets)
        _neighbours(grid=self.args, flags=flags, n=n, inv_cell=self.inv_cell, margin=margin,
                    margin_radii=margin_radii, forward=mode, local=cpu, block=PACKED_BLOCK if cpu else 1,
                    awake_only=awake_only is not None, rest=flags if awake_only is None else awake_only,
                    lists=self.lists, touching=self.touching, overflow=self.overflow, listed_any=self.listed,
                    awake=self.overflow if awake_only is None else self.awake)

    def sort(self, x, radius, flags, n: int, cell_size: float):
        """The counting sort alone: buckets, their starts, the entries and the copy of positions
        and radii in bucket order, for kernels that query the grid themselves (`query_span`,
        with `args` and `inv_cell`). entries[:n] is an ordering of all n particles: the
        simulated ones in bucket order (starts[n_buckets] of them), then the others, so the
        particle store can be put in cell order by it (`ParticleStore.permute`)."""
        self._ensure(n)
        self.inv_cell = 1.0 / cell_size
        bits = ivec3(*table_bits(self._extent(x, flags, n), self.total_bits))
        if any(bits != self.bits):
            self.bits = bits
            self._args = None
        _sort(x=x, radius=radius, flags=flags, n=n, inv_cell=self.inv_cell, n_buckets=self.n_buckets, bits=self.bits,
              scan_block=sorting.scan_block(runtime.info().arch), bucket=self.bucket, rank=self.rank,
              counts=self.counts, block_sums=self.block_sums, starts=self.starts, entries=self.entries,
              sorted_xr=self.sorted_xr)

    def _extent(self, x, flags, n: int):
        """How many cells the active particles span along each axis (None: none active)."""
        if n == 0:
            return None
        if self._bounds is None:
            self._bounds = ti.ndarray(ti.i32, shape=6)
        span = cell_span(x, flags, n, self.inv_cell, self._bounds, interleaved=runtime.info().arch != "cpu")
        return None if span is None else (span[1].astype(np.int64) - span[0] + 1).tolist()

    def own_lists(self, n: int) -> list:
        """Host copies of the lists as built: one index array per particle (forward lists:
        each pair in one of the two particles' arrays only)."""
        counts = self.neighbour_count.to_numpy()[:n]
        first = self.first.to_numpy()[:n]
        flat = self.neighbours.to_numpy()
        return [flat[first[i]:first[i] + counts[i]] for i in range(n)]

    def neighbour_lists(self, n: int):
        """Host copies: a list of index arrays, one per particle (for tests and debugging); from
        forward lists, each pair appears in both particles' arrays, as from full ones."""
        lists = self.own_lists(n)
        counts = np.array([len(row) for row in lists], dtype=np.int64)
        if self.forward:
            owner = np.repeat(np.arange(n), counts)
            listed = np.concatenate(lists) if n else np.zeros(0, int)
            back = np.argsort(listed, kind="stable")
            bounds = np.searchsorted(listed[back], np.arange(n + 1))
            lists = [np.concatenate([lists[i], owner[back[bounds[i]:bounds[i + 1]]]]) for i in range(n)]
        return [np.sort(row) for row in lists]

    def listed_any(self) -> bool:
        """Whether the last build listed any pair (a read from the device)."""
        return bool(runtime.read_small(self.listed, 1)[0])

    def dropped(self) -> int:
        """Neighbours left out of full lists by every build so far (a read from the device)."""
        return int(self.overflow[0])
