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

SCAN_BLOCK = 1024  # CPU: bins per block of the parallel prefix sum
SCAN_BLOCK_GPU = 256  # GPU: shorter blocks, more threads (a GPU thread's serial chain is slow)


def scan_block(arch: str) -> int:
    """The prefix sum's block length for a Taichi arch ("cpu", "cuda", ...): see exclusive_scan."""
    return SCAN_BLOCK if arch == "cpu" else SCAN_BLOCK_GPU


def scan_blocks(n: int) -> int:
    """The length of the `block_sums` array that `exclusive_scan` needs for up to n + 1 bins,
    with either block length (the blocks' totals, then their groups' totals)."""
    block = min(SCAN_BLOCK, SCAN_BLOCK_GPU)
    blocks = n // block + 1
    return blocks + blocks // block + 1


@ti.func
def exclusive_scan(counts: ti.template(), n, block_sums: ti.template(), block: ti.template(),
                   # outputs
                   starts: ti.template()):
    """starts[k] = counts[0] + ... + counts[k - 1] for k = 0..n (starts[n] is the total), in
    parallel phases over blocks of `block` bins (a compile-time int, scan_block(arch)) and
    groups of `block` blocks: the blocks' totals, the groups' totals, a scan of the (few)
    groups' totals by one thread with the sum in a register, each block's offset within its
    group, then each block's own scan from its offset. Integer sums: exact in any order.
    (One group of 1,024-bin blocks spans a million bins: on the CPU the group phases are one
    thread's short loop. On a GPU, 1,024-bin blocks and a serial scan of their totals through
    memory took 0.67 ms of a 1M-particle bed's substep on an H200, the serial part 0.35 ms.)"""
    n_blocks = (n + block - 1) // block
    n_groups = (n_blocks + block - 1) // block
    for b in range(n_blocks):
        total = 0
        for k in range(b * block, ti.min((b + 1) * block, n)):
            total += counts[k]
        block_sums[b] = total
    for g in range(n_groups):
        total = 0
        for b in range(g * block, ti.min((g + 1) * block, n_blocks)):
            total += block_sums[b]
        block_sums[n_blocks + g] = total
    for _ in range(1):  # one thread
        running = 0
        for g in range(n_groups):
            total = block_sums[n_blocks + g]
            block_sums[n_blocks + g] = running
            running += total
        starts[n] = running
    for g in range(n_groups):
        running = block_sums[n_blocks + g]
        for b in range(g * block, ti.min((g + 1) * block, n_blocks)):
            total = block_sums[b]
            block_sums[b] = running
            running += total
    for b in range(n_blocks):
        running = block_sums[b]
        for k in range(b * block, ti.min((b + 1) * block, n)):
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
