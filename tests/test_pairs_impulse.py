"""Particles hitting particles with impulses (docs/physics.md 2, two movable bodies), by closed
form: two-body laws, stacks and piles, the Gauss-Seidel and Jacobi passes, the projection
and the settle pass."""

import math

import numpy as np
import pytest

import tai_coll as tc
from tai_coll.solvers.pairs import gauss_seidel
from conftest import FLOOR, TEST_ARCH, assert_stack_rests_in_contact, grid_of, on_device, pile_scene


# ---------------------------------------------------------------- two bodies
def pair_scene(*, restitution, friction=0.0, dt=1e-4, substeps=10, **options):
    """Impulse pairs without gravity; options: those of enable_particle_collisions."""
    scene = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=dt, substeps=substeps)
    scene.enable_particle_collisions(material=tc.Material(restitution=restitution, friction=friction), **options)
    return scene


def test_head_on_masses_one_and_three():
    # Textbook: v_a' = (m_a v_a + m_b v_b - m_b e (v_a - v_b)) / (m_a + m_b), and for b swap.
    ma, mb, va, vb, e = 1.0, 3.0, 1.0, -1.0, 0.5
    scene = pair_scene(restitution=e)
    scene.add_particles(positions=[[-0.1, 0, 0], [0.1, 0, 0]], velocities=[[va, 0, 0], [vb, 0, 0]],
                        mass=np.array([ma, mb]), radius=0.05)
    scene.step(150)
    v = scene.velocities()
    expected_a = (ma * va + mb * vb - mb * e * (va - vb)) / (ma + mb)
    expected_b = (ma * va + mb * vb + ma * e * (va - vb)) / (ma + mb)
    assert v[0, 0] == pytest.approx(expected_a, rel=0.01)
    assert v[1, 0] == pytest.approx(expected_b, rel=0.01)
    momentum = ma * v[0] + mb * v[1]
    assert np.allclose(momentum, [ma * va + mb * vb, 0, 0], atol=1e-12)


def test_glancing_collision_with_friction_follows_the_pair_law():
    # Equal masses, impact parameter b: the contact normal makes asin(b / (2r)) with the
    # x axis. The outcome is the pair law along that normal (tc.collide_pair).
    r, b, e, mu = 0.05, 0.05, 0.8, 0.2
    scene = pair_scene(restitution=e, friction=mu, dt=2e-5)
    scene.add_particles(positions=[[-0.095, b, 0], [0.0, 0.0, 0.0]], velocities=[[2.0, 0, 0], [0, 0, 0]], radius=r)
    scene.step(60)
    v = scene.velocities()
    angle = np.arcsin(b / (2 * r))
    normal = np.array([-np.cos(angle), np.sin(angle), 0.0])  # from b to a at contact
    va, vb = tc.collide_pair([2.0, 0, 0], [0, 0, 0], normal, 1.0, 1.0, restitution=e, friction=mu)
    assert np.allclose(v[0], va, atol=0.02 * 2.0)
    assert np.allclose(v[1], vb, atol=0.02 * 2.0)
    assert np.allclose(v.sum(axis=0), [2.0, 0, 0], atol=1e-12)  # momentum, to round-off
    # friction took tangential speed: b's velocity is not along the normal only
    assert abs(np.cross(v[1], normal)[2]) > 1e-3


def test_newtons_cradle_passes_the_velocity_down_the_row():
    r, gap = 0.01, 1e-4
    n = 5
    scene = pair_scene(restitution=1.0, dt=2e-5)
    x = np.array([[k * (2 * r + gap), 0, 0] for k in range(n)])
    v = np.zeros((n, 3))
    v[0, 0] = 1.0
    scene.add_particles(positions=x, velocities=v, radius=r)
    scene.step(100)
    out = scene.velocities()[:, 0]
    assert out[-1] == pytest.approx(1.0, rel=0.01)
    assert np.all(np.abs(out[:-1]) < 0.01)
    assert out.sum() == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("method", ["gauss-seidel", "jacobi"])
def test_coincident_centres_are_separated_keeping_momentum(method):
    # Two particles placed at one point (no normal from their centres: the pair's hashed axis,
    # response.laws.coincident_axis), moving with one velocity: overlap they start with is not a
    # collision. It goes by positions only, exactly max_push_speed * dt a substep, and their
    # velocities stay as they were; the centre of mass moves on with the momentum.
    ma, mb, r = 1.0, 3.0, 0.05
    v0 = np.array([0.3, 0.5, -0.1])
    scene = pair_scene(restitution=0.5, friction=0.3, dt=1e-3, substeps=5, method=method)
    push = scene.particle_collisions.settings.max_push_speed
    scene.add_particles(positions=[[0.1, 0.2, -0.3]] * 2, velocities=[v0, v0], mass=np.array([ma, mb]), radius=r)
    for frame in range(1, 46):
        scene.step(1)
        x, v = scene.positions(), scene.velocities()
        assert np.all(np.isfinite(x)) and np.all(np.isfinite(v))
        # no speed from the overlap, to round-off: the hashed axis has three components, and
        # x + dt v rounds differently at the two positions (at most 1.5e-14 m/s seen)
        assert np.allclose(v, [v0, v0], rtol=0.0, atol=1e-12)
        distance = min(2 * r, frame * scene.substeps * push * scene.dt)
        assert np.linalg.norm(x[0] - x[1]) == pytest.approx(distance, rel=1e-6)
        centre = (ma * x[0] + mb * x[1]) / (ma + mb)
        assert np.allclose(centre, np.array([0.1, 0.2, -0.3]) + scene.time * v0, atol=1e-9)
    assert np.linalg.norm(x[0] - x[1]) >= 2 * r * (1 - 1e-6)  # touching after 2 r / push


@pytest.mark.parametrize("method", ["gauss-seidel", "jacobi"])
def test_coincident_centres_approaching_collide_by_the_pair_law(method):
    # The same pair with different velocities: the impulses between them are a collision
    # (momentum kept, no energy gained); the overlap they started with still goes by positions.
    ma, mb, r = 1.0, 3.0, 0.05
    va, vb = np.array([0.3, 0.5, 0.0]), np.array([0.0, -0.2, 0.1])
    energy = 0.5 * (ma * va @ va + mb * vb @ vb)
    scene = pair_scene(restitution=0.5, friction=0.3, dt=1e-3, substeps=5, method=method)
    scene.add_particles(positions=[[0.1, 0.2, -0.3]] * 2, velocities=[va, vb], mass=np.array([ma, mb]), radius=r)
    for _ in range(45):
        scene.step(1)
        x, v = scene.positions(), scene.velocities()
        assert np.all(np.isfinite(x)) and np.all(np.isfinite(v))
        assert np.allclose(ma * v[0] + mb * v[1], ma * va + mb * vb, atol=1e-9)
        assert 0.5 * (ma * v[0] @ v[0] + mb * v[1] @ v[1]) <= energy * (1 + 1e-9)
    assert np.linalg.norm(x[0] - x[1]) >= 2 * r * (1 - 1e-4)


# ---------------------------------------------------------------- stacks and piles
def pass_method(method, monkeypatch):
    """The method to ask for; "gauss-seidel, GPU units": Gauss-Seidel coloured as on a GPU
    (units of gauss_seidel.UNIT_BITS, no slabs), here on the CPU."""
    if method == "gauss-seidel, GPU units":
        monkeypatch.setattr(gauss_seidel, "colouring", lambda: dict(slabs=0, unit_bits=gauss_seidel.UNIT_BITS))
        return "gauss-seidel"
    return method


@pytest.mark.parametrize("method", ["gauss-seidel", "gauss-seidel, GPU units", "jacobi"])
def test_stack_on_a_floor_comes_to_rest(method, monkeypatch):
    method = pass_method(method, monkeypatch)
    r = 0.01
    scene, _ = pile_scene(method=method)
    scene.add_particles(positions=[[0, r + k * 2.05 * r, 0] for k in range(10)], radius=r)
    scene.step(100)
    assert_stack_rests_in_contact(scene, r, 10)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["gauss-seidel", "jacobi"])
def test_pile_in_a_box_settles(method):
    # 10,000 particles dropped into a box of planes: the pile's overlap stays small, no
    # particle escapes, kinetic energy decays to near zero.
    r, half = 0.01, 0.25
    scene, _ = pile_scene(box=half, method=method)
    rng = np.random.default_rng(0)
    g = np.arange(-half + 1.5 * r, half - 1.5 * r, 2.3 * r)
    X, Y, Z = np.meshgrid(g, np.arange(0.02, 3.0, 2.3 * r), g, indexing="ij")
    x = np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1)
    x = x[np.argsort(x[:, 1], kind="stable")][:10_000] + rng.uniform(-0.1 * r, 0.1 * r, (10_000, 3))
    scene.add_particles(positions=x, radius=r)
    energy = []
    for _ in range(12):
        scene.step(25)
        v = scene.velocities()
        energy.append(0.5 * float((v * v).sum()))
    overlap = scene.particle_overlap()
    x = scene.positions()
    assert overlap["mean"] < 0.05 and overlap["max"] < 0.20, overlap
    assert np.all(np.abs(x[:, [0, 2]]) <= half) and x[:, 1].min() >= r * (1 - 1e-3)
    assert energy[-1] < 1e-3 * max(energy), energy
    assert np.all(scene.particle_status() == "active")


@pytest.mark.parametrize("method", ["gauss-seidel", "jacobi"])
def test_passes_run_to_their_count_unread_give_the_same_state(method, monkeypatch):
    # A GPU does not read whether a pass changed anything (a read waits for every kernel
    # launched before it): the passes run their full count. A pass after one that found nothing
    # to do finds nothing either, so a pile falling into a box onto a sphere ends bit for bit
    # where the early stop takes it, while the flags are read fewer times.
    from tai_coll.solvers.pairs import collisions

    reads = []

    def pile(read_flags):
        monkeypatch.setattr(collisions, "reads_pass_flags", lambda: read_flags)
        monkeypatch.setattr(collisions.ParticleCollisions, "_changed",
                            lambda self: reads.append(read_flags) or bool(self.changed[0]))
        scene, _ = pile_scene(box=0.06, method=method)
        scene.add_collider(tc.Sphere(center=(0.0, 0.0, 0.0), radius=0.03))
        rng = np.random.default_rng(4)
        scene.add_particles(positions=rng.uniform((-0.05, 0.03, -0.05), (0.05, 0.12, 0.05), (600, 3)), radius=0.004)
        scene.step(40)
        return scene.positions(), scene.velocities()

    x_read, v_read = pile(True)
    x_full, v_full = pile(False)
    assert np.array_equal(x_read, x_full) and np.array_equal(v_read, v_full)
    assert reads.count(True) >= 5 * 40 and reads.count(False) == 0, (reads.count(True), reads.count(False))


@pytest.mark.parametrize("options", [{}, {"verlet_skin": 0.004}], ids=["lists-each-substep", "kept-lists"])
def test_passes_over_lists_without_pairs_are_skipped_to_the_same_state(options, monkeypatch):
    # Gauss-Seidel passes over lists that hold no pair change nothing, so where the pass flags
    # are read (the CPU) they are not launched. Columns of particles falling onto a floor, each
    # particle apart from the others until the upper ones land on the lower (pairs appear),
    # with sleeping on, end where passes launched every substep take them.
    from tai_coll.neighbors import hash_grid
    from tai_coll.solvers.pairs import collisions, gauss_seidel

    real_pass, real_listed = gauss_seidel._pass, hash_grid.HashGrid.listed_any
    launches, listed = [], []
    monkeypatch.setattr(gauss_seidel, "_pass", lambda **kw: launches.append(1) or real_pass(**kw))
    monkeypatch.setattr(hash_grid.HashGrid, "listed_any",
                        lambda self: listed.append(real_listed(self)) or listed[-1])

    def columns(skip):
        if not skip:
            monkeypatch.setattr(hash_grid.HashGrid, "listed_any", lambda self: True)
        launches.clear()
        # (short substeps: the elastic pass of a particle without pairs once left round-off on
        # its velocity here, fast math reordering v1 + (vi - v_test))
        scene = tc.Scene(dt=1e-4, substeps=10)
        scene.add_collider(tc.Plane(), material=tc.Material(restitution=0.6, friction=0.4))
        scene.enable_particle_collisions(material=tc.Material(restitution=0.2, friction=0.4), sleep_time=0.05,
                                         **options)
        r = 0.005
        lows = [[x, r + 0.002 * k, 0.0] for k, x in enumerate((0.0, 0.05, 0.1))]
        highs = [[x, 0.03 + 0.01 * k, 0.0] for k, x in enumerate((0.0, 0.05, 0.1))]
        lone = [[0.3, 0.2 + r, 0.0]]  # (falling alone throughout)
        scene.add_particles(positions=lows + highs + lone, radius=r)
        scene.step(120)
        return scene.positions(), scene.velocities(), scene.sleeping(), len(launches)

    x_skip, v_skip, asleep_skip, skipped = columns(skip=True)
    assert True in listed and False in listed  # (apart at first, touching once the upper ones land)
    x_all, v_all, asleep_all, every = columns(skip=False)
    assert np.array_equal(x_skip, x_all) and np.array_equal(v_skip, v_all) and np.array_equal(asleep_skip, asleep_all)
    assert np.all(x_skip[3:6, 1] > x_skip[:3, 1] + 1.9 * 0.005)  # (each upper particle rests on its lower one)
    if collisions.reads_pass_flags():
        assert skipped < every, (skipped, every)


@pytest.mark.parametrize("ground", ["height_field", "triangle_mesh", "mesh_sdf"])
def test_pile_on_terrain_and_meshes_stays_outside(ground):
    # Particle-particle collisions together with the other collider kinds: a small heap
    # poured onto a bowl-shaped terrain, a closed icosphere mesh and its baked grid ends with
    # no particle inside the ground and little overlap.
    import trimesh

    r = 0.02
    if ground == "height_field":
        x = np.linspace(-0.5, 0.5, 21)
        X, Z = np.meshgrid(x, x, indexing="ij")
        shape = tc.HeightField(heights=0.5 * (X ** 2 + Z ** 2), cell_size=0.05, origin=(-0.5, 0.0, -0.5))
        top = 0.05
    else:
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.3)
        shape = (tc.TriangleMesh(mesh) if ground == "triangle_mesh"
                 else tc.MeshSDF(mesh, resolution=48, cache=False))
        top = 0.3
    scene = tc.Scene(dt=1 / 1000, substeps=5)
    scene.add_collider(shape, material=tc.Material(restitution=0.2, friction=0.5))
    scene.enable_particle_collisions(material=tc.Material(restitution=0.2, friction=0.5))
    g = np.arange(-0.08, 0.081, 2.3 * r)
    X, Y, Z = np.meshgrid(g, top + 2 * r + 2.3 * r * np.arange(3), g, indexing="ij")
    scene.add_particles(positions=np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1), radius=r)
    lowest = np.inf
    for _ in range(20):
        scene.step(5)
        lowest = min(lowest, float(shape.signed_distance(scene.positions()).min()))
    # the mesh grid is trilinear: allow a few percent of a radius on its surface
    assert lowest > (0.95 if ground == "mesh_sdf" else 0.99) * r
    assert scene.particle_overlap()["max"] < 0.2


def test_pile_sees_the_floor_after_particles_are_moved():
    # The collider passes skip particles whose kept clearance covers their move; moving the
    # particles by hand must drop the kept clearances (else they would fall through).
    scene = tc.Scene(dt=1 / 1000, substeps=5)
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(restitution=0.0))
    scene.enable_particle_collisions(material=tc.Material(restitution=0.0))
    r = 0.01
    scene.add_particles(positions=[[0.0, 3.0, 0.0], [0.5, 3.0, 0.0]], radius=r)
    scene.step(2)  # clearances of about 3 m are kept
    scene.set_positions([[0.0, 0.015, 0.0], [0.5, 0.015, 0.0]])
    scene.set_velocities([[0.0, -4.0, 0.0], [0.0, -4.0, 0.0]])
    scene.step(5)
    assert np.all(scene.positions()[:, 1] >= r * (1 - 2e-3)), scene.positions()


# ---------------------------------------------------------------- the passes: Gauss-Seidel units, projection, settle
def bucket_coords(grid):
    """The table coordinates (x, y, z) of the bucket of every sorted entry, and the entries."""
    bits = [int(b) for b in grid.bits]
    starts = grid.starts.to_numpy()
    active = int(starts[grid.n_buckets])
    bucket = np.repeat(np.arange(grid.n_buckets), np.diff(starts[: grid.n_buckets + 1]))
    coords = np.stack([bucket & ((1 << bits[0]) - 1), (bucket >> bits[0]) & ((1 << bits[1]) - 1),
                       bucket >> (bits[0] + bits[1])], 1)
    return coords, grid.entries.to_numpy()[:active]


def gauss_seidel_groups(grid, n, layout):
    """Per particle: the colour and the group (an id) the coloured passes give it, recomputed on
    the host from the grid's buckets (see tai_coll.solvers.pairs.gauss_seidel); layout: "slabs"
    (the CPU's, at most MAX_SLABS along z in two colours) or a GPU unit's bits."""
    coords, entries = bucket_coords(grid)
    if layout == "slabs":
        bz = int(grid.bits[2])
        slabs = min(1 << (bz - 1), gauss_seidel.MAX_SLABS)
        group = coords[:, 2] // ((1 << bz) // slabs)
        colour = group & 1
    else:
        unit = coords >> np.array(layout)
        colour = (unit[:, 0] & 1) | ((unit[:, 1] & 1) << 1) | ((unit[:, 2] & 1) << 2)
        group = unit[:, 0] + (unit[:, 1] << 16) + (unit[:, 2] << 32)
    per_colour, per_group = np.full(n, -1), np.full(n, -1)
    per_colour[entries], per_group[entries] = colour, group
    return per_colour, per_group


@pytest.mark.parametrize("layout", ["slabs", gauss_seidel.UNIT_BITS], ids=["cpu slabs", "gpu units"])
@pytest.mark.parametrize("spread", [0.3, 40.0])
def test_gauss_seidel_groups_of_a_colour_share_no_particle(spread, layout):
    # The coloured passes resolve the groups (slabs, units) of one colour at the same time: what
    # one group's pairs touch (its particles and their listed neighbours) must not meet what
    # another's touch. 30 dense clusters, close together or spread over many table widths
    # (wrap-around); the CPU's slabs and GPUs' units.
    rng = np.random.default_rng(11)
    n = 3000
    clusters = rng.uniform(-spread, spread, (30, 3)) - [3.1, 0.2, -7.7]
    x = clusters[np.arange(n) % 30] + rng.uniform(-0.12, 0.12, (n, 3))
    radius = rng.uniform(0.01, 0.02, n)
    grid = grid_of(x, radius, 0.005, forward=True)
    colour, unit = gauss_seidel_groups(grid, n, layout)
    assert np.all(colour >= 0)
    own = grid.own_lists(n)
    owner = np.repeat(np.arange(n), [len(row) for row in own])
    listed = np.concatenate(own)
    assert len(listed) > n // 2  # pairs enough to mean something
    # (particle touched, colour, unit) for the owners and for the neighbours they list
    touched = np.concatenate([np.arange(n), listed])
    by = np.concatenate([np.arange(n), owner])
    records = np.unique(np.stack([touched, colour[by], unit[by]], 1), axis=0)
    # at most one group of each colour touches any particle
    pairs = np.unique(records[:, :2], axis=0)
    assert len(pairs) == len(records)


@pytest.mark.parametrize("bits", [(4, 3, 3), (8, 3, 7), (6, 6, 6), (5, 8, 4)])
def test_gauss_seidel_units_of_each_colour_cover_the_table_once(bits):
    # The table's bits per axis follow the particles (hash_grid.table_bits): whatever its shape,
    # every unit of the table comes up once (unit_origin), in the colour of its parities.
    import taichi as ti

    unit_bits = gauss_seidel.UNIT_BITS
    per = [1 << (b - u - 1) for b, u in zip(bits, unit_bits)]
    units = per[0] * per[1] * per[2]
    origins = ti.ndarray(ti.i32, shape=8 * units)

    @ti.kernel
    def every_origin(bits: ti.types.vector(3, ti.i32), out: ti.types.ndarray()):
        for c in ti.static(range(8)):
            for u in range(units):
                out[c * units + u] = gauss_seidel.unit_origin(c, u, bits, unit_bits)

    every_origin(ti.Vector(list(bits)), origins)
    origin = origins.to_numpy()
    coords = np.stack([origin & ((1 << bits[0]) - 1), (origin >> bits[0]) & ((1 << bits[1]) - 1),
                       origin >> (bits[0] + bits[1])], 1)
    unit = coords >> np.array(unit_bits)
    assert np.all(coords == unit << np.array(unit_bits))  # unit corners
    colour = (unit[:, 0] & 1) | ((unit[:, 1] & 1) << 1) | ((unit[:, 2] & 1) << 2)
    assert np.array_equal(colour, np.repeat(np.arange(8), units))
    assert len(np.unique(origin)) == 8 * units == 1 << (sum(bits) - sum(unit_bits))


@pytest.mark.parametrize("bits", [(4, 3, 3), (8, 3, 7), (6, 6, 6), (5, 8, 4), (4, 3, 8), (4, 4, 12)])
def test_gauss_seidel_slabs_cover_the_table_once_in_alternating_colours(bits):
    # Whatever the table's shape, the CPU's slabs (slab_range) cut every bucket's entries into
    # consecutive ranges, each bucket in one slab, slabs alternating in colour along z, at
    # least two buckets thick, no more than MAX_SLABS (the 2^12 buckets along z of the last
    # shape: 64 slabs of 64 buckets).
    import taichi as ti

    n_buckets = 1 << sum(bits)
    slabs = min(1 << (bits[2] - 1), gauss_seidel.MAX_SLABS)
    starts = ti.ndarray(ti.i32, shape=n_buckets + 1)
    starts.from_numpy(np.arange(n_buckets + 1, dtype=np.int32))  # one entry a bucket
    ranges = ti.ndarray(ti.i32, shape=(2, slabs // 2, 2))

    @ti.kernel
    def every_range(bits: ti.types.vector(3, ti.i32), starts: ti.types.ndarray(), out: ti.types.ndarray()):
        for c in ti.static(range(2)):
            for u in range(gauss_seidel.slab_count(bits, gauss_seidel.MAX_SLABS) // 2):
                out[c, u, 0], out[c, u, 1] = gauss_seidel.slab_range(c, u, bits, starts, gauss_seidel.MAX_SLABS)

    every_range(ti.Vector(list(bits)), starts, ranges)
    r = ranges.to_numpy()
    assert slabs % 2 == 0 and (1 << bits[2]) // slabs >= 2
    plane = 1 << (bits[0] + bits[1])
    order = r.transpose(1, 0, 2).reshape(-1, 2)  # slab 0 (even), 1 (odd), 2 (even), ...
    assert order[0, 0] == 0 and order[-1, 1] == n_buckets
    assert np.array_equal(order[1:, 0], order[:-1, 1])  # consecutive, no gap, no overlap
    assert np.all(order[:, 1] - order[:, 0] == n_buckets // slabs)  # equal slabs, whole z planes
    assert np.all((order[:, 0] % plane) == 0)


@pytest.mark.parametrize("method, relaxation", [("gauss-seidel", None), ("gauss-seidel", 0.8),
                                                ("gauss-seidel, GPU units", None), ("jacobi", None)])
def test_one_projection_pass_separates_every_isolated_pair(method, relaxation, monkeypatch):
    # Overlapping pairs at rest, far apart from each other and spread over many widths of the
    # grid's table: no contact pass has anything to do, and one projection pass must take away
    # the relaxation's share of every pair's overlap (a unit the coloured pass skipped would
    # leave its pair as it was): all of it with Gauss-Seidel's default (1) and with Jacobi's
    # over-relaxation (an isolated pair's share is capped at 1), 0.8 of it under-relaxed,
    # split by inverse mass: each pair's centre of mass stays put. Also with the units a GPU
    # gets, run here on the CPU.
    method = pass_method(method, monkeypatch)
    rng = np.random.default_rng(5)
    pairs, r = 400, 0.01
    centres = rng.uniform(-30.0, 30.0, (pairs, 3)) + [0.0, 40.0, 0.0]
    axis = rng.normal(size=(pairs, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    gap = rng.uniform(1.0, 1.9, pairs) * r  # overlaps of 5 % to 50 %
    x = np.concatenate([centres + 0.5 * gap[:, None] * axis, centres - 0.5 * gap[:, None] * axis])
    mass = rng.uniform(1.0, 3.0, 2 * pairs)
    scene = tc.Scene(dt=1 / 1000, substeps=1, gravity=(0.0, 0.0, 0.0))
    # (max_push_speed=inf: the projection on the overlap these pairs are placed with)
    settings = scene.enable_particle_collisions(material=tc.Material(restitution=0.0, friction=0.0), method=method,
                                                projection_iterations=1, relaxation=relaxation,
                                                max_push_speed=math.inf)
    share = min(1.0, settings.relaxation)
    assert share == (1.0 if relaxation is None else relaxation)
    scene.add_particles(positions=x, radius=r, mass=mass)
    scene.step(1)
    y = scene.positions()
    a, b = y[:pairs], y[pairs:]
    assert np.allclose(np.linalg.norm(a - b, axis=1), gap + share * (2 * r - gap), rtol=1e-4)
    before = (mass[:pairs, None] * x[:pairs] + mass[pairs:, None] * x[pairs:]) / (mass[:pairs] + mass[pairs:])[:, None]
    after = (mass[:pairs, None] * a + mass[pairs:, None] * b) / (mass[:pairs] + mass[pairs:])[:, None]
    assert np.allclose(after, before, atol=1e-5 * r)


@pytest.mark.parametrize("asleep", [False, True])
def test_a_projection_pass_leaves_listed_pairs_that_do_not_overlap_exactly_as_they_were(asleep):
    # A lattice at 2.1 r: every neighbour is listed (within the 0.25 r margin) and none
    # overlaps. The projection pass moves every listed pair, by zero where it does not overlap
    # (gauss_seidel._particle_pairs): positions and velocities must come back bit for bit and
    # the pass must report nothing done (the loop of passes ends on that). Then one pair pushed
    # into overlap: it alone is separated, split by mass, and every other particle stays
    # bit-identical. asleep: every other particle of the lattice sleeps (immovable).
    from tai_coll.types import ParticleArgs

    r = 0.01
    g = np.arange(6) * 2.1 * r
    x = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3) + [0.0, 0.5, 0.0]
    n = len(x)
    rng = np.random.default_rng(3)
    v = rng.normal(0.0, 0.1, (n, 3))
    mass = rng.uniform(1.0, 2.0, n)
    rest = np.where(np.arange(n) % 2 == 1, -1.0, 0.0) if asleep else np.zeros(n)

    def project(x):
        grid = grid_of(x, np.full(n, r), 0.25 * r, forward=True)
        assert np.mean([len(row) for row in grid.own_lists(n)]) > 2.0  # (the lattice's pairs are listed)
        x1, v1, changed = on_device(x), on_device(v), on_device(np.zeros(1, int))
        particles = ParticleArgs(count=n, x=on_device(x), v=on_device(v), mass=on_device(mass),
                                 radius=on_device(np.full(n, r)), flags=on_device(np.zeros(n, int)),
                                 allowance=on_device(np.zeros(n)), rest=on_device(rest),
                                 anchor=on_device(x), stats=on_device(np.zeros(4, int)))
        gauss_seidel.projection_pass(particles, grid.args, grid.lists, 1.0, 1e-3, False, 0.0, changed, x1, v1,
                                     sleep=asleep)
        return x1.to_numpy(), v1.to_numpy(), changed[0]

    x = x.astype(np.float32).astype(float)  # (held exactly in f32 and f64: "unchanged" is to the bit)
    v = v.astype(np.float32).astype(float)
    x1, v1, changed = project(x)
    assert changed == 0
    assert np.array_equal(x1, x) and np.array_equal(v1, v)
    a, b = 2 * 36 + 2 * 6 + 2, 2 * 36 + 2 * 6 + 3  # two neighbours along z inside the lattice (a awake)
    pushed = x.copy()
    pushed[b, 2] -= 0.3 * r  # now 1.8 r apart
    pushed = pushed.astype(np.float32).astype(float)
    x1, v1, changed = project(pushed)
    assert changed == 1
    others = np.ones(n, bool)
    others[[a, b]] = False
    assert np.array_equal(x1[others], pushed[others]) and np.array_equal(v1[others], v[others])
    assert np.linalg.norm(x1[a] - x1[b]) == pytest.approx(2 * r, rel=1e-5)
    if asleep and rest[b] < 0:
        assert np.array_equal(x1[b], pushed[b]) and np.array_equal(v1[b], v[b])  # (immovable: a takes it all)
    else:
        centre = (mass[a] * x1[a] + mass[b] * x1[b]) / (mass[a] + mass[b])
        assert np.allclose(centre, (mass[a] * pushed[a] + mass[b] * pushed[b]) / (mass[a] + mass[b]), atol=1e-6 * r)


def settle(x, v, mass, r, law, **options):
    """gauss_seidel.settle_pass over particles at x (radius r) with velocities v, masses mass and
    the pair law `law` (restitution, friction); options: settle_pass's. Returns (x1, v1 after,
    whether the pass changed anything)."""
    from tai_coll.types import ParticleArgs

    n = len(x)
    grid = grid_of(x, np.full(n, r), 0.25 * r, forward=True)
    x1, v1, changed = on_device(x), on_device(v), on_device(np.zeros(1, int))
    particles = ParticleArgs(count=n, x=on_device(x), v=on_device(v), mass=on_device(mass),
                             radius=on_device(np.full(n, r)), flags=on_device(np.zeros(n, int)),
                             allowance=on_device(np.zeros(n)), rest=on_device(np.zeros(n)),
                             anchor=on_device(x), stats=on_device(np.zeros(4, int)))
    gauss_seidel.settle_pass(particles, grid.args, grid.lists, law, 1e-3, changed, x1, v1, **options)
    return x1.to_numpy(), v1.to_numpy().astype(float), changed[0]


def separate_pairs(rng, pairs, r, distance, closing):
    """`pairs` isolated pairs far apart along random axes, their centres `distance` apart, each
    particle moving towards the other by `closing` (negative: apart) plus a shared tangential
    velocity. Returns (x, v, axis): the first particles, then their partners."""
    centres = rng.uniform(-20.0, 20.0, (pairs, 3))
    axis = rng.normal(size=(pairs, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    x = np.concatenate([centres + 0.5 * distance[:, None] * axis, centres - 0.5 * distance[:, None] * axis])
    towards = -closing[:, None] * axis
    tangential = rng.normal(scale=0.1, size=(pairs, 3))
    return x, np.concatenate([towards + tangential, -towards + tangential]), axis


def test_settle_pass_stops_touching_pairs_approaching_and_moves_nothing():
    # Gauss-Seidel's last pass: the law (here e = 0, no friction) on pairs touching at the
    # final positions (up to SETTLE_TOUCH beyond r_i + r_j, what a projection leaves):
    # isolated touching pairs that approach stop approaching, with momentum conserved;
    # separating pairs and pairs just out of touch keep their velocities; nothing moves.
    from tai_coll import runtime
    from tai_coll.response.laws import WET_LINEAR

    rng = np.random.default_rng(4)
    pairs, r = 300, 0.01
    kind = np.arange(pairs) % 3  # 0: touching, approaching; 1: touching, separating; 2: just apart
    distance = np.where(kind == 2, 2 * r * 1.01, 2 * r * (1 + 0.5 * gauss_seidel.SETTLE_TOUCH))
    closing = np.where(kind == 1, -1.0, 1.0) * rng.uniform(0.01, 0.5, pairs)
    x, v, axis = separate_pairs(rng, pairs, r, distance, closing)
    mass = rng.uniform(1.0, 3.0, 2 * pairs)
    dtype = runtime.float_dtype()
    law = dict(restitution=0.0, friction=0.0, wet_friction=0.0, wet_law=WET_LINEAR)
    x1, after, changed = settle(x, v, mass, r, law)
    assert np.array_equal(x1, x.astype(dtype))  # nothing moved
    assert changed == 1
    eps = 1e-5 if dtype == np.float32 else 1e-12
    momentum = mass[:pairs, None] * v[:pairs] + mass[pairs:, None] * v[pairs:]
    assert np.allclose(mass[:pairs, None] * after[:pairs] + mass[pairs:, None] * after[pairs:], momentum, atol=eps)
    normal_rel = np.sum((after[:pairs] - after[pairs:]) * axis, axis=1)
    stopped = kind == 0
    assert np.all(np.abs(normal_rel[stopped]) < eps)
    assert np.allclose(after[np.concatenate([~stopped, ~stopped])], v[np.concatenate([~stopped, ~stopped])], atol=eps)
    tangent_rel = (after[:pairs] - after[pairs:]) - normal_rel[:, None] * axis
    assert np.allclose(tangent_rel[stopped], 0.0, atol=eps)  # (both particles share the tangential velocity)


def test_settle_pass_bounces_only_approaches_faster_than_the_rest_speed():
    # docs/physics.md 5, step 5: a touching pair approaching slower than the rest speed is a
    # resting contact and stops (e = 0); faster, it leaves with e times its approach.
    from tai_coll import runtime
    from tai_coll.response.laws import WET_LINEAR

    rng = np.random.default_rng(5)
    pairs, r, e, rest_speed = 200, 0.01, 0.5, 0.1
    approach = rng.uniform(0.01, 0.3, pairs)  # the pair's relative approach speed
    x, v, axis = separate_pairs(rng, pairs, r, np.full(pairs, 2 * r), 0.5 * approach)
    mass = np.ones(2 * pairs)
    law = dict(restitution=e, friction=0.0, wet_friction=0.0, wet_law=WET_LINEAR)
    _x1, after, _changed = settle(x, v, mass, r, law, rest_speed=rest_speed)
    eps = 1e-5 if runtime.float_dtype() == np.float32 else 1e-12
    leaving = np.sum((after[:pairs] - after[pairs:]) * axis, axis=1)
    slow = approach < rest_speed
    assert 0 < slow.sum() < pairs
    assert np.allclose(leaving[slow], 0.0, atol=eps)
    assert np.allclose(leaving[~slow], e * approach[~slow], rtol=1e-4, atol=eps)


# ---------------------------------------------------------------- configuration
def test_particle_collisions_need_a_material():
    scene = tc.Scene()
    with pytest.raises(TypeError, match="material"):
        scene.enable_particle_collisions(material=0.5)
    with pytest.raises(ValueError, match="iterations"):
        scene.enable_particle_collisions(iterations=0)
    with pytest.raises(ValueError, match="method must be one of 'gauss-seidel', 'jacobi'; got 'sor'"):
        scene.enable_particle_collisions(method="sor")
    with pytest.raises(ValueError, match="relaxation"):
        scene.enable_particle_collisions(method="jacobi", relaxation=2.5)
    defaults = scene.enable_particle_collisions(method="jacobi")
    assert (defaults.iterations, defaults.projection_iterations, defaults.relaxation) == (4, 4, 1.5)
    defaults = scene.enable_particle_collisions()
    assert defaults.method == "gauss-seidel"
    assert (defaults.iterations, defaults.projection_iterations, defaults.relaxation) == (1, 3, 1.0)
    assert not defaults.tangential_springs
    with pytest.raises(ValueError, match="tangential_springs: DEM pairs only"):
        scene.enable_particle_collisions(tangential_springs=True)  # an impulse scene
    dem = tc.Scene(solver=tc.PenaltySolver(hertz=100.0))
    with pytest.raises(TypeError, match="tangential_springs must be True or False"):
        dem.enable_particle_collisions(tangential_springs="yes")
    with pytest.raises(ValueError, match="tangential_ratio"):
        dem.enable_particle_collisions(tangential_springs=True, tangential_ratio=0.0)


THREADS_PROBE = '''
import hashlib
import sys

import numpy as np
import tai_coll as tc

for threads in (1, 2):
    tc.init(arch="cpu", precision="f64", threads=threads, seed=0)
    r = 0.005
    rng = np.random.default_rng(5)
    grid = np.stack(np.meshgrid(np.arange(10), np.arange(6), np.arange(10), indexing="ij"), -1).reshape(-1, 3)
    x = (grid * 2.05 * r + r + rng.uniform(-0.1, 0.1, grid.shape) * r) + [0.0, 0.002, 0.0]
    scene = tc.Scene(dt=1.0 / 120.0, substeps=4)
    wall = tc.Material(restitution=0.3, friction=0.4)
    width = 10 * 2.05 * r + 2 * r
    for point, normal in (((0, 0, 0), (0, 1, 0)), ((0, 0, 0), (1, 0, 0)), ((width, 0, 0), (-1, 0, 0)),
                          ((0, 0, 0), (0, 0, 1)), ((0, 0, width), (0, 0, -1))):
        scene.add_collider(tc.Plane(point=point, normal=normal), material=wall)
    scene.add_particles(positions=x, radius=r)
    scene.enable_particle_collisions(material=tc.Material(restitution=0.3, friction=0.4))
    scene.step(12)
    state = np.concatenate([scene.positions(), scene.velocities()]).tobytes()
    print(threads, hashlib.sha256(state).hexdigest(), float(scene.velocities()[:, 1].min()))
'''


@pytest.mark.skipif(TEST_ARCH != "cpu", reason="the CPU's thread count")
def test_gauss_seidel_slabs_give_the_same_state_with_any_thread_count(tmp_path):
    # The CPU's slabs are claimed by whichever thread is free (gauss_seidel.CLAIM_STRIDE), and
    # slabs of one colour share no particle: 600 particles settling in a box (a table of
    # several slabs, pairs in every one) reach the same state to the bit with 1 and 2 threads (each
    # thread count compiles its kernels anew: a third would add a third of the time).
    import subprocess
    import sys

    probe = tmp_path / "probe.py"
    probe.write_text(THREADS_PROBE)
    run = subprocess.run([sys.executable, str(probe)], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    lines = [line.split() for line in run.stdout.splitlines() if line[:1].isdigit()]
    assert [line[0] for line in lines] == ["1", "2"]
    assert len({line[1] for line in lines}) == 1, lines
    assert float(lines[0][2]) < -0.01  # (something moved: the particles fell and met)
