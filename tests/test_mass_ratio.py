"""Particles of very different masses and sizes (docs/physics.md 5.3.2): a heavy particle on a
light one on a floor keeps them apart by the sum of their radii (shock propagation), a large heavy
ball lands on a bed of small particles without swallowing them, momentum is kept where no
support is involved, DEM contacts too soft for their load are warned about, and particles
spawned on top of each other leave no faster than the push speed."""

import warnings

import numpy as np
import pytest

import tai_coll as tc
from tai_coll.neighbors import HashGrid
from tai_coll.solvers.pairs import gauss_seidel
from tai_coll.solvers.pairs.settings import MAX_PUSH_SPEED
from conftest import on_device


def _stack(masses, radius=0.01, method="gauss-seidel"):
    scene = tc.Scene(dt=1 / 600, substeps=10)
    scene.add_collider(tc.Plane(), material=tc.Material(restitution=0.0, friction=0.5))
    heights = radius + 2 * radius * np.arange(len(masses))
    scene.add_particles(positions=np.c_[np.zeros(len(masses)), heights, np.zeros(len(masses))], radius=radius,
                        mass=np.asarray(masses, dtype=float))
    scene.enable_particle_collisions(method=method, material=tc.Material(restitution=0.0, friction=0.5))
    return scene


@pytest.mark.parametrize("masses", [(1e-6, 1e3), (1e-3, 1e-3, 1e3), (1e-6, 1.0, 1e3), (1.0, 1e-6, 1e-3)])
def test_a_heavy_particle_rests_on_light_ones_apart_by_the_sum_of_radii(masses):
    scene = _stack(masses)
    scene.step(60)  # 1 s
    y = scene.positions()[:, 1]
    gaps = np.diff(y)
    assert np.all(np.abs(gaps - 0.02) <= 0.05 * 0.02), gaps
    assert y[0] == pytest.approx(0.01, rel=0.05)  # the bottom one is on the floor, not in it
    assert np.all(np.isfinite(scene.velocities())) and np.abs(scene.velocities()).max() < 1e-3


def test_equal_masses_need_no_shock_propagation():
    # (the stack of one mass is held as before: support from the floor climbs within a pass)
    scene = _stack((1.0, 1.0, 1.0))
    scene.step(60)
    assert np.diff(scene.positions()[:, 1]) == pytest.approx(0.02, rel=0.05)
    assert scene.particle_collisions.levels is None  # never allocated: not needed


def test_momentum_is_kept_between_heavy_and_light_particles_in_flight():
    # no support (no collider): the shock pass leaves pairs to the split by inverse mass
    scene = tc.Scene(dt=1 / 600, substeps=10)
    masses = np.array([1e3, 1e-3])
    scene.add_particles(positions=[[0.0, 1.0, 0.0], [0.05, 1.0, 0.0]], velocities=[[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]],
                        radius=0.01, mass=masses)
    scene.enable_particle_collisions(material=tc.Material(restitution=0.5, friction=0.0))
    scene.step(6)  # they meet within 25 ms
    v = scene.velocities()
    momentum = (masses[:, None] * v).sum(0)
    expected = (masses[:, None] * np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])).sum(0) \
        + masses.sum() * np.asarray(scene.gravity) * scene.time
    assert momentum == pytest.approx(expected, rel=1e-5, abs=1e-6)
    assert v[1, 0] > v[0, 0]  # the light one bounced off the heavy one


def test_a_heavy_ball_lands_on_a_bed_of_small_particles_without_swallowing_them():
    r, big = 0.005, 0.05
    scene = tc.Scene(dt=1 / 1200, substeps=10)
    material = tc.Material(restitution=0.1, friction=0.5)
    scene.add_collider(tc.Plane(), material=material)
    half = 0.08
    for axis in (0, 2):
        for side in (-1, 1):
            point, normal = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
            point[axis], normal[axis] = side * half, -side
            scene.add_collider(tc.Plane(point=tuple(point), normal=tuple(normal)), material=material)
    grid = np.arange(-half + 1.1 * r, half - 1.1 * r, 2.2 * r)
    gx, gy, gz = np.meshgrid(grid, 1.1 * r + 2.2 * r * np.arange(2), grid, indexing="ij")
    bed = np.c_[gx.ravel(), gy.ravel(), gz.ravel()]
    scene.add_particles(positions=bed, radius=r, mass=2500 * 4 / 3 * np.pi * r ** 3)
    scene.add_particles(positions=[[0.0, 0.15, 0.0]], radius=big, mass=100.0)  # mass ratio 7.6e4, radius 10
    pairs = scene.enable_particle_collisions(material=material)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no neighbour-list overflow
        scene.step(40)
    x = scene.positions()
    gap = np.linalg.norm(x[:-1] - x[-1], axis=1) - (big + r)
    assert gap.min() > -0.05 * r  # no small particle inside the ball
    assert x[-1, 1] > big + 2 * r  # it rests on the bed, not on the floor
    assert pairs.neighbour_overflow == 0


@pytest.mark.parametrize("margin_radii", [0.0, 0.25])
def test_lists_of_a_large_particle_among_small_ones_hold_each_pair_once(margin_radii):
    # by_radius: each pair in the list of its smaller particle, so the large one's hundreds of
    # neighbours do not overflow its list; reach r_i + r_j + margin_radii * min(r_i, r_j)
    rng = np.random.default_rng(3)
    r, big = 0.005, 0.1
    small = rng.uniform(-0.13, 0.13, (4000, 3))
    x = np.r_[small[np.linalg.norm(small, axis=1) > big], [[0.0, 0.0, 0.0]]]
    radius = np.r_[np.full(len(x) - 1, r), [big]]
    n = len(x)
    grid = HashGrid()
    grid.build(on_device(x), on_device(radius), on_device(np.zeros(n, int)), n, (2 + margin_radii) * big, 0.0,
               forward=True, margin_radii=margin_radii, by_radius=True)
    d = np.linalg.norm(x[:, None] - x[None], axis=2)
    reach = radius[:, None] + radius[None] + margin_radii * np.minimum(radius[:, None], radius[None])
    lists = grid.neighbour_lists(n)
    for i in range(n):
        assert np.array_equal(lists[i], np.flatnonzero((d[i] < reach[i]) & (np.arange(n) != i))), i
    counts = grid.neighbour_count.to_numpy()[:n]
    assert counts[-1] == 0 and len(lists[-1]) > 100  # the large one lists none, and is in 100+ lists
    assert counts.sum() == sum(len(row) for row in lists) // 2
    assert grid.dropped() == 0


def _dem_stack(masses, radius=0.01):
    # hertz=: each contact as stiff as its (reduced) mass, the light particle's as soft as its own
    scene = tc.Scene(solver=tc.PenaltySolver(hertz=200), dt=5e-5, substeps=100)
    scene.add_collider(tc.Plane(), material=tc.Material(restitution=0.0, friction=0.5))
    heights = radius + 2 * radius * np.arange(len(masses))
    scene.add_particles(positions=np.c_[np.zeros(len(masses)), heights, np.zeros(len(masses))], radius=radius,
                        mass=np.asarray(masses, dtype=float))
    scene.enable_particle_collisions(material=tc.Material(restitution=0.0, friction=0.5))
    return scene


@pytest.mark.parametrize("masses", [(1e-6, 1e3), (1e-3, 1e-3, 1e3), (1.0, 1e-6, 1e-3)])
def test_dem_a_heavy_particle_rests_on_light_ones_apart_by_the_sum_of_radii(masses):
    # A spring on a 1e-6 kg particle cannot hold 1e3 kg (it would need k >= 2e7 N/m, stable only
    # below dt = 2e-7 s): without the overlap limit the heavy one sank to 10 mm from the light
    # one, which sat with its centre on the floor. The limit (shock.DEM_OVERLAP_LIMIT, 2.5 % of
    # the radius) keeps both within 5 %.
    scene = _dem_stack(masses)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing crushed, nothing to warn about
        scene.step(15)  # 0.075 s
    y = scene.positions()[:, 1]
    assert np.all(np.abs(np.diff(y) - 0.02) <= 0.05 * 0.02), np.diff(y)
    assert y[0] == pytest.approx(0.01, rel=0.05)  # the bottom one is on the floor, not in it
    assert np.abs(scene.velocities()).max() < 1e-2


def test_dem_momentum_is_kept_between_heavy_and_light_particles_in_flight():
    # no support: the overlap limit splits by inverse mass, as the spring does
    masses = np.array([1e3, 1e-3])
    scene = tc.Scene(solver=tc.PenaltySolver(hertz=200), dt=5e-5, substeps=100)
    scene.add_particles(positions=[[0.0, 1.0, 0.0], [0.025, 1.0, 0.0]], velocities=[[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]],
                        radius=0.01, mass=masses)
    scene.enable_particle_collisions(material=tc.Material(restitution=0.5, friction=0.0))
    scene.step(2)  # they meet within 2.5 ms, the deepest 2 m/s / (2 pi 200 Hz) = 1.6 mm: beyond the limit
    v = scene.velocities()
    momentum = (masses[:, None] * v).sum(0)
    expected = masses.sum() * (np.array([1.0, 0.0, 0.0]) * (1e3 - 1e-3) / masses.sum()
                               + np.asarray(scene.gravity) * scene.time)
    assert momentum == pytest.approx(expected, rel=1e-5, abs=1e-6)
    assert v[1, 0] > v[0, 0]  # the light one bounced off the heavy one


def test_dem_particles_of_very_different_masses_spawned_on_one_point_gain_no_speed():
    # placed overlap is the separation's, by positions; the overlap limit must not turn it into
    # velocity (before it excluded the allowances, 40 of them left at 208 m/s)
    n, height = 20, 0.05
    scene = tc.Scene(solver=tc.PenaltySolver(hertz=200), substeps="auto")
    scene.add_collider(tc.Plane(), material=tc.Material(restitution=0.0))
    masses = np.where(np.arange(n) % 2 == 0, 1e-3, 1.0)
    scene.add_particles(positions=np.tile([[0.0, height, 0.0]], (n, 1)), radius=0.005, mass=masses)
    scene.enable_particle_collisions()
    fastest = 0.0
    for _ in range(20):
        scene.step()
        fastest = max(fastest, float(np.linalg.norm(scene.velocities(), axis=1).max()))
    assert fastest <= np.sqrt(2 * 9.81 * height) + MAX_PUSH_SPEED
    assert scene.particle_overlap()["max"] <= 1.1 * 0.025  # at rest in a pile, within the limit


def test_dem_particles_of_very_different_masses_pushed_by_a_paddle_are_not_thrown():
    # the overlap limit moves positions only, not into colliders, and stops approaches: when
    # the velocity followed its moves (dx / dt over DEM's 1e-5 s substeps), 400 such particles
    # pushed at 1 m/s reached 155 m/s (4.5 m/s without the limit, 1.7 with equal masses)
    rng = np.random.default_rng(1)
    scene = tc.Scene(solver=tc.PenaltySolver(hertz=300), substeps="auto")
    scene.add_collider(tc.Plane(), material=tc.Material(restitution=0.0, friction=0.5))
    g = np.arange(-0.03, 0.03, 0.0105)
    gx, gy, gz = np.meshgrid(g, 0.006 + 0.0105 * np.arange(3), g, indexing="ij")
    x = np.c_[gx.ravel(), gy.ravel(), gz.ravel()]
    scene.add_particles(positions=x, radius=0.005, mass=np.where(rng.random(len(x)) < 0.3, 0.5, 1e-3))
    scene.enable_particle_collisions()
    scene.add_collider(tc.Box(center=(-0.06, 0.02, 0.0), half_extents=(0.01, 0.02, 0.05)), velocity=(1.0, 0.0, 0.0))
    fastest = 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (jammed against the paddle, some pairs overlap: warned)
        for _ in range(6):
            scene.step()
            fastest = max(fastest, float(np.linalg.norm(scene.velocities(), axis=1).max()))
    assert np.all(np.isfinite(scene.positions()))
    assert fastest < 10.0


def test_dem_contacts_too_soft_for_their_load_are_warned_about():
    # equal masses (no overlap limit): a column of 10 on hertz=20 contacts, the lowest
    # holding 9 weights at 9 g / (2 pi 20 Hz)^2 = 5.6 mm, more than a quarter of the radius
    scene = tc.Scene(solver=tc.PenaltySolver(hertz=20), substeps="auto")
    scene.add_collider(tc.Plane(), material=tc.Material(restitution=0.0))
    scene.add_particles(positions=np.c_[np.zeros(10), 0.01 + 0.02 * np.arange(10), np.zeros(10)], radius=0.01)
    scene.enable_particle_collisions()
    with pytest.warns(RuntimeWarning, match="too soft for the load"):
        scene.step(30)


@pytest.mark.parametrize("count, layout", [(36, "slabs"), (40, "slabs"), (44, "slabs"), (48, "slabs"), (40, "units"),
                                           (48, "units"), pytest.param(1000, "slabs", marks=pytest.mark.slow)])
def test_coincident_particles_separate_without_energy_beyond_the_push_speed(count, layout, monkeypatch):
    # Particles spawned all in one place separate by positions, the velocity the separation
    # leaves capped by the push speed relative to the crowd's, the momentum kept: no particle
    # is faster than 1 m/s (issue [2 of 6]'s bound for the random cube), the crowd carries no
    # more kinetic energy than every particle at the push speed would (1,000: 5 % more), and it
    # is apart within the 30 frames, in either pair order (the CPU's slabs, or the GPUs' units
    # run here). A particle may pass the push speed itself (36 to 48: up to 0.64 m/s at 0.80 to
    # 0.84 of the energy bound; 1,000: 0.73 m/s at 1.03): the crowd's particles, leaving in every
    # direction, meet again and share their momentum in the velocity passes, which never add
    # energy, and a particle that enters the next substep's passes faster than the push speed
    # may leave them as fast. As the crowd comes apart it breaks into smaller crowds, each
    # capped relative to its own mean velocity (docs/design-notes.md, "Coincident centres",
    # "Crowds keep their momentum").
    if layout == "units":
        monkeypatch.setattr(gauss_seidel, "colouring", lambda: dict(slabs=0, unit_bits=gauss_seidel.UNIT_BITS))
    scene = tc.Scene(gravity=(0, 0, 0))
    scene.add_particles(positions=np.zeros((count, 3)), radius=0.005)
    scene.enable_particle_collisions()
    fastest, energy = 0.0, 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (1,000 in one place overflow the neighbour lists, and say so)
        for _ in range(30):
            scene.step()
            v = scene.velocities()
            speed = np.linalg.norm(v, axis=1)
            fastest = max(fastest, float(speed.max()))
            energy = max(energy, float(np.sum(speed ** 2)) / (count * MAX_PUSH_SPEED ** 2))  # (equal masses)
            assert np.linalg.norm(v.sum(axis=0)) <= 1e-12 * count * MAX_PUSH_SPEED  # momentum kept
    assert fastest <= 1.0
    assert energy <= (1.05 if count > 100 else 1.0)
    assert scene.particle_overlap()["max"] < 0.01
