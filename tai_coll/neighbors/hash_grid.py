"""A spatial hash grid built by counting sort, and per-particle neighbour lists.

Cells are cubes of side `cell_size` (at least the largest particle diameter, so touching
particles are never more than one cell apart); a particle's cell is floor(x / cell_size),
so negative coordinates and particles far outside any initial bounds work the same way.
Cells hash into a table of buckets; a bucket holds any number of particles (no per-cell
cap): counts, an exclusive prefix sum, then a scatter place every particle in one flat
array, sorted within each bucket by index so the result does not depend on thread timing.
A query visits the 27 cells around a particle and keeps the particles whose own cell is the
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
def bucket_of(cell: ivec3, n_buckets) -> ti.i32:
    # Large primes mixed with xor (Teschner et al. 2003), made non-negative before the modulo.
    h = (cell.x * 73856093) ^ (cell.y * 19349663) ^ (cell.z * 83492791)
    return ti.cast(ti.cast(h, ti.u32) % ti.cast(n_buckets, ti.u32), ti.i32)


@ti.kernel
def _count(x: ti.types.ndarray(), flags: ti.types.ndarray(), n: ti.i32, inv_cell: float, n_buckets: ti.i32,
           # outputs
           bucket: ti.types.ndarray(), rank: ti.types.ndarray(), counts: ti.types.ndarray(),
           cells: ti.types.ndarray()):
    for b in range(n_buckets):
        counts[b] = 0
    for i in range(n):
        if flags[i] == P.ACTIVE:
            cell = cell_of(x[i], inv_cell)
            cells[i] = cell
            h = bucket_of(cell, n_buckets)
            bucket[i] = h
            rank[i] = ti.atomic_add(counts[h], 1)
        else:
            bucket[i] = -1


@ti.kernel
def _prefix_sum(counts: ti.types.ndarray(), n_buckets: ti.i32,
                # outputs
                starts: ti.types.ndarray()):
    ti.loop_config(serialize=True)
    for b in range(n_buckets):
        if b == 0:
            starts[0] = 0
        else:
            starts[b] = starts[b - 1] + counts[b - 1]


@ti.kernel
def _scatter(bucket: ti.types.ndarray(), rank: ti.types.ndarray(), starts: ti.types.ndarray(), n: ti.i32,
             # outputs
             entries: ti.types.ndarray()):
    for i in range(n):
        if bucket[i] >= 0:
            entries[starts[bucket[i]] + rank[i]] = i


@ti.kernel
def _sort_buckets(starts: ti.types.ndarray(), counts: ti.types.ndarray(), n_buckets: ti.i32,
                  # in-out
                  entries: ti.types.ndarray()):
    # Insertion sort inside each bucket: buckets are short, and sorted buckets make the
    # neighbour order, and so every sum over neighbours, independent of thread timing.
    for b in range(n_buckets):
        begin = starts[b]
        for k in range(begin + 1, begin + counts[b]):
            value = entries[k]
            m = k - 1
            while m >= begin and entries[m] > value:
                entries[m + 1] = entries[m]
                m -= 1
            entries[m + 1] = value


@ti.kernel
def _neighbours(x: ti.types.ndarray(), radius: ti.types.ndarray(), flags: ti.types.ndarray(), n: ti.i32,
                n_buckets: ti.i32, margin: float, starts: ti.types.ndarray(),
                counts: ti.types.ndarray(), entries: ti.types.ndarray(), cells: ti.types.ndarray(),
                # outputs
                neighbours: ti.types.ndarray(), neighbour_count: ti.types.ndarray(),
                overflow: ti.types.ndarray()):
    for i in range(n):
        found = 0
        if flags[i] == P.ACTIVE:
            xi = x[i]
            ri = radius[i]
            home = cells[i]
            for dx, dy, dz in ti.static(ti.ndrange((-1, 2), (-1, 2), (-1, 2))):
                cell = home + ivec3(dx, dy, dz)
                h = bucket_of(cell, n_buckets)
                for k in range(starts[h], starts[h] + counts[h]):
                    j = entries[k]
                    if j != i and all(cells[j] == cell):
                        if (xi - x[j]).norm() < ri + radius[j] + margin:
                            if found < NEIGHBOUR_CAPACITY:
                                neighbours[i, found] = j
                            found += 1
        if found > NEIGHBOUR_CAPACITY:
            ti.atomic_add(overflow[0], found - NEIGHBOUR_CAPACITY)
            found = NEIGHBOUR_CAPACITY
        neighbour_count[i] = found


class HashGrid:
    """Buckets, their starts and counts, the sorted entries and the neighbour lists of up
    to `capacity` particles; arrays grow with the particle count, never per step."""

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
        self.n_buckets = 2 * capacity  # about half the buckets empty: short probes
        self.bucket = ti.ndarray(ti.i32, shape=capacity)
        self.rank = ti.ndarray(ti.i32, shape=capacity)
        self.entries = ti.ndarray(ti.i32, shape=capacity)
        self.cells = ti.Vector.ndarray(3, ti.i32, shape=capacity)
        self.counts = ti.ndarray(ti.i32, shape=self.n_buckets)
        self.starts = ti.ndarray(ti.i32, shape=self.n_buckets)
        self.neighbours = ti.ndarray(ti.i32, shape=(capacity, NEIGHBOUR_CAPACITY))
        self.neighbour_count = ti.ndarray(ti.i32, shape=capacity)

    def build(self, x, radius, flags, n: int, cell_size: float, margin: float):
        """Sort the first n particles (positions x, an ndarray) into buckets and collect, for
        each, the particles closer than r_i + r_j + margin (needs cell_size >= 2 r_max + margin)."""
        self._ensure(n)
        inv_cell = 1.0 / cell_size
        _count(x, flags, n, inv_cell, self.n_buckets, self.bucket, self.rank, self.counts, self.cells)
        _prefix_sum(self.counts, self.n_buckets, self.starts)
        _scatter(self.bucket, self.rank, self.starts, n, self.entries)
        _sort_buckets(self.starts, self.counts, self.n_buckets, self.entries)
        _neighbours(x, radius, flags, n, self.n_buckets, margin, self.starts, self.counts, self.entries, self.cells,
                    self.neighbours, self.neighbour_count, self.overflow)

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
