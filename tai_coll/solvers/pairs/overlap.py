"""How deep particles overlap each other now (Scene.particle_overlap), measured from the hash
grid's sort."""

import numpy as np
import taichi as ti

from ...neighbors.hash_grid import cell_of, query_span, query_spans
from ...types import ACTIVE, ARRAY, GridArgs, vec3


@ti.kernel
def _overlap_stats(grid: GridArgs, inv_cell: float, flags: ARRAY, n: ti.i32,
                   # outputs
                   stats: ARRAY):
    """Per particle (max, sum, count) of its overlaps relative to the smaller radius of each
    pair, straight from the sorted grid (the host reduces them: no atomics per pair)."""
    for slot in range(grid.starts[grid.n_buckets]):
        own = grid.sorted_xr[slot]
        home = cell_of(own.xyz, inv_cell)
        worst = 0.0
        total = 0.0
        count = 0
        spans = query_spans(home, grid.bits)
        for q in range(spans):
            begin, end = query_span(home, q, spans, grid.bits, grid.starts)
            for k in range(begin, end):
                other = grid.sorted_xr[k]
                overlap = (own.w + other.w - (own.xyz - other.xyz).norm()) / ti.min(own.w, other.w)
                if k != slot and overlap > 0.0:
                    worst = ti.max(worst, overlap)
                    total += overlap
                    count += 1
        stats[grid.entries[slot]] = vec3(worst, total, count)
    for i in range(n):
        if flags[i] != ACTIVE:
            stats[i] = vec3(0.0, 0.0, 0.0)


def overlap(grid, flags, n: int, work) -> dict:
    """{"max", "mean" (over overlapping pairs), "pairs"} of the n particles the grid has just
    sorted; work: an array of at least n 3-vectors the kernel fills."""
    _overlap_stats(grid=grid.args, inv_cell=grid.inv_cell, flags=flags, n=n, stats=work)
    stats = work.to_numpy()[:n]
    worst = stats[:, 0].max(initial=0.0)
    total = stats[:, 1].sum(dtype=np.float64)
    pairs = stats[:, 2].sum(dtype=np.float64)
    return {"max": float(worst), "mean": float(total / pairs) if pairs else 0.0, "pairs": int(pairs // 2)}
