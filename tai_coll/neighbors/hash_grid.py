"""A spatial hash grid built by counting sort, and per-particle neighbour lists.

Cells are cubes of side `cell_size` (at least the largest particle diameter, so touching
particles are never more than one cell apart); a particle's cell is floor(x / cell_size),
so negative coordinates and particles far outside any initial bounds work the same way.
Cells map into a table of buckets (a grid that wraps around, see `bucket_of`); a bucket holds
any number of particles (no per-cell cap): counts, an exclusive prefix sum (parallel, by
blocks), then a scatter place every particle in one flat array, sorted within each bucket by
index so the result does not depend on thread timing.
A query visits the 27 cells around a particle (nine rows of three, each row one range of
entries where it does not wrap around the table) and keeps the particles whose own cell is the
visited one (two cells can share a bucket) and whose distance is within reach.
"""

import numpy as np
import taichi as ti

from ..scene import particles as P

vec3 = ti.math.vec3
ivec3 = ti.math.ivec3

NEIGHBOUR_CAPACITY = 48  # neighbours kept per particle; more are counted as overflow


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


@ti.kernel
def _count(x: ti.types.ndarray(), flags: ti.types.ndarray(), n: ti.i32, inv_cell: float, n_buckets: ti.i32,
           bits: ivec3,
           # outputs
           bucket: ti.types.ndarray(), rank: ti.types.ndarray(), counts: ti.types.ndarray(),
           cells: ti.types.ndarray()):
    for b in range(n_buckets):
        counts[b] = 0
    for i in range(n):
        if flags[i] == P.ACTIVE:
            cell = cell_of(x[i], inv_cell)
            cells[i] = cell
            h = bucket_of(cell, bits)
            bucket[i] = h
            rank[i] = ti.atomic_add(counts[h], 1)
        else:
            bucket[i] = -1


SCAN_BLOCK = 1024  # buckets per block of the parallel prefix sum


@ti.kernel
def _prefix_sum(counts: ti.types.ndarray(), n_buckets: ti.i32, block_sums: ti.types.ndarray(),
                # outputs
                starts: ti.types.ndarray()):
    """Exclusive prefix sum of the counts into starts[0..n_buckets] (starts[n_buckets] is
    the total), in three phases: block totals in parallel, a serial scan of the (few)
    block totals, then each block's own scan in parallel from its offset."""
    n_blocks = (n_buckets + SCAN_BLOCK - 1) // SCAN_BLOCK
    for b in range(n_blocks):
        total = 0
        for k in range(b * SCAN_BLOCK, ti.min((b + 1) * SCAN_BLOCK, n_buckets)):
            total += counts[k]
        block_sums[b] = total
    starts[n_buckets] = 0  # the running total
    ti.loop_config(serialize=True)
    for b in range(n_blocks):
        total = block_sums[b]
        block_sums[b] = starts[n_buckets]
        starts[n_buckets] += total
    for b in range(n_blocks):
        running = block_sums[b]
        for k in range(b * SCAN_BLOCK, ti.min((b + 1) * SCAN_BLOCK, n_buckets)):
            starts[k] = running
            running += counts[k]


@ti.kernel
def _scatter(bucket: ti.types.ndarray(), rank: ti.types.ndarray(), starts: ti.types.ndarray(), n: ti.i32,
             # outputs
             entries: ti.types.ndarray()):
    for i in range(n):
        if bucket[i] >= 0:
            entries[starts[bucket[i]] + rank[i]] = i


@ti.kernel
def _sort_buckets(starts: ti.types.ndarray(), n_buckets: ti.i32,
                  # in-out
                  entries: ti.types.ndarray()):
    # Insertion sort inside each bucket: buckets are short, and sorted buckets make the
    # neighbour order, and so every sum over neighbours, independent of thread timing.
    for b in range(n_buckets):
        begin = starts[b]
        for k in range(begin + 1, starts[b + 1]):
            value = entries[k]
            m = k - 1
            while m >= begin and entries[m] > value:
                entries[m + 1] = entries[m]
                m -= 1
            entries[m + 1] = value


@ti.kernel
def _gather(x: ti.types.ndarray(), radius: ti.types.ndarray(), cells: ti.types.ndarray(),
            entries: ti.types.ndarray(), starts: ti.types.ndarray(), n_buckets: ti.i32,
            # outputs
            sorted_x: ti.types.ndarray(), sorted_radius: ti.types.ndarray(), sorted_cells: ti.types.ndarray()):
    """Copies of positions, radii and cells in bucket order, so a query scans memory that
    lies together instead of jumping through the particle arrays."""
    for k in range(starts[n_buckets]):
        i = entries[k]
        sorted_x[k] = x[i]
        sorted_radius[k] = radius[i]
        sorted_cells[k] = cells[i]


@ti.func
def _scan_row(begin, end, slot, i, xi: vec3, ri, row: ivec3, margin, found, touch, entries: ti.template(),
              sorted_x: ti.template(), sorted_radius: ti.template(), sorted_cells: ti.template(),
              neighbours: ti.template()):
    """Entries begin..end that lie in the row of cells row .. row + (2, 0, 0) (other cells
    may share the buckets) and within reach of particle i (at `slot`): append them to i's
    list; count those touching it."""
    for k in range(begin, end):
        cell = sorted_cells[k]
        if k != slot and cell.y == row.y and cell.z == row.z and cell.x >= row.x and cell.x <= row.x + 2:
            d2 = (xi - sorted_x[k]).norm_sqr()
            contact = ri + sorted_radius[k]
            if d2 < (contact + margin) * (contact + margin):
                if found < NEIGHBOUR_CAPACITY:
                    neighbours[i, found] = entries[k]
                found += 1
                if d2 < contact * contact:
                    touch += 1
    return found, touch


@ti.kernel
def _neighbours(flags: ti.types.ndarray(), n: ti.i32, n_buckets: ti.i32, bits: ivec3, margin: float,
                starts: ti.types.ndarray(), entries: ti.types.ndarray(), sorted_x: ti.types.ndarray(),
                sorted_radius: ti.types.ndarray(), sorted_cells: ti.types.ndarray(),
                # outputs
                neighbours: ti.types.ndarray(), neighbour_count: ti.types.ndarray(),
                touching: ti.types.ndarray(), overflow: ti.types.ndarray()):
    # One particle per iteration, visited in bucket order (its own data and the cells
    # around it were just read by its bucket neighbours).
    for slot in range(starts[n_buckets]):
        i = entries[slot]
        found = 0
        touch = 0
        xi = sorted_x[slot]
        ri = sorted_radius[slot]
        home = sorted_cells[slot]
        for dy, dz in ti.static(ti.ndrange((-1, 2), (-1, 2))):
            # the row of three cells home.x - 1 .. home.x + 1: three buckets in a row, so one
            # range of entries, unless the row wraps around the table's edge
            row = home + ivec3(-1, dy, dz)
            first = bucket_of(row, bits)
            last = bucket_of(row + ivec3(2, 0, 0), bits)
            if last == first + 2:
                found, touch = _scan_row(starts[first], starts[last + 1], slot, i, xi, ri, row, margin, found,
                                         touch, entries, sorted_x, sorted_radius, sorted_cells, neighbours)
            else:
                for dx in ti.static(range(3)):
                    h = bucket_of(row + ivec3(dx, 0, 0), bits)
                    found, touch = _scan_row(starts[h], starts[h + 1], slot, i, xi, ri, row, margin, found, touch,
                                             entries, sorted_x, sorted_radius, sorted_cells, neighbours)
        if found > NEIGHBOUR_CAPACITY:
            ti.atomic_add(overflow[0], found - NEIGHBOUR_CAPACITY)
            found = NEIGHBOUR_CAPACITY
        neighbour_count[i] = found
        touching[i] = touch
    for i in range(n):
        if flags[i] != P.ACTIVE:
            neighbour_count[i] = 0
            touching[i] = 0


class HashGrid:
    """Buckets, their starts, the sorted entries (with copies of positions, radii and cells
    in that order) and the neighbour lists of up to `capacity` particles; arrays grow with
    the particle count, never per step."""

    def __init__(self):
        self.capacity = 0
        self.n_buckets = 0
        self.overflow = ti.ndarray(ti.i32, shape=1)
        self.overflow.fill(0)

    def _ensure(self, n: int):
        if n <= self.capacity:
            return
        capacity = max(n, 2 * self.capacity, 1024)
        self.capacity = capacity
        # about half the buckets empty: short probes; a power of two: the bucket is a mask
        total_bits = int(np.ceil(np.log2(2 * capacity)))
        self.n_buckets = 1 << total_bits
        self.bits = ivec3((total_bits + 2) // 3, total_bits // 3, (total_bits + 1) // 3)
        self.bucket = ti.ndarray(ti.i32, shape=capacity)
        self.rank = ti.ndarray(ti.i32, shape=capacity)
        self.entries = ti.ndarray(ti.i32, shape=capacity)
        self.cells = ti.Vector.ndarray(3, ti.i32, shape=capacity)
        self.sorted_x = ti.Vector.ndarray(3, float, shape=capacity)
        self.sorted_radius = ti.ndarray(float, shape=capacity)
        self.sorted_cells = ti.Vector.ndarray(3, ti.i32, shape=capacity)
        self.counts = ti.ndarray(ti.i32, shape=self.n_buckets)
        self.starts = ti.ndarray(ti.i32, shape=self.n_buckets + 1)
        self.block_sums = ti.ndarray(ti.i32, shape=self.n_buckets // SCAN_BLOCK + 2)
        self.neighbours = ti.ndarray(ti.i32, shape=(capacity, NEIGHBOUR_CAPACITY))
        self.neighbour_count = ti.ndarray(ti.i32, shape=capacity)
        self.touching = ti.ndarray(ti.i32, shape=capacity)

    def arrays(self) -> list:
        """Every array the grid holds (for memory accounting)."""
        return [self.bucket, self.rank, self.entries, self.cells, self.sorted_x, self.sorted_radius,
                self.sorted_cells, self.counts, self.starts, self.block_sums, self.neighbours,
                self.neighbour_count, self.touching]

    def build(self, x, radius, flags, n: int, cell_size: float, margin: float):
        """Sort the first n particles (positions x, an ndarray) into buckets and collect, for
        each, the particles closer than r_i + r_j + margin (needs cell_size >= 2 r_max + margin),
        and how many of them touch it (closer than r_i + r_j) in `touching`."""
        self._ensure(n)
        inv_cell = 1.0 / cell_size
        _count(x, flags, n, inv_cell, self.n_buckets, self.bits, self.bucket, self.rank, self.counts, self.cells)
        _prefix_sum(self.counts, self.n_buckets, self.block_sums, self.starts)
        _scatter(self.bucket, self.rank, self.starts, n, self.entries)
        _sort_buckets(self.starts, self.n_buckets, self.entries)
        _gather(x, radius, self.cells, self.entries, self.starts, self.n_buckets, self.sorted_x,
                self.sorted_radius, self.sorted_cells)
        _neighbours(flags, n, self.n_buckets, self.bits, margin, self.starts, self.entries, self.sorted_x,
                    self.sorted_radius, self.sorted_cells, self.neighbours, self.neighbour_count, self.touching,
                    self.overflow)

    def neighbour_lists(self, n: int):
        """Host copies: a list of index arrays, one per particle (for tests and debugging)."""
        counts = self.neighbour_count.to_numpy()[:n]
        table = self.neighbours.to_numpy()[:n]
        return [np.sort(table[i, : counts[i]]) for i in range(n)]

    def take_overflow(self) -> int:
        value = int(self.overflow.to_numpy()[0])
        if value:
            self.overflow.fill(0)
        return value
