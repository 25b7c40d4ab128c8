"""The public names of 0.1: settings in SI units, the solver interface, and the old names
that keep working for a while (with a DeprecationWarning, the same behaviour)."""

import numpy as np
import pytest

import tai_coll as tc
from conftest import pile_scene


def falling_row(solver, n=5):
    """A few particles dropped on a floor with a ball in the way: every contact path runs."""
    scene = tc.Scene(dt=1e-3, substeps=10, solver=solver)
    scene.add_collider(tc.Plane(), material=tc.Material(restitution=0.5, friction=0.3))
    scene.add_collider(tc.Sphere(center=(0.0, 0.05, 0.0), radius=0.05))
    scene.add_particles(positions=np.column_stack([np.linspace(-0.02, 0.02, n), np.full(n, 0.2), np.zeros(n)]),
                        velocities=np.tile([0.1, 0.0, 0.05], (n, 1)), radius=0.01)
    return scene


def test_spin_is_the_penalty_solvers_switch_for_spinning_particles():
    assert tc.PenaltySolver(hertz=15.0, spin=True).spin
    with pytest.warns(DeprecationWarning, match="rotation= is now called spin="):
        old = tc.PenaltySolver(hertz=15.0, rotation=True)
    assert old.spin and "spin=True" in repr(old)
    with pytest.raises(TypeError, match="spin"):
        tc.PenaltySolver(hertz=15.0, spin=True, rotation=True)
    # the same run either way
    runs = []
    for solver in (tc.PenaltySolver(hertz=15.0, spin=True), old):
        scene = falling_row(solver)
        scene.step(30)
        runs.append((scene.positions(), scene.angular_velocities()))
    assert np.array_equal(runs[0][0], runs[1][0]) and np.array_equal(runs[0][1], runs[1][1])
    assert np.abs(runs[0][1]).max() > 0  # they did spin


def test_push_fraction_and_max_push_speed_are_the_last_resorts_settings():
    solver = tc.ImpulseSolver(push_fraction=0.3, max_push_speed=0.5)
    assert (solver.push_fraction, solver.max_push_speed) == (0.3, 0.5)
    with pytest.warns(DeprecationWarning, match="(repulsion|repulsion_speed_limit)= is now called"):
        old = tc.ImpulseSolver(repulsion=0.3, repulsion_speed_limit=0.5)
    assert (old.push_fraction, old.max_push_speed) == (0.3, 0.5)
    with pytest.raises(TypeError, match="push_fraction"):
        tc.ImpulseSolver(push_fraction=0.3, repulsion=0.3)
    with pytest.raises(ValueError, match="max_push_speed"):
        tc.ImpulseSolver(max_push_speed=0.0)


def test_particle_status_and_stats_are_two_different_things():
    scene = falling_row(tc.ImpulseSolver())
    scene.step(2)
    assert list(scene.particle_status()) == ["active"] * 5
    assert set(scene.stats()) == {"failsafe", "repulsion", "non_finite", "left_domain", "substeps", "dt",
                                  "substep_limit"}
    with pytest.warns(DeprecationWarning, match="particle_status") as caught:
        assert np.array_equal(scene.status(), scene.particle_status())
    assert [w.filename for w in caught] == [__file__]  # the caller's line, through the runtime guard


@pytest.mark.parametrize("method", ["gauss-seidel", "jacobi"])
def test_margin_and_skin_in_metres_match_their_old_fractions(method):
    # contact_margin and verlet_skin (m) against the old dimensionless margin and skin
    # (fractions of the largest radius, 10 mm here): the same lists, the same run, bit for bit.
    r = 0.01
    x = np.array([[0.0, r + k * 2.05 * r, 0.0] for k in range(8)]) + [[0.001 * k, 0.0, 0.0] for k in range(8)]
    runs = []
    for options in (dict(contact_margin=0.4 * r, verlet_skin=0.5 * r), dict(margin=0.4, skin=0.5)):
        if "margin" in options:
            with pytest.warns(DeprecationWarning, match="now (contact_margin|verlet_skin)= in metres"):
                scene, pairs = pile_scene(method=method, **options)
        else:
            scene, pairs = pile_scene(method=method, **options)
        scene.add_particles(positions=x, radius=r)
        scene.step(20)
        runs.append((scene.positions(), scene.velocities(), pairs.list_builds))
    assert np.array_equal(runs[0][0], runs[1][0]) and np.array_equal(runs[0][1], runs[1][1])
    assert runs[0][2] == runs[1][2] < 100  # the lists were kept between substeps
    assert pairs.settings.skin_length(r) == 0.5 * r and pairs.settings.margin_length(r) == 0.4 * r


def test_pair_settings_are_validated_and_read_through_the_handle():
    scene = tc.Scene()
    pairs = scene.enable_particle_collisions(contact_margin=0.002, iterations=3)
    assert scene.particle_collisions is pairs
    assert isinstance(pairs.settings, tc.PairSettings)
    assert (pairs.settings.iterations, pairs.iterations, pairs.contact_margin) == (3, 3, 0.002)
    assert pairs.settings.margin_length(1.0) == 0.002
    assert tc.PairSettings().margin_length(0.02) == 0.25 * 0.02  # default: a quarter of the largest radius
    with pytest.raises(ValueError, match="contact_margin"):
        scene.enable_particle_collisions(contact_margin=-0.001)
    with pytest.raises(ValueError, match="verlet_skin"):
        scene.enable_particle_collisions(verlet_skin=float("nan"))
    with pytest.raises(TypeError, match="verlet_skin"):
        scene.enable_particle_collisions(verlet_skin=0.001, skin=0.5)
    with pytest.raises(AttributeError, match="no_such_setting"):
        pairs.no_such_setting


def test_a_solver_is_an_instance_of_the_solver_interface():
    with pytest.raises(TypeError, match="solver"):
        tc.Scene(solver=tc.ImpulseSolver)  # the class, not a solver

    class Incomplete(tc.Solver):
        def advance(self, world, dt, substeps=1):
            pass

    with pytest.raises(TypeError, match="pair_substep"):
        Incomplete()
    assert tc.ImpulseSolver().pair_model == "impulses" and tc.PenaltySolver(hertz=10.0).pair_model == "dem"


def test_gravity_set_on_a_running_scene_reaches_the_solver():
    scene = tc.Scene(dt=1e-3, substeps=10)
    scene.add_particles(positions=[[0.0, 1.0, 0.0]])
    scene.step(1)
    scene.gravity = (0.0, 0.0, 0.0)
    v = scene.velocities().copy()
    scene.step(1)
    assert np.array_equal(scene.velocities(), v)
    with pytest.raises(ValueError, match="gravity"):
        scene.gravity = (0.0, float("inf"), 0.0)
