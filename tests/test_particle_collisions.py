"""Particles hitting particles (PHYSICS.md 2, two movable bodies), by closed form; and the
hash grid against brute force."""

import numpy as np
import pytest

import tai_coll as tc
from tai_coll.neighbors import HashGrid
from tai_coll.solvers import gauss_seidel


def pair_scene(*, restitution, friction=0.0, dt=1e-4, substeps=10):
    scene = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=dt, substeps=substeps)
    scene.enable_particle_collisions(material=tc.Material(restitution=restitution, friction=friction))
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
    # Two particles placed at one point (no normal from their centres: pair_normal's fixed
    # axis): one step separates them to touching, with finite velocities, the momentum and
    # the centre of mass's motion unchanged (every change split by inverse mass).
    ma, mb, r = 1.0, 3.0, 0.05
    va, vb = np.array([0.3, 0.5, 0.0]), np.array([0.0, -0.2, 0.1])
    scene = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=1e-3, substeps=5)
    scene.enable_particle_collisions(material=tc.Material(restitution=0.5, friction=0.3), method=method)
    scene.add_particles(positions=[[0.1, 0.2, -0.3]] * 2, velocities=[va, vb], mass=np.array([ma, mb]), radius=r)
    scene.step(1)
    x, v = scene.positions(), scene.velocities()
    assert np.all(np.isfinite(x)) and np.all(np.isfinite(v))
    assert np.linalg.norm(x[0] - x[1]) >= 2 * r * (1 - 1e-4)
    assert np.allclose(ma * v[0] + mb * v[1], ma * va + mb * vb, atol=1e-5)
    centre = (ma * x[0] + mb * x[1]) / (ma + mb)
    assert np.allclose(centre, np.array([0.1, 0.2, -0.3]) + scene.frame_time * (ma * va + mb * vb) / (ma + mb), atol=1e-5)


def assert_stack_rests_in_contact(scene, r, count):
    """A column of `count` particles of radius r on a floor: still, every neighbour touching
    (no gap wider than round-off), overlaps below 5 % of r, the lowest one on the floor."""
    assert np.abs(scene.velocities()).max() < 1e-3
    y = np.sort(scene.positions()[:, 1])
    xz = scene.positions()[:, [0, 2]]
    assert len(y) == count and np.abs(xz - xz[0]).max() < 1e-6  # still a column
    assert np.all(np.diff(y) - 2 * r < 1e-5 * r)
    assert scene.particle_overlap()["max"] < 0.05
    assert y[0] == pytest.approx(r, abs=1e-3 * r)


def pass_method(method, monkeypatch):
    """The method to ask for; "gauss-seidel, GPU units": Gauss-Seidel with the units a GPU
    gets (gauss_seidel.GPU_UNIT_BITS), here on the CPU."""
    if method == "gauss-seidel, GPU units":
        monkeypatch.setattr(gauss_seidel, "unit_bits", lambda: gauss_seidel.GPU_UNIT_BITS)
        return "gauss-seidel"
    return method


@pytest.mark.parametrize("method", ["gauss-seidel", "gauss-seidel, GPU units", "jacobi"])
def test_stack_on_a_floor_comes_to_rest(method, monkeypatch):
    method = pass_method(method, monkeypatch)
    r = 0.01
    scene = tc.Scene(dt=1 / 1000, substeps=5)
    scene.add_collider(tc.Plane(), material=tc.Material(restitution=0.2, friction=0.4))
    scene.enable_particle_collisions(material=tc.Material(restitution=0.2, friction=0.4), method=method)
    scene.add_particles(positions=[[0, r + k * 2.05 * r, 0] for k in range(10)], radius=r)
    scene.step(100)
    assert_stack_rests_in_contact(scene, r, 10)


@pytest.mark.parametrize("method", ["gauss-seidel", "jacobi"])
def test_pile_in_a_box_settles(method):
    # 10,000 particles dropped into a box of planes: the pile's overlap stays small, no
    # particle escapes, kinetic energy decays to near zero.
    r, half = 0.01, 0.25
    scene = tc.Scene(dt=1 / 1000, substeps=5)
    walls = [((0, 0, 0), (0, 1, 0)), ((-half, 0, 0), (1, 0, 0)), ((half, 0, 0), (-1, 0, 0)),
             ((0, 0, -half), (0, 0, 1)), ((0, 0, half), (0, 0, -1))]
    for point, normal in walls:
        scene.add_collider(tc.Plane(point=point, normal=normal), material=tc.Material(restitution=0.2, friction=0.4))
    scene.enable_particle_collisions(material=tc.Material(restitution=0.2, friction=0.4), method=method)
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
    assert np.all(scene.status() == "active")


def on_device(a):
    """A Taichi ndarray holding the host array a: integers as i32, floats in the session's
    precision (n x 3 as vectors)."""
    import taichi as ti
    from tai_coll import runtime

    a = np.asarray(a)
    if np.issubdtype(a.dtype, np.integer):
        out = ti.ndarray(ti.i32, shape=len(a))
        out.from_numpy(a.astype(np.int32))
    else:
        out = ti.Vector.ndarray(3, float, shape=len(a)) if a.ndim == 2 else ti.ndarray(float, shape=len(a))
        out.from_numpy(a.astype(runtime.float_dtype()))
    return out


def grid_of(x, radius, margin, forward=False):
    """A HashGrid built on host arrays (positions x, radii), every particle simulated."""
    n = len(x)
    grid = HashGrid()
    grid.build(on_device(x), on_device(radius), on_device(np.zeros(n, int)), n, 2 * radius.max() + margin, margin,
               forward=forward)
    return grid


@pytest.mark.parametrize("forward", [False, True])
@pytest.mark.parametrize("offset", [(0.0, 0.0, 0.0), (-37.3, -5.0, -12.9)])
def test_hash_grid_matches_brute_force(offset, forward):
    rng = np.random.default_rng(3)
    n = 600
    x = rng.uniform(-0.3, 0.3, (n, 3)) + np.array(offset)
    x[:5] += [1e3, -2e3, 5e2]  # far outside the others' bounds
    radius = rng.uniform(0.01, 0.03, n)
    margin = 0.005
    grid = grid_of(x, radius, margin, forward)
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
        counts = grid.neighbour_count.to_numpy()[:n]
        table = grid.neighbours.to_numpy()[:n]
        slot_of = np.empty(n, int)
        slot_of[grid.entries.to_numpy()[:n]] = np.arange(n)
        for i in range(n):
            assert np.all(slot_of[table[i, : counts[i]]] > slot_of[i]), i
        assert counts.sum() == sum(len(row) for row in lists) // 2
    assert grid.dropped() == 0


def gauss_seidel_units(grid, n, unit_bits):
    """Per particle: the colour (0..7) and the unit (an id) the coloured passes give it with
    units of unit_bits, recomputed on the host from the grid's buckets (see
    tai_coll.solvers.gauss_seidel)."""
    bits = [int(b) for b in grid.bits]
    starts = grid.starts.to_numpy()
    active = int(starts[grid.n_buckets])
    bucket = np.repeat(np.arange(grid.n_buckets), np.diff(starts[: grid.n_buckets + 1]))
    coords = np.stack([bucket & ((1 << bits[0]) - 1), (bucket >> bits[0]) & ((1 << bits[1]) - 1),
                       bucket >> (bits[0] + bits[1])], 1)
    unit = coords >> np.array(unit_bits)
    colour = (unit[:, 0] & 1) | ((unit[:, 1] & 1) << 1) | ((unit[:, 2] & 1) << 2)
    unit_id = unit[:, 0] + (unit[:, 1] << 16) + (unit[:, 2] << 32)
    entries = grid.entries.to_numpy()[:active]
    per_colour, per_unit = np.full(n, -1), np.full(n, -1)
    per_colour[entries], per_unit[entries] = colour, unit_id
    return per_colour, per_unit


@pytest.mark.parametrize("unit_bits", [gauss_seidel.CPU_UNIT_BITS, gauss_seidel.GPU_UNIT_BITS], ids=["cpu", "gpu"])
@pytest.mark.parametrize("spread", [0.3, 40.0])
def test_gauss_seidel_units_of_a_colour_share_no_particle(spread, unit_bits):
    # The coloured passes resolve the units of one colour at the same time: what one unit's
    # pairs touch (its particles and their listed neighbours) must not meet what another's
    # touch. 30 dense clusters, close together or spread over many table widths (wrap-around);
    # the units of the CPU and of GPUs.
    rng = np.random.default_rng(11)
    n = 3000
    clusters = rng.uniform(-spread, spread, (30, 3)) - [3.1, 0.2, -7.7]
    x = clusters[np.arange(n) % 30] + rng.uniform(-0.12, 0.12, (n, 3))
    radius = rng.uniform(0.01, 0.02, n)
    grid = grid_of(x, radius, 0.005, forward=True)
    colour, unit = gauss_seidel_units(grid, n, unit_bits)
    assert np.all(colour >= 0)
    counts = grid.neighbour_count.to_numpy()[:n]
    table = grid.neighbours.to_numpy()[:n]
    owner = np.repeat(np.arange(n), counts)
    listed = np.concatenate([table[i, : counts[i]] for i in range(n)])
    assert len(listed) > n // 2  # pairs enough to mean something
    # (particle touched, colour, unit) for the owners and for the neighbours they list
    touched = np.concatenate([np.arange(n), listed])
    by = np.concatenate([np.arange(n), owner])
    records = np.unique(np.stack([touched, colour[by], unit[by]], 1), axis=0)
    # at most one unit of each colour touches any particle
    pairs = np.unique(records[:, :2], axis=0)
    assert len(pairs) == len(records)


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
    settings = scene.enable_particle_collisions(material=tc.Material(restitution=0.0, friction=0.0), method=method,
                                                projection_iterations=1, relaxation=relaxation)
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
    assert (defaults.iterations, defaults.projection_iterations, defaults.relaxation) == (1, 2, 1.0)
    assert not defaults.tangential_springs
    with pytest.raises(ValueError, match="tangential_springs: DEM pairs only"):
        scene.enable_particle_collisions(tangential_springs=True)  # an impulse scene
    dem = tc.Scene(solver=tc.PenaltySolver(hertz=100.0))
    with pytest.raises(TypeError, match="tangential_springs must be True or False"):
        dem.enable_particle_collisions(tangential_springs="yes")
    with pytest.raises(ValueError, match="tangential_ratio"):
        dem.enable_particle_collisions(tangential_springs=True, tangential_ratio=0.0)


def test_full_neighbour_lists_are_warned_about_once():
    # One particle ten times larger stretches everyone's reach (margin x the largest radius):
    # a cluster of small ones on a 1.05 mm lattice sees about 150 others within reach.
    import warnings

    scene = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=1e-4, substeps=2)
    pairs = scene.enable_particle_collisions()
    g = 0.0105 * np.arange(8)
    X, Y, Z = np.meshgrid(g, g, g, indexing="ij")
    scene.add_particles(positions=np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1), radius=0.005)
    scene.add_particles(positions=[[5.0, 0.0, 0.0]], radius=0.1)
    with pytest.warns(RuntimeWarning, match=r"neighbour lists were full .* more than 48 others"):
        scene.step()
    dropped = pairs.neighbour_overflow
    assert dropped > 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene.step()  # once per scene
    assert pairs.neighbour_overflow > dropped
    # radii of one size: no list is full, nothing to warn about
    calm = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=1e-4, substeps=2)
    calm.enable_particle_collisions()
    calm.add_particles(positions=np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1), radius=0.005)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        calm.step()


def dem_scene(**solver):
    scene = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=2e-5, substeps=10, solver=tc.PenaltySolver(**solver))
    scene.enable_particle_collisions(material=tc.Material(friction=0.0))
    return scene


def test_dem_pair_undamped_is_elastic_and_conserves_momentum():
    # Penalty solver: a spring on the overlap with the pair's reduced mass. Undamped, equal
    # masses exchange velocities; masses 1 and 3 keep the total momentum to round-off.
    scene = dem_scene(stiffness=2e4, damping=0.0)
    scene.add_particles(positions=[[-0.06, 0, 0], [0.06, 0, 0]], velocities=[[1, 0, 0], [-1, 0, 0]],
                        mass=np.array([1.0, 3.0]), radius=0.05)
    scene.step(300)
    v = scene.velocities()
    assert np.allclose(1.0 * v[0] + 3.0 * v[1], [-2.0, 0, 0], atol=1e-12)
    # elastic: the relative speed is restored (e = 1) within the integrator's error
    assert (v[1, 0] - v[0, 0]) == pytest.approx(2.0, rel=0.01)
    assert scene.particle_overlap()["pairs"] == 0


def crowded_particle(count, seed, offset=(0.0, 0.0, 0.0)):
    """A big particle (r 0.1, 5 kg) overlapped by `count` small ones (r 0.02, 0.5 to 2 kg) in
    random directions, some of which overlap each other: positions, radii, masses."""
    rng = np.random.default_rng(seed)
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    small = directions * rng.uniform(0.105, 0.118, (count, 1))  # overlapping the big one (r 0.1 + 0.02)
    x = np.vstack([[0.0, 0.0, 0.0], small]) + offset
    radius = np.concatenate([[0.1], np.full(count, 0.02)])
    mass = np.concatenate([[5.0], rng.uniform(0.5, 2.0, count)])
    return x, radius, mass


def spring_law_velocities(x, radius, mass, k, dt):
    """Brute force: the velocities after one substep from rest with undamped DEM springs and no
    gravity, dt/m times the sum of k overlap n over every touching pair; and which pairs touch."""
    d = x[:, None, :] - x[None, :, :]
    dist = np.linalg.norm(d, axis=2)
    overlap = radius[:, None] + radius[None, :] - dist
    np.fill_diagonal(overlap, 0.0)
    touching = overlap > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        force = np.where(touching[:, :, None], k * overlap[:, :, None] * d / dist[:, :, None], 0.0).sum(axis=1)
    return dt * force / mass[:, None], touching


@pytest.mark.parametrize("springs", [False, True])
def test_dem_forces_on_a_crowded_particle_match_the_spring_law(springs):
    # A big particle touched by 40 small ones (more than the kernel's batch of touching
    # neighbours) and a few small ones touching each other, all at rest, no gravity: after one
    # substep every velocity is dt/m times the sum of k overlap n over its contacts (the
    # damper and friction see zero relative velocity), with k = stiffness as given. With
    # tangential springs (new contacts: zero springs) the big one keeps 12 of its 40 and
    # counts the other 28 as overflow.
    k, dt = 3e3, 1e-5
    x, radius, mass = crowded_particle(40, 5, offset=(3.0, -2.0, 1.0))
    scene = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=dt, substeps=1,
                     solver=tc.PenaltySolver(stiffness=k, damping=0.0))
    settings = scene.enable_particle_collisions(material=tc.Material(friction=0.5), tangential_springs=springs)
    scene.add_particles(positions=x, radius=radius, mass=mass)
    scene.step(1)
    expected, touching = spring_law_velocities(x, radius, mass, k, dt)
    assert touching[0].sum() == 40 and touching[1:, 1:].any()
    assert np.allclose(scene.velocities(), expected, rtol=1e-4, atol=1e-9 * np.abs(expected).max())
    assert np.allclose((mass[:, None] * scene.velocities()).sum(axis=0), 0.0, atol=1e-12)
    assert settings.history_overflow == (40 - 12 if springs else 0)


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


def push_only_restitution(zeta: float) -> float:
    """Rebound of the damped oscillator x'' = -w^2 x - 2 zeta w x' (x: overlap) that can only
    push: x(t) = (v0/wd) exp(-zeta w t) sin(wd t) until the force w x + 2 zeta x' reaches zero
    (bisection on that closed form), then free flight at -x'(t*)."""
    w = 1.0
    wd = w * np.sqrt(1 - zeta ** 2)

    def x(t):
        return np.exp(-zeta * w * t) * np.sin(wd * t) / wd

    def xdot(t):
        return np.exp(-zeta * w * t) * (np.cos(wd * t) - zeta * w / wd * np.sin(wd * t))

    lo, hi = np.pi / (2 * wd), np.pi / wd  # the force changes sign between the turn and x = 0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if w * x(mid) + 2 * zeta * xdot(mid) > 0:
            lo = mid
        else:
            hi = mid
    return -xdot(lo)


def test_dem_pair_damping_ratio_sets_the_rebound():
    # Damped pair contact, push-only: the rebound follows the closed form above (it is a
    # little above the linear oscillator's exp(-zeta pi / sqrt(1 - zeta^2)), since a
    # push-only contact cannot brake the particles as they separate).
    zeta = 0.2
    scene = dem_scene(hertz=40.0, damping_ratio=zeta)
    scene.add_particles(positions=[[-0.051, 0, 0], [0.051, 0, 0]], velocities=[[0.5, 0, 0], [-0.5, 0, 0]],
                        radius=0.05)
    scene.step(400)
    v = scene.velocities()
    e = push_only_restitution(zeta)
    assert np.exp(-zeta * np.pi / np.sqrt(1 - zeta ** 2)) < e
    assert (v[1, 0] - v[0, 0]) / 1.0 == pytest.approx(e, rel=0.02)
    assert np.allclose(v.sum(axis=0), 0.0, atol=1e-12)


def sphere_incline(theta_deg, mu, springs, *, top_first=False):
    """A particle B (1 kg) resting on a heavy one A (1000 kg) on a floor, gravity tilted by
    theta along x: the contact A-B is an incline of angle theta. DEM pairs, 200 Hz per pair
    (k = m_pair (2 pi 200)^2), critically damped; the floor holds A by friction 2."""
    th = np.radians(theta_deg)
    scene = tc.Scene(gravity=(9.81 * np.sin(th), -9.81 * np.cos(th), 0.0), dt=1e-4, substeps=10,
                     solver=tc.PenaltySolver(hertz=200.0, damping_ratio=1.0))
    scene.add_collider(tc.Plane(point=(0, 0, 0), normal=(0, 1, 0)), material=tc.Material(friction=2.0))
    settings = scene.enable_particle_collisions(material=tc.Material(friction=mu), tangential_springs=springs)
    r = 0.05
    x, mass = np.array([[0, r, 0], [0, 3 * r, 0]]), np.array([1000.0, 1.0])
    if top_first:  # B in the first slot: the store's reordering by cell swaps the two
        x, mass = x[::-1], mass[::-1]
    scene.add_particles(positions=x, radius=r, mass=mass)
    a, b = (1, 0) if top_first else (0, 1)
    return scene, settings, a, b


def slip(scene, a, b):
    x, v = scene.positions(), scene.velocities()
    return x[b, 0] - x[a, 0], v[b, 0] - v[a, 0]


@pytest.mark.parametrize("top_first", [False, True])
def test_tangential_spring_holds_a_contact_still_where_regularised_friction_creeps(top_first):
    # mu = 0.5 > tan 20 deg: the contact holds. With a spring it stretches to
    # m g sin(theta) / k_t (k_t = 2/7 k_n) and stays there (B's offset from A also holds the
    # tenths of a micrometre the contact turned while B settled onto A, within 5 %); the
    # regularised friction cancels
    # the tangential velocity every substep after the load has moved it for one, so the
    # contact creeps at g sin(theta) dt. top_first: the store's reordering swaps the two
    # particles every 8 substeps, and the springs must move with them.
    theta, dt = 20.0, 1e-4
    load = 9.81 * np.sin(np.radians(theta))
    k_t = 2.0 / 7.0 * (1000.0 / 1001.0) * (2 * np.pi * 200.0) ** 2  # per unit mass of B
    scene, settings, a, b = sphere_incline(theta, 0.5, True, top_first=top_first)
    scene.step(60)  # 0.06 s
    early, _ = slip(scene, a, b)
    scene.step(100)
    late, speed = slip(scene, a, b)
    assert early == pytest.approx(load / k_t, rel=0.05)
    assert abs(late - early) < 1e-3 * early and abs(speed) < 1e-6
    assert settings.history_overflow == 0
    scene, _, a, b = sphere_incline(theta, 0.5, False, top_first=top_first)
    scene.step(60)
    early, _ = slip(scene, a, b)
    scene.step(100)
    late, _ = slip(scene, a, b)
    assert (late - early) / 0.1 == pytest.approx(load * dt, rel=0.05)


@pytest.mark.parametrize("springs", [True, False])
def test_contact_beyond_its_friction_slides_at_the_incline_law(springs):
    # mu = 0.2 < tan 20 deg: B slides off A with a = g (sin - mu cos) (A is 1000 times heavier;
    # after 0.02 s B has moved 0.3 mm, 0.6 % of its radius along A's surface).
    theta, mu = 20.0, 0.2
    th = np.radians(theta)
    expected = 9.81 * (np.sin(th) - mu * np.cos(th))
    scene, _, a, b = sphere_incline(theta, mu, springs)
    scene.step(20)
    _, speed = slip(scene, a, b)
    assert speed / scene.time == pytest.approx(expected, rel=0.02)


def test_tangential_springs_conserve_momentum():
    # A glancing DEM contact of masses 1 and 3 with friction by springs, no gravity: each
    # particle keeps the pair's spring, both springs exactly opposite, so are the forces.
    scene = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=2e-5, substeps=10,
                     solver=tc.PenaltySolver(hertz=100.0, damping_ratio=0.3))
    scene.enable_particle_collisions(material=tc.Material(friction=0.6), tangential_springs=True)
    v0 = np.array([[1.0, 0.0, 0.2], [-0.3, 0.1, 0.0]])
    mass = np.array([1.0, 3.0])
    scene.add_particles(positions=[[-0.06, 0.04, 0.0], [0.04, 0.0, 0.01]], velocities=v0, mass=mass, radius=0.05)
    scene.step(150)
    v = scene.velocities()
    assert np.allclose(mass @ v, mass @ v0, atol=1e-12)
    assert scene.particle_overlap()["pairs"] == 0
    tangential = v[0] - v0[0]
    assert np.linalg.norm(tangential - tangential.dot([1, 0, 0]) * np.array([1, 0, 0])) > 1e-3  # friction acted


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
    scene.add_collider(tc.Plane(point=(0, 0, 0), normal=(0, 1, 0)), material=tc.Material(restitution=0.0))
    scene.enable_particle_collisions(material=tc.Material(restitution=0.0))
    r = 0.01
    scene.add_particles(positions=[[0.0, 3.0, 0.0], [0.5, 3.0, 0.0]], radius=r)
    scene.step(2)  # clearances of about 3 m are kept
    scene.set_positions([[0.0, 0.015, 0.0], [0.5, 0.015, 0.0]])
    scene.set_velocities([[0.0, -4.0, 0.0], [0.0, -4.0, 0.0]])
    scene.step(5)
    assert np.all(scene.positions()[:, 1] >= r * (1 - 2e-3)), scene.positions()


def test_head_on_with_lists_kept_between_substeps():
    # Verlet lists (skin > 0): rebuilt only when a particle has moved skin / 2 since the
    # last build; the pair approaching at 2 m/s is still caught and follows the textbook law.
    ma, mb, va, vb, e = 1.0, 3.0, 1.0, -1.0, 0.5
    scene = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=1e-4, substeps=10)
    pairs = scene.enable_particle_collisions(material=tc.Material(restitution=e), skin=0.5)
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
    scene = tc.Scene(dt=1 / 1000, substeps=5)
    scene.add_collider(tc.Plane(), material=tc.Material(restitution=0.2, friction=0.4))
    pairs = scene.enable_particle_collisions(material=tc.Material(restitution=0.2, friction=0.4), skin=0.5)
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
    assert_stack_rests_in_contact(scene, r, 10)


def dem_box_pile(skin, springs, rotation):
    """125 particles (r = 10 mm) on a jittered lattice with random velocities in a box of
    planes: DEM pairs (200 Hz), 0.03 s of collisions, contacts forming and ending."""
    r, half = 0.01, 0.06
    scene = tc.Scene(dt=1e-4, substeps=10, solver=tc.PenaltySolver(hertz=200.0, rotation=rotation))
    material = tc.Material(restitution=0.2, friction=0.4, rolling_friction=0.1 if rotation else 0.0)
    walls = [((0, 0, 0), (0, 1, 0)), ((-half, 0, 0), (1, 0, 0)), ((half, 0, 0), (-1, 0, 0)),
             ((0, 0, -half), (0, 0, 1)), ((0, 0, half), (0, 0, -1))]
    for point, normal in walls:
        scene.add_collider(tc.Plane(point=point, normal=normal), material=material)
    pairs = scene.enable_particle_collisions(material=material, tangential_springs=springs, skin=skin)
    g = np.arange(-half + 1.5 * r, half - 1.4 * r, 2.2 * r)
    X, Y, Z = np.meshgrid(g, r + 2.2 * r * np.arange(5), g, indexing="ij")
    x = np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1)
    rng = np.random.default_rng(3)
    scene.add_particles(positions=x + rng.uniform(-0.1 * r, 0.1 * r, x.shape),
                        velocities=rng.normal(0.0, 0.2, x.shape), radius=r)
    scene.step(30)
    return scene, pairs


@pytest.mark.parametrize("springs, rotation", [(False, False), (True, True)])
def test_dem_lists_find_the_contacts_the_grid_finds(springs, rotation):
    # The DEM kernel reading Verlet lists (skin > 0: built from the grid, kept until some
    # particle has moved skin / 2) against the kernel querying the grid sorted every substep:
    # the same contacts, so the same motion (to round-off: only the order the forces are summed
    # in differs). Measured: positions 1e-17, velocities 3e-16, spins 5e-15.
    grid, _ = dem_box_pile(0.0, springs, rotation)
    listed, pairs = dem_box_pile(0.3, springs, rotation)
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
    pairs = scene.enable_particle_collisions(material=tc.Material(friction=0.5), skin=0.1)
    scene.add_particles(positions=x, radius=radius, mass=mass)
    scene.step(1)
    assert pairs.grid.dropped() > 0 and pairs.list_builds == 1
    expected, touching = spring_law_velocities(x, radius, mass, k, dt)
    assert touching[0].sum() == count
    assert np.allclose(scene.velocities(), expected, rtol=1e-4, atol=1e-9 * np.abs(expected).max())


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
        scene = tc.Scene(dt=1 / 1000, substeps=5)
        scene.add_collider(tc.Plane(), material=tc.Material(restitution=0.2, friction=0.4))
        scene.enable_particle_collisions(material=tc.Material(restitution=0.2, friction=0.4), reorder=reorder,
                                         method="jacobi")
        scene.add_particles(positions=x, mass=mass, radius=radius)
        scene.step(20)
        runs[reorder] = scene
    ids = runs[True]._particles._public()
    assert ids is not None and not np.array_equal(ids, np.arange(n))  # the store was permuted
    assert runs[False]._particles._public() is None
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
    assert np.all(scene.status() == "active")


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
    store.add(x[:30], v[:30], mass[:30], radius[:30])  # grows past the capacity: order reset
    assert store._public() is None
    assert np.array_equal(store.read("x"), np.concatenate([x, x[:30]]))
    with pytest.raises(ValueError, match="n must be"):
        store.permute(perm, n - 1)


def test_grid_entries_order_every_particle():
    # Particles no longer simulated sit after the simulated ones, in a bucket no query visits.
    rng = np.random.default_rng(4)
    n = 300
    x = rng.uniform(-0.2, 0.2, (n, 3))
    status = (rng.uniform(size=n) < 0.2).astype(np.int32)
    xs, rs, flags = on_device(x), on_device(np.full(n, 0.02)), on_device(status)
    grid = HashGrid()
    n_buckets = grid.sort(xs, rs, flags, n, 0.04)[0]
    entries = grid.entries.to_numpy()[:n]
    active = int(grid.starts.to_numpy()[n_buckets])
    assert np.array_equal(np.sort(entries), np.arange(n))
    assert active == np.count_nonzero(status == 0)
    assert np.all(status[entries[:active]] == 0) and np.all(status[entries[active:]] != 0)
    grid.build(xs, rs, flags, n, 0.05, 0.01)
    lists = grid.neighbour_lists(n)
    assert all(np.all(status[lst] == 0) for lst in lists)


def test_grid_sort_on_a_table_of_many_scan_blocks():
    # 20,000 particles: a table of 2^16 buckets, 64 blocks of the prefix sum (its serial middle
    # phase included). starts is the exclusive prefix sum of counts, each bucket's entries are
    # its particles in increasing order, and sorted_xr holds their positions and radii.
    from tai_coll.neighbors.hash_grid import SCAN_BLOCK

    rng = np.random.default_rng(5)
    n = 20_000
    x = rng.uniform(-1.0, 1.0, (n, 3))
    xs, rs, flags = on_device(x), on_device(np.full(n, 0.01)), on_device(np.zeros(n, int))
    grid = HashGrid()
    n_buckets, inv_cell, bits, *_ = grid.sort(xs, rs, flags, n, 0.03)
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


def test_settle_pass_stops_touching_pairs_approaching_and_moves_nothing():
    # Gauss-Seidel's last pass: the law (here e = 0, no friction) on pairs touching at the
    # final positions (up to SETTLE_TOUCH beyond r_i + r_j, what a projection leaves):
    # isolated touching pairs that approach stop approaching, with momentum conserved;
    # separating pairs and pairs just out of touch keep their velocities; nothing moves.
    from tai_coll import runtime
    from tai_coll.response.laws import WET_LINEAR

    rng = np.random.default_rng(4)
    pairs, r = 300, 0.01
    centres = rng.uniform(-20.0, 20.0, (pairs, 3))
    axis = rng.normal(size=(pairs, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    kind = np.arange(pairs) % 3  # 0: touching, approaching; 1: touching, separating; 2: just apart
    distance = np.where(kind == 2, 2 * r * 1.01, 2 * r * (1 + 0.5 * gauss_seidel.SETTLE_TOUCH))
    x = np.concatenate([centres + 0.5 * distance[:, None] * axis, centres - 0.5 * distance[:, None] * axis])
    closing = np.where(kind == 1, 1.0, -1.0)[:, None] * rng.uniform(0.01, 0.5, (pairs, 1)) * axis
    tangential = rng.normal(scale=0.1, size=(pairs, 3))
    v = np.concatenate([closing + tangential, -closing + tangential])  # a's velocity minus b's: 2 closing
    mass = rng.uniform(1.0, 3.0, 2 * pairs)
    n = 2 * pairs
    grid = grid_of(x, np.full(n, r), 0.25 * r, forward=True)
    dtype = runtime.float_dtype()
    x1, v1, changed = on_device(x), on_device(v), on_device(np.zeros(1, int))
    gauss_seidel.settle_pass(on_device(x), on_device(mass), on_device(np.full(n, r)), grid,
                             (0.0, 0.0, 0.0, WET_LINEAR), 1e-3, changed, x1, v1)
    after = v1.to_numpy().astype(float)
    assert np.array_equal(x1.to_numpy(), x.astype(dtype))  # nothing moved
    assert changed[0] == 1
    eps = 1e-5 if dtype == np.float32 else 1e-12
    momentum = mass[:pairs, None] * v[:pairs] + mass[pairs:, None] * v[pairs:]
    assert np.allclose(mass[:pairs, None] * after[:pairs] + mass[pairs:, None] * after[pairs:], momentum, atol=eps)
    normal_rel = np.sum((after[:pairs] - after[pairs:]) * axis, axis=1)
    stopped = kind == 0
    assert np.all(np.abs(normal_rel[stopped]) < eps)
    assert np.allclose(after[np.concatenate([~stopped, ~stopped])], v[np.concatenate([~stopped, ~stopped])], atol=eps)
    tangent_rel = (after[:pairs] - after[pairs:]) - normal_rel[:, None] * axis
    assert np.allclose(tangent_rel[stopped], 0.0, atol=eps)  # (both particles share the tangential velocity)
