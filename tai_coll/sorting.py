"""Counting-sort steps, shared by the particle hash grid (neighbors/hash_grid.py) and the
triangle-mesh cell grid (geometry/mesh_grid.py).

A counting sort bins items in three steps: count the items per bin, turn the counts into each
bin's first slot by an exclusive prefix sum (`exclusive_scan`), and scatter every item into
its bin's slots. A parallel scatter leaves each bin's items in any order, so each bin is then
sorted by item index (`sort_bins`): the result, and every sum taken over a bin afterwards,
does not depend on thread timing. The steps are @ti.func so that a caller runs them as
consecutive parallel loops of one kernel.
"""

import taichi as ti

SCAN_BLOCK = 1024  # bins per block of the parallel prefix sum


def scan_blocks(n: int) -> int:
    """The length of the `block_sums` array that `exclusive_scan` needs for n bins."""
    return n // SCAN_BLOCK + 2


@ti.func
def exclusive_scan(counts: ti.template(), n, block_sums: ti.template(),
                   # outputs
                   starts: ti.template()):
    """starts[k] = counts[0] + ... + counts[k - 1] for k = 0..n (starts[n] is the total), in
    three phases: the block totals in parallel, a serial scan of the (few) block totals, then
    each block's own scan in parallel from its offset. Integer sums: exact in any order."""
    n_blocks = (n + SCAN_BLOCK - 1) // SCAN_BLOCK
    for b in range(n_blocks):
        total = 0
        for k in range(b * SCAN_BLOCK, ti.min((b + 1) * SCAN_BLOCK, n)):
            total += counts[k]
        block_sums[b] = total
    starts[n] = 0  # the running total
    ti.loop_config(serialize=True)
    for b in range(n_blocks):
        total = block_sums[b]
        block_sums[b] = starts[n]
        starts[n] += total
    for b in range(n_blocks):
        running = block_sums[b]
        for k in range(b * SCAN_BLOCK, ti.min((b + 1) * SCAN_BLOCK, n)):
            starts[k] = running
            running += counts[k]


@ti.func
def sort_bins(starts: ti.template(), n_bins,
              # in-out
              items: ti.template()):
    """Insertion sort of each bin's items (bin b holds items[starts[b]:starts[b + 1]]): bins
    are short, and a fixed order within each makes the binning deterministic."""
    for b in range(n_bins):
        begin = starts[b]
        for k in range(begin + 1, starts[b + 1]):
            value = items[k]
            m = k - 1
            while m >= begin and items[m] > value:
                items[m + 1] = items[m]
                m -= 1
            items[m + 1] = value
