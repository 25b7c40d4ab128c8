"""Finding the pairs: the hash grid against brute force (negative coordinates, far
outliers, forward lists, the prefix sum over many blocks and groups of blocks), the store
kept in cell order, and Verlet lists (skin > 0) kept between substeps, for impulses and for
DEM pairs."""

import math

import numpy as np
import pytest

import taichi as ti

import tai_coll as tc
from tai_coll import sorting
from tai_coll.neighbors import HashGrid
from conftest import (add_box_of_planes, assert_stack_rests_in_contact, crowded_particle, grid_of, on_device,
                      pile_scene, spring_law_velocities)


# ---------------------------------------------------------------- the hash grid against brute force
@pytest.mark.parametrize("forward", [False, True])
@pytest.mark.parametrize("offset", [(0.0, 0.0, 0.0), (-37.3, -5.0, -12.9)])
def test_hash_grid_matches_brute_force(offset, forward):
    rng = np.random.default_rng(3)
    n = 600
    x = rng.uniform(-0.3, 0.3, (n, 3)) + np.array(offset)
    x[:5] += [1e3, -2e3, 5e2]  # far outside the others' bounds
    radius = rng.uniform(0.01, 0.03, n)
    margin = 0.005
    assert_lists_match_brute_force(grid_of(x, radius, margin, forward), x, radius, margin, forward)


@pytest.mark.parametrize("forward", [False, True])
def test_lists_of_clusters_scattered_over_many_table_widths_match_brute_force(forward):
    # 400 clusters of 4 touching particles, spread over about 30 widths of the grid's table
    # along each axis: clusters cross the table's edges (where a query's rows wrap around to
    # the far side), so forward lists must also read rows whose buckets come after the
    # particle's own only by wrapping (hash_grid._neighbours skips the rows wholly before it).
    rng = np.random.default_rng(11)
    r = 0.01
    centres = rng.uniform(-4.0, 4.0, (400, 3))
    x = (centres[:, None, :] + rng.uniform(-1.5 * r, 1.5 * r, (400, 4, 3))).reshape(-1, 3)
    radius = np.full(len(x), r)
    grid = grid_of(x, radius, 0.25 * r, forward)
    assert (1 << int(max(grid.bits))) * 2.25 * r < 0.8  # (the table: a tenth of the spread or less)
    assert_lists_match_brute_force(grid, x, radius, 0.25 * r, forward)


def assert_lists_match_brute_force(grid, x, radius, margin, forward):
    """The grid's lists (and its touching counts, from full lists) against all pairs."""
    n = len(x)
    lists = grid.neighbour_lists(n)  # from forward lists: each pair put in both particles' lists
    d = np.linalg.norm(x[:, None, :] - x[None, :, :], axis=2)
    reach = radius[:, None] + radius[None, :] + margin
    touching = grid.touching.to_numpy()[:n]
    contact = radius[:, None] + radius[None, :]
    for i in range(n):
        expected = np.flatnonzero((d[i] < reach[i]) & (np.arange(n) != i))
        assert np.array_equal(lists[i], expected), i
        if not forward:
            assert touching[i] == np.count_nonzero((d[i] < contact[i]) & (np.arange(n) != i)), i
    if forward:  # each pair listed once, by the particle sorted first
        own = grid.own_lists(n)
        slot_of = np.empty(n, int)
        slot_of[grid.entries.to_numpy()[:n]] = np.arange(n)
        for i in range(n):
            assert np.all(slot_of[own[i]] > slot_of[i]), i
        assert sum(len(row) for row in own) == sum(len(row) for row in lists) // 2
    assert grid.dropped() == 0


@pytest.mark.parametrize("forward", [False, True])
def test_lists_of_the_awake_hold_every_pair_with_an_awake_particle(forward):
    # HashGrid.build's awake_only (solvers/pairs/awake_lists.py): a sleeping particle (rest < 0)
    # lists nothing when no awake particle is within the 27 cells around it; every other particle
    # lists as before. So every pair with an awake particle is listed, once (forward) or from
    # both sides, and lists far from the awake ones are empty.
    rng = np.random.default_rng(5)
    r, margin = 0.01, 0.0025
    g = np.arange(30) * 2.1 * r
    x = np.stack(np.meshgrid(g, g[:6], g[:10], indexing="ij"), -1).reshape(-1, 3) + rng.uniform(-0.1 * r, 0.1 * r,
                                                                                                    (1800, 3))
    radius = np.full(len(x), r)
    awake = np.zeros(len(x), bool)
    awake[rng.choice(len(x), 12, replace=False)] = True
    awake[(x[:, 0] < 0.1) & (x[:, 2] < 0.05)] = True  # and a corner of them
    rest = np.where(awake, 0.01, -1.0)
    n = len(x)
    whole, slim = (HashGrid(), HashGrid())
    cell = 2 * r + margin
    whole.build(on_device(x), on_device(radius), on_device(np.zeros(n, int)), n, cell, margin, forward=forward)
    slim.build(on_device(x), on_device(radius), on_device(np.zeros(n, int)), n, cell, margin, forward=forward,
               awake_only=on_device(rest))
    assert np.array_equal(whole.entries.to_numpy()[:n], slim.entries.to_numpy()[:n])  # the same sort
    full, kept = whole.own_lists(n), slim.own_lists(n)
    near = np.zeros(n, bool)  # an awake particle within the 27 cells around
    cells = np.floor(x.astype(np.float32) * np.float32(1.0 / cell)).astype(int)  # (as the kernel's f32)
    for i in np.flatnonzero(awake):
        near |= np.abs(cells - cells[i]).max(axis=1) <= 1
    for i in range(n):
        if awake[i] or near[i]:
            assert np.array_equal(kept[i], full[i]), i
        else:
            assert len(kept[i]) == 0, i
    listed = {(min(i, j), max(i, j)) for i in range(n) for j in kept[i]}
    for i in range(n):
        for j in full[i]:
            if awake[i] or awake[j]:
                assert (min(i, j), max(i, j)) in listed, (i, j)
    assert 0 < sum(map(len, kept)) < sum(map(len, full)) // 4  # most of the sleeping bed lists nothing
    assert slim.dropped() == whole.dropped() == 0


@pytest.mark.parametrize("forward", [False, True])
def test_packed_lists_follow_each_other_and_overfull_ones_stay_within_their_block(forward):
    # The lists of PACKED_BLOCK particles in a row of the sorted entries lie one after the
    # other in their block's places (the CPU's layout), also where a dense cluster gives 40
    # particles in a row more neighbours than a list keeps: each keeps NEIGHBOUR_CAPACITY
    # true neighbours, and no list overwrites the next one's.
    from tai_coll.neighbors.hash_grid import NEIGHBOUR_CAPACITY, PACKED_BLOCK

    rng = np.random.default_rng(5)
    cloud = rng.uniform(-0.3, 0.3, (500, 3))
    cluster = rng.uniform(-0.01, 0.01, (70, 3)) + 0.5  # 70 within reach of each other
    x = np.concatenate([cloud, cluster])
    radius = np.full(len(x), 0.02)
    margin = 0.005
    grid = grid_of(x, radius, margin, forward)
    n = len(x)
    assert grid.dropped() > 0
    counts = grid.neighbour_count.to_numpy()[:n]
    first = grid.first.to_numpy()[:n]
    entries = grid.entries.to_numpy()[:n]
    for slot in range(n):
        i = entries[slot]
        block = slot // PACKED_BLOCK
        start = block * PACKED_BLOCK * NEIGHBOUR_CAPACITY
        expected = start + sum(counts[entries[s]] for s in range(block * PACKED_BLOCK, slot))
        assert first[i] == expected, slot
        assert first[i] + counts[i] <= start + PACKED_BLOCK * NEIGHBOUR_CAPACITY
    d = np.linalg.norm(x[:, None, :] - x[None, :, :], axis=2)
    for i, row in enumerate(grid.own_lists(n)):
        assert len(row) == counts[i] <= NEIGHBOUR_CAPACITY
        assert len(set(row.tolist())) == len(row) and np.all(d[i, row] < 2 * 0.02 + margin) and i not in row, i
    if not forward:  # each of the cluster keeps a full list of its 69 neighbours
        assert np.all(counts[500:] == NEIGHBOUR_CAPACITY)
    lists = grid.neighbour_lists(n)  # the cloud's own lists are whole
    for i in range(500):
        assert np.array_equal(lists[i], np.flatnonzero((d[i] < 2 * 0.02 + margin) & (np.arange(n) != i))), i


@pytest.mark.parametrize("forward", [False, True])
def test_the_gpus_list_layout_holds_the_same_lists(forward):
    # GPUs write each kept neighbour straight into the particle's own NEIGHBOUR_CAPACITY places
    # (a block of one); the same kernel run that way here lists what the CPU's packed lists do.
    from tai_coll.neighbors import hash_grid
    from tai_coll.neighbors.hash_grid import FORWARD_SORTED, FULL, NEIGHBOUR_CAPACITY

    rng = np.random.default_rng(7)
    x = np.concatenate([rng.uniform(-0.3, 0.3, (400, 3)), rng.uniform(-0.01, 0.01, (60, 3)) + 0.5])
    radius = rng.uniform(0.01, 0.02, len(x))
    n, margin = len(x), 0.004
    grid = grid_of(x, radius, margin, forward)
    packed = grid.own_lists(n)
    dropped = grid.dropped()
    flags = on_device(np.zeros(n, int))
    hash_grid._neighbours(grid=grid.args, flags=flags, n=n, inv_cell=grid.inv_cell, margin=margin, margin_radii=0.0,
                          forward=FORWARD_SORTED if forward else FULL, local=False, block=1, awake_only=False,
                          rest=flags, lists=grid.lists, touching=grid.touching, overflow=grid.overflow,
                          listed_any=grid.listed, awake=grid.overflow)
    first = grid.first.to_numpy()[:n]
    slot_of = np.empty(n, int)
    slot_of[grid.entries.to_numpy()[:n]] = np.arange(n)
    assert np.array_equal(first, slot_of * NEIGHBOUR_CAPACITY)
    rows = grid.own_lists(n)
    assert dropped > 0 and grid.dropped() == 2 * dropped
    for i in range(n):
        assert np.array_equal(rows[i], packed[i]), i


@pytest.mark.parametrize("interleaved", [False, True])
@pytest.mark.parametrize("n", [1, 5, 255, 257, 1000])
def test_cell_span_is_the_active_particles_lowest_and_highest_cell(n, interleaved):
    # Both ways of sharing the particles among threads (runs on a CPU, every blocks-th on a
    # GPU), with counts below, just above and well above one share or one run each; the
    # particles after the first n, and inactive ones, are left out.
    import taichi as ti

    from tai_coll import runtime
    from tai_coll.neighbors.hash_grid import cell_span
    from tai_coll.types import ACTIVE

    rng = np.random.default_rng(n)
    cell = 0.01
    x = rng.uniform(-0.5, 0.7, (n + 3, 3))
    x[n:] = 50.0  # beyond n: not counted
    flags = np.full(n + 3, ACTIVE, np.int32)
    if n > 1:
        x[0] = (-9.0, 9.0, 0.0)  # far, but not active
        flags[0] = ACTIVE + 1
    xs, fs = on_device(x), on_device(flags)
    bounds = ti.ndarray(ti.i32, shape=6)
    lo, hi = cell_span(xs, fs, n, 1.0 / cell, bounds, interleaved)
    xd = x.astype(runtime.float_dtype())  # the kernel's arithmetic: floor(x / cell) in its precision
    cells = np.floor(xd[:n][flags[:n] == ACTIVE] * xd.dtype.type(1.0 / cell)).astype(int)
    assert np.array_equal(lo, cells.min(axis=0)) and np.array_equal(hi, cells.max(axis=0))
    fs_none = on_device(np.full(n + 3, ACTIVE + 1, np.int32))
    assert cell_span(xs, fs_none, n, 1.0 / cell, bounds, interleaved) is None


def test_table_bits_follow_the_particles_extent():
    # Each axis gets the bits its extent in cells plus the query's cell on either side needs,
    # at least MIN_BITS; past the table's total, bits come off the axis holding the most (z,
    # then y, before x); unknown extents share the bits evenly.
    from tai_coll.neighbors.hash_grid import MIN_BITS, table_bits

    assert table_bits([127, 6, 127], 18) == (8, 3, 7)  # the benchmark's 100k bed: 129 columns
    assert table_bits([30, 2, 30], 18) == (5, 3, 5)  # everything fits: bits left unused
    assert table_bits([1, 1, 1], 11) == MIN_BITS
    assert table_bits([5000, 3, 3], 18) == (12, 3, 3)
    assert table_bits([1, 70000, 1], 18) == (4, 11, 3)
    assert table_bits([1000, 1000, 10], 18) == (7, 7, 4)
    assert table_bits(None, 18) == (6, 6, 6)


@pytest.mark.parametrize("forward", [False, True])
def test_a_flat_bed_gets_a_flat_table_and_the_lists_of_brute_force(forward):
    # A layer 25 cells wide and 3 deep, away from the origin: the table follows its shape (2^5
    # x 2^3 x 2^5 buckets, where an even split of the 13 bits would put up to four of its
    # cells in a bucket) and the lists are those of brute force.
    rng = np.random.default_rng(9)
    n = 3000
    x = np.column_stack([rng.uniform(0, 0.5, n), rng.uniform(0, 0.06, n), rng.uniform(0, 0.5, n)]) - [0.3, 3.0, 7.1]
    radius = np.full(n, 0.009)
    margin = 0.002
    grid = grid_of(x, radius, margin, forward)
    cells = np.floor(x * grid.inv_cell).astype(np.int64)
    extent = cells.max(axis=0) - cells.min(axis=0) + 1
    assert tuple(int(b) for b in grid.bits) == (5, 3, 5)
    assert np.all(2 ** np.array(list(grid.bits)) >= extent + 2)
    assert_lists_match_brute_force(grid, x, radius, margin, forward)


def test_grid_entries_order_every_particle():
    # Particles no longer simulated sit after the simulated ones, in a bucket no query visits.
    rng = np.random.default_rng(4)
    n = 300
    x = rng.uniform(-0.2, 0.2, (n, 3))
    status = (rng.uniform(size=n) < 0.2).astype(np.int32)
    xs, rs, flags = on_device(x), on_device(np.full(n, 0.02)), on_device(status)
    grid = HashGrid()
    grid.sort(xs, rs, flags, n, 0.04)
    n_buckets = grid.n_buckets
    entries = grid.entries.to_numpy()[:n]
    active = int(grid.starts.to_numpy()[n_buckets])
    assert np.array_equal(np.sort(entries), np.arange(n))
    assert active == np.count_nonzero(status == 0)
    assert np.all(status[entries[:active]] == 0) and np.all(status[entries[active:]] != 0)
    grid.build(xs, rs, flags, n, 0.05, 0.01)
    lists = grid.neighbour_lists(n)
    assert all(np.all(status[lst] == 0) for lst in lists)


@ti.kernel
def scan_for_test(counts: ti.types.ndarray(), n: ti.i32, block: ti.template(), block_sums: ti.types.ndarray(),
                  starts: ti.types.ndarray()):
    sorting.exclusive_scan(counts, n, block_sums, block, starts)


@pytest.mark.parametrize("block", [sorting.SCAN_BLOCK, sorting.SCAN_BLOCK_GPU])
@pytest.mark.parametrize("n", [1, 255, 256, 257, 70_000, 1_100_001])
def test_prefix_sum_over_blocks_and_groups_of_blocks(n, block):
    # both block lengths (the CPU's and a GPU's) on any arch, across block and group edges: 70,000
    # bins make 2 groups of GPU blocks, 1,100,001 make 2 groups of CPU blocks and 17 of GPU ones
    rng = np.random.default_rng(n)
    counts = rng.integers(0, 5, n).astype(np.int32)
    counts[rng.integers(0, n, 3)] = 100_000  # large counts: the sums are exact integers
    block_sums = np.full(sorting.scan_blocks(n - 1), -7, dtype=np.int32)
    starts = np.full(n + 1, -7, dtype=np.int32)
    scan_for_test(counts, n, block, block_sums, starts)
    assert np.array_equal(starts, np.concatenate([[0], np.cumsum(counts)]))


def test_grid_sort_on_a_table_of_many_scan_blocks():
    # 20,000 particles: a table of 2^16 buckets, 64 blocks of the prefix sum. starts is the
    # exclusive prefix sum of counts, each bucket's entries are its particles in increasing
    # order, and sorted_xr holds their positions and radii.
    from tai_coll.sorting import SCAN_BLOCK

    rng = np.random.default_rng(5)
    n = 20_000
    x = rng.uniform(-1.0, 1.0, (n, 3))
    xs, rs, flags = on_device(x), on_device(np.full(n, 0.01)), on_device(np.zeros(n, int))
    grid = HashGrid()
    grid.sort(xs, rs, flags, n, 0.03)
    n_buckets, inv_cell, bits = grid.n_buckets, grid.inv_cell, grid.bits
    assert n_buckets // SCAN_BLOCK >= 32
    counts = grid.counts.to_numpy()[: n_buckets + 1]
    starts = grid.starts.to_numpy()[: n_buckets + 2]
    assert np.array_equal(starts[: n_buckets + 1], np.concatenate([[0], np.cumsum(counts)[:-1]]))
    assert starts[n_buckets] == n and counts[n_buckets] == 0
    cell = np.floor(x * inv_cell).astype(np.int64)
    mask = (1 << np.array(list(bits))) - 1
    bucket = ((cell[:, 0] & mask[0]) | ((cell[:, 1] & mask[1]) << bits[0])
              | ((cell[:, 2] & mask[2]) << (bits[0] + bits[1])))
    entries = grid.entries.to_numpy()[:n]
    order = np.lexsort((np.arange(n), bucket))  # by bucket, then by index
    assert np.array_equal(entries, order)
    assert np.allclose(grid.sorted_xr.to_numpy()[:n], np.hstack([x[order], np.full((n, 1), 0.01)]))


def test_particle_overlap_matches_brute_force():
    # The statistics come straight from the sorted grid: every overlapping pair, relative to
    # the smaller radius, counted once; mixed radii and negative coordinates.
    rng = np.random.default_rng(8)
    n = 400
    x = rng.uniform(-0.25, 0.25, (n, 3)) - [4.0, 0.5, 7.0]
    radius = rng.uniform(0.01, 0.04, n)
    scene = tc.Scene()
    scene.enable_particle_collisions()
    scene.add_particles(positions=x, radius=radius)
    stats = scene.particle_overlap()
    dist = np.linalg.norm(x[:, None, :] - x[None, :, :], axis=2)
    i, j = np.triu_indices(n, 1)
    rel = (radius[i] + radius[j] - dist[i, j]) / np.minimum(radius[i], radius[j])
    rel = rel[rel > 0]
    assert stats["pairs"] == len(rel) > 50
    assert stats["max"] == pytest.approx(rel.max(), rel=1e-5)
    assert stats["mean"] == pytest.approx(rel.mean(), rel=1e-5)


def test_full_neighbour_lists_are_warned_about_once():
    # A contact margin of four radii: a cluster on a 10.5 mm lattice sees about 100 others
    # within reach.
    import warnings

    scene = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=1e-4, substeps=2)
    pairs = scene.enable_particle_collisions(contact_margin=0.02)
    g = 0.0105 * np.arange(8)
    X, Y, Z = np.meshgrid(g, g, g, indexing="ij")
    scene.add_particles(positions=np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1), radius=0.005)
    with pytest.warns(RuntimeWarning, match=r"neighbour lists were full .* more than 48 others"):
        scene.step()
    dropped = pairs.neighbour_overflow
    assert dropped > 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene.step()  # once per scene
    assert pairs.neighbour_overflow > dropped
    # the default margin (a quarter of the smaller radius of each pair): no list is full,
    # nothing to warn about, even beside a particle twenty times larger
    calm = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=1e-4, substeps=2)
    calm.enable_particle_collisions()
    calm.add_particles(positions=np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1), radius=0.005)
    calm.add_particles(positions=[[0.037, 0.2, 0.037]], radius=0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        calm.step()


# ---------------------------------------------------------------- the store in cell order
def test_reordering_keeps_the_public_order():
    # The pair solver puts the store in cell order; what the scene reads and writes is
    # still in the order the particles were added, and the physics is the same (with Jacobi
    # passes, whose result does not depend on the order of the particles).
    rng = np.random.default_rng(7)
    n = 400
    x = rng.uniform([-0.1, 0.01, -0.1], [0.1, 0.3, 0.1], (n, 3))
    mass = rng.uniform(1.0, 2.0, n)
    radius = rng.uniform(0.008, 0.012, n)
    runs = {}
    for reorder in (False, True):
        scene, _ = pile_scene(reorder=reorder, method="jacobi")
        scene.add_particles(positions=x, mass=mass, radius=radius)
        scene.step(20)
        runs[reorder] = scene
    slots = runs[True]._particles._slots()
    assert slots is not None and not np.array_equal(slots, np.arange(n))  # the store was permuted
    assert runs[False]._particles._slots() is None
    assert np.array_equal(runs[True].ids(), np.arange(n)) and np.array_equal(runs[False].ids(), np.arange(n))
    assert np.array_equal(runs[True].masses(), runs[False].masses())
    assert np.array_equal(runs[True].radii(), runs[False].radii())
    # the same physics: only the order of each particle's sum over neighbours differs
    assert np.allclose(runs[True].positions(), runs[False].positions(), atol=1e-9)
    assert np.allclose(runs[True].velocities(), runs[False].velocities(), atol=1e-6)
    # writes and appends in public order
    scene = runs[True]
    v = rng.normal(size=(n, 3))
    scene.set_velocities(v)
    assert np.array_equal(scene.velocities(), v)
    extra = np.array([[0.5, 0.5, 0.5], [0.6, 0.5, 0.5]])
    scene.add_particles(positions=extra, radius=0.01)
    assert np.array_equal(scene.positions()[n:], extra)
    assert np.array_equal(scene.velocities()[:n], v)
    assert np.array_equal(scene.radii()[:n], radius)
    scene.step(1)
    assert np.all(scene.particle_status() == "active")


def test_store_permute_moves_every_quantity():
    from tai_coll.scene.particles import ParticleStore
    import taichi as ti

    rng = np.random.default_rng(2)
    n = 50
    store = ParticleStore(capacity=64)
    x, v = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    mass, radius = rng.uniform(1, 2, n), rng.uniform(0.1, 0.2, n)
    store.add(x, v, mass, radius)
    store.clearance.from_numpy(np.arange(64, dtype=store.clearance.to_numpy().dtype))
    order = rng.permutation(n)
    perm = ti.ndarray(ti.i32, shape=n)
    perm.from_numpy(order.astype(np.int32))
    store.permute(perm, n)
    assert np.array_equal(store.x.to_numpy()[:n], x[order])  # slot k holds what slot order[k] held
    assert np.array_equal(store.clearance.to_numpy()[:n], order)
    for name, values in (("x", x), ("v", v), ("mass", mass), ("radius", radius)):
        assert np.array_equal(store.read(name), values), name
    store.add(x[:30], v[:30], mass[:30], radius[:30])  # grows past the capacity: slots kept
    assert store.capacity >= n + 30 and np.array_equal(store.x.to_numpy()[:n], x[order])
    assert np.array_equal(store.read("x"), np.concatenate([x, x[:30]]))
    assert np.array_equal(store.public_ids(), np.arange(n + 30))
    keep = np.ones(n + 30, dtype=bool)
    keep[[0, 7, n + 3]] = False  # slots: two of the permuted particles and a new one
    store.compact(keep)
    gone = {int(order[0]), int(order[7]), n + 3}
    left = np.array([k for k in range(n + 30) if k not in gone])
    assert np.array_equal(store.public_ids(), left)  # ascending, the removed ids gone
    assert np.array_equal(store.read("x"), np.concatenate([x, x[:30]])[left])
    assert np.array_equal(store.read("mass"), np.concatenate([mass, mass[:30]])[left])
    with pytest.raises(ValueError, match="n must be"):
        store.permute(perm, n - 1)


# ---------------------------------------------------------------- Verlet lists (skin > 0)
def test_head_on_with_lists_kept_between_substeps():
    # Verlet lists (skin > 0): rebuilt only when a particle has moved skin / 2 since the
    # last build; the pair approaching at 2 m/s is still caught and follows the textbook law.
    ma, mb, va, vb, e = 1.0, 3.0, 1.0, -1.0, 0.5
    scene = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=1e-4, substeps=10)
    pairs = scene.enable_particle_collisions(material=tc.Material(restitution=e), verlet_skin=0.025)
    scene.add_particles(positions=[[-0.1, 0, 0], [0.1, 0, 0]], velocities=[[va, 0, 0], [vb, 0, 0]],
                        mass=np.array([ma, mb]), radius=0.05)
    scene.step(150)
    v = scene.velocities()
    assert v[0, 0] == pytest.approx((ma * va + mb * vb - mb * e * (va - vb)) / (ma + mb), rel=0.01)
    assert v[1, 0] == pytest.approx((ma * va + mb * vb + ma * e * (va - vb)) / (ma + mb), rel=0.01)
    assert np.allclose(ma * v[0] + mb * v[1], [ma * va + mb * vb, 0, 0], atol=1e-12)
    # each moves 0.1 mm a substep: a rebuild every 62 substeps or so (skin / 2 = 12.5 mm)
    # until they meet, a few while they touch and part
    assert 10 <= pairs.list_builds < 200


def test_resting_stack_keeps_its_lists():
    r = 0.01
    scene, pairs = pile_scene(verlet_skin=0.5 * r)
    scene.add_particles(positions=[[0, r + k * 2.05 * r, 0] for k in range(10)], radius=r)
    scene.step(60)
    builds = pairs.list_builds
    scene.step(40)
    assert pairs.list_builds == builds  # at rest: 200 substeps on the same lists
    assert_stack_rests_in_contact(scene, r, 10)
    # a write from the host drops the lists: the stack moved sideways is listed anew
    builds = pairs.list_builds  # (particle_overlap sorted the grid anew: the lists were rebuilt)
    scene.set_positions(scene.positions() + [0.5, 0.0, 0.0])
    scene.step(1)
    assert pairs.list_builds == builds + 1
    # (the write woke the sleeping stack: it settles again, at up to 17 mm/s for a few frames)
    scene.step(100)
    assert_stack_rests_in_contact(scene, r, 10)


def dem_box_pile(skin, springs, spin):
    """125 particles (r = 10 mm) on a jittered lattice with random velocities in a box of
    planes: DEM pairs (200 Hz), 0.03 s of collisions, contacts forming and ending; skin: the
    Verlet lists' (m)."""
    r, half = 0.01, 0.06
    scene = tc.Scene(dt=1e-4, substeps=10, solver=tc.PenaltySolver(hertz=200.0, spin=spin))
    material = tc.Material(restitution=0.2, friction=0.4, rolling_friction=0.1 if spin else 0.0)
    add_box_of_planes(scene, half, material)
    pairs = scene.enable_particle_collisions(material=material, tangential_springs=springs, verlet_skin=skin)
    g = np.arange(-half + 1.5 * r, half - 1.4 * r, 2.2 * r)
    X, Y, Z = np.meshgrid(g, r + 2.2 * r * np.arange(5), g, indexing="ij")
    x = np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1)
    rng = np.random.default_rng(3)
    scene.add_particles(positions=x + rng.uniform(-0.1 * r, 0.1 * r, x.shape),
                        velocities=rng.normal(0.0, 0.2, x.shape), radius=r)
    scene.step(30)
    return scene, pairs


@pytest.mark.parametrize("springs, spin", [(False, False), (True, True)])
def test_dem_lists_find_the_contacts_the_grid_finds(springs, spin):
    # The DEM kernel reading Verlet lists (skin > 0: built from the grid, kept until some
    # particle has moved skin / 2) against the kernel querying the grid sorted every substep:
    # the same contacts, so the same motion (to round-off: only the order the forces are summed
    # in differs). Measured: positions 1e-17, velocities 3e-16, spins 5e-15.
    grid, _ = dem_box_pile(0.0, springs, spin)
    listed, pairs = dem_box_pile(0.003, springs, spin)
    assert grid.particle_overlap()["pairs"] > 10  # contacts at the end, many more on the way
    assert 2 <= pairs.list_builds < 100  # of 300 substeps
    assert np.allclose(listed.positions(), grid.positions(), rtol=0.0, atol=1e-12)
    assert np.allclose(listed.velocities(), grid.velocities(), rtol=0.0, atol=1e-10)
    assert np.allclose(listed.angular_velocities(), grid.angular_velocities(), rtol=0.0, atol=1e-9)


def test_dem_lists_too_full_fall_back_to_the_grid():
    # A particle with more neighbours than the lists keep (60 > NEIGHBOUR_CAPACITY): the DEM
    # kernel queries the grid instead until the lists are built again, and every contact
    # acts (one substep from rest, no gravity: v = dt/m sum of k overlap n).
    from tai_coll.neighbors.hash_grid import NEIGHBOUR_CAPACITY

    k, dt, count = 3e3, 1e-5, 60
    assert count > NEIGHBOUR_CAPACITY
    x, radius, mass = crowded_particle(count, 8)
    scene = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=dt, substeps=1, solver=tc.PenaltySolver(stiffness=k, damping=0.0))
    # (max_push_speed=inf: the law on the overlap these particles are placed with)
    pairs = scene.enable_particle_collisions(material=tc.Material(friction=0.5), verlet_skin=0.1 * radius.max(),
                                             max_push_speed=math.inf)
    scene.add_particles(positions=x, radius=radius, mass=mass)
    scene.step(1)
    assert pairs.grid.dropped() > 0 and pairs.list_builds == 1
    expected, touching = spring_law_velocities(x, radius, mass, k, dt)
    assert touching[0].sum() == count
    assert np.allclose(scene.velocities(), expected, rtol=1e-4, atol=1e-9 * np.abs(expected).max())
