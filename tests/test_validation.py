"""Bad input gets a clear error that names the argument, raised before any kernel runs.

The `no_kernels` fixture replaces every kernel launch point of tai_coll (and Taichi's
init/reset) with a stub that raises KernelRan, so an error that only surfaced from inside
a kernel, or after one ran, would fail these tests instead of passing them.
"""

import importlib
import warnings

import numpy as np
import pytest
import taichi as ti

import tai_coll as tc
from tai_coll import runtime
from tai_coll.geometry import queries
from tai_coll.solvers import impulse
from conftest import TEST_ARCH

# `tai_coll.response.collide` the module (the package re-exports the function of that name)
collide_module = importlib.import_module("tai_coll.response.collide")


class KernelRan(Exception):
    """A kernel (or a Taichi restart) was launched where validation should have stopped first."""


@pytest.fixture
def no_kernels(monkeypatch):
    def stub(name):
        def launch(*args, **kwargs):
            raise KernelRan(f"{name} ran before the bad argument was reported")
        return launch

    for module, name in ((impulse, "impulse_substep"), (collide_module, "_collide_kernel"),
                         (collide_module, "_pair_kernel"), (queries, "_sdf_kernel"),
                         (queries, "_crossing_kernel"), (runtime, "_start")):
        monkeypatch.setattr(module, name, stub(name))
    monkeypatch.setattr(ti, "init", stub("ti.init"))
    monkeypatch.setattr(ti, "reset", stub("ti.reset"))


def test_no_kernels_fixture_catches_launches(scene, no_kernels):
    """The stubs are live: valid calls that launch kernels do hit them."""
    with pytest.raises(KernelRan):
        tc.collide(V3, N3)
    with pytest.raises(KernelRan):
        tc.Sphere().signed_distance([[0.0, 0.0, 0.0]])
    with pytest.raises(KernelRan):
        tc.Sphere().crossing([[0.0, 2.0, 0.0]], [[0.0, 0.0, 0.0]])
    with pytest.raises(KernelRan):
        scene.step()


def free_fall_y(y0, gravity_y, dt, n):
    """Symplectic Euler from rest after n substeps: y0 + g dt^2 n (n + 1) / 2."""
    return y0 + gravity_y * dt * dt * n * (n + 1) / 2


@pytest.fixture
def scene():
    s = tc.Scene(dt=1e-3, substeps=4)
    s.add_particles(positions=[[0.0, 1.0, 0.0], [0.5, 2.0, 0.0]], radius=0.01)
    return s


# ---------------------------------------------------------------------------- Scene(...)

@pytest.mark.parametrize("kwargs, error, name", [
    (dict(dt=0), ValueError, "dt"),
    (dict(dt=-1e-3), ValueError, "dt"),
    (dict(dt=float("nan")), ValueError, "dt"),
    (dict(dt="0.01"), TypeError, "dt"),
    (dict(substeps=0), ValueError, "substeps"),
    (dict(substeps=-3), ValueError, "substeps"),
    (dict(substeps=2.5), TypeError, "substeps"),
    (dict(gravity=(0.0, -9.81)), ValueError, "gravity"),
    (dict(gravity=(0.0, -9.81, 0.0, 0.0)), ValueError, "gravity"),
    (dict(gravity=(0.0, float("nan"), 0.0)), ValueError, "gravity"),
    (dict(gravity=(0.0, float("-inf"), 0.0)), ValueError, "gravity"),
    (dict(domain=((0, 0, 0), (1, 0, 1))), ValueError, "domain"),     # hi == lo in y
    (dict(domain=((0, 0, 0), (1, -1, 1))), ValueError, "domain"),    # hi < lo in y
    (dict(domain=((1, 1, 1), (1, 1, 1))), ValueError, "domain"),
    (dict(domain=((0, 0, 0),)), ValueError, "domain"),
    (dict(domain=((0, 0), (1, 1))), ValueError, "domain"),
    (dict(solver="impulse"), TypeError, "solver"),
])
def test_scene_rejects_bad_configuration(kwargs, error, name, no_kernels):
    with pytest.raises(error, match=name):
        tc.Scene(**kwargs)


def test_scene_is_keyword_only():
    with pytest.raises(TypeError):
        tc.Scene((0.0, -9.81, 0.0))


# ---------------------------------------------------------------------------- add_particles

NAN, INF = float("nan"), float("inf")


@pytest.mark.parametrize("kwargs, error, name", [
    (dict(positions=[[0, 0, 0], [NAN, 0, 0]]), ValueError, "positions"),
    (dict(positions=[[0, INF, 0], [0, 0, 0]]), ValueError, "positions"),
    (dict(positions=[[0, 0, -INF], [0, 0, 0]]), ValueError, "positions"),
    (dict(positions=np.zeros((2, 2))), ValueError, "positions"),
    (dict(positions=np.zeros((2, 3, 1))), ValueError, "positions"),
    (dict(positions="here"), (TypeError, ValueError), "positions"),
    (dict(positions=np.zeros((2, 3)), velocities=[[0, 0, 0], [0, NAN, 0]]), ValueError, "velocities"),
    (dict(positions=np.zeros((2, 3)), velocities=[[INF, 0, 0], [0, 0, 0]]), ValueError, "velocities"),
    (dict(positions=np.zeros((2, 3)), velocities=np.zeros((3, 3))), ValueError, "velocities"),
    (dict(positions=np.zeros((2, 3)), velocities=np.zeros((2, 2))), ValueError, "velocities"),
    (dict(positions=np.zeros((2, 3)), radius=0.0), ValueError, "radius"),
    (dict(positions=np.zeros((2, 3)), radius=-0.01), ValueError, "radius"),
    (dict(positions=np.zeros((2, 3)), radius=[0.01, 0.0]), ValueError, "radius"),
    (dict(positions=np.zeros((2, 3)), radius=[0.01, NAN]), ValueError, "radius"),
    (dict(positions=np.zeros((2, 3)), radius=[0.01, 0.01, 0.01]), ValueError, "radius"),
    (dict(positions=np.zeros((2, 3)), radius=np.full((2, 1), 0.01)), ValueError, "radius"),
    (dict(positions=np.zeros((2, 3)), mass=0.0), ValueError, "mass"),
    (dict(positions=np.zeros((2, 3)), mass=-1.0), ValueError, "mass"),
    (dict(positions=np.zeros((2, 3)), mass=[1.0, -1.0]), ValueError, "mass"),
    (dict(positions=np.zeros((2, 3)), mass=[1.0]), ValueError, "mass"),
    (dict(positions=np.zeros((2, 3)), mass=INF), ValueError, "mass"),
])
def test_add_particles_rejects_bad_input(scene, kwargs, error, name, no_kernels):
    before = scene.positions()
    with pytest.raises(error, match=name):
        scene.add_particles(**kwargs)
    assert scene.num_particles == 2  # nothing was half-added
    np.testing.assert_array_equal(scene.positions(), before)


def test_add_particles_accepts_a_single_point_and_per_particle_arrays(scene):
    """The happy path next to the rejections: shapes that are fine are kept exactly."""
    sl = scene.add_particles(positions=[0.1, 0.2, 0.3], radius=0.02, mass=3.0)
    assert (sl.start, sl.stop) == (2, 3)
    sl = scene.add_particles(positions=np.ones((2, 3)), velocities=np.full((2, 3), 0.5),
                             radius=[0.01, 0.03], mass=[1.0, 2.0])
    assert (sl.start, sl.stop) == (3, 5)
    np.testing.assert_array_equal(scene.radii()[2:], [0.02, 0.01, 0.03])
    np.testing.assert_array_equal(scene.masses()[2:], [3.0, 1.0, 2.0])
    np.testing.assert_array_equal(scene.velocities()[3:], np.full((2, 3), 0.5))


# ---------------------------------------------------------------------------- Material

@pytest.mark.parametrize("kwargs, error, name", [
    (dict(restitution=-0.1), ValueError, "restitution"),
    (dict(restitution=1.0 + 1e-9), ValueError, "restitution"),
    (dict(restitution=2), ValueError, "restitution"),
    (dict(restitution=NAN), ValueError, "restitution"),
    (dict(restitution="high"), TypeError, "restitution"),
    (dict(friction=-0.1), ValueError, "friction"),
    (dict(friction=INF), ValueError, "friction"),
    (dict(wet_friction=-1.0), ValueError, "wet_friction"),
    (dict(wet_friction=NAN), ValueError, "wet_friction"),
])
def test_material_rejects_bad_coefficients(kwargs, error, name):
    with pytest.raises(error, match=name):
        tc.Material(**kwargs)


def test_material_bounds_are_inclusive():
    assert tc.Material(restitution=0.0, friction=0.0).restitution == 0.0
    assert tc.Material(restitution=1.0, wet_friction=0.0).restitution == 1.0


# ---------------------------------------------------------------------------- colliders

REFLECTION = np.diag([1.0, 1.0, -1.0])
SHEAR = np.array([[1.0, 0.2, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("make, error, name", [
    (lambda: tc.Plane(normal=(0, 0, 0)), ValueError, "normal"),
    (lambda: tc.Plane(normal=(0, NAN, 0)), ValueError, "normal"),
    (lambda: tc.Plane(normal=(0, 1)), ValueError, "normal"),
    (lambda: tc.Plane(point=(0, INF, 0)), ValueError, "point"),
    (lambda: tc.Sphere(radius=0), ValueError, "radius"),
    (lambda: tc.Sphere(radius=-1), ValueError, "radius"),
    (lambda: tc.Sphere(radius=NAN), ValueError, "radius"),
    (lambda: tc.Sphere(center=(0, 0)), ValueError, "center"),
    (lambda: tc.Box(half_extents=(1, 0, 1)), ValueError, "half_extents"),
    (lambda: tc.Box(half_extents=(1, 1, -0.5)), ValueError, "half_extents"),
    (lambda: tc.Box(half_extents=(1, 1)), ValueError, "half_extents"),
    (lambda: tc.Box(rotation=2 * np.eye(3)), ValueError, "rotation"),
    (lambda: tc.Box(rotation=SHEAR), ValueError, "rotation"),
    (lambda: tc.Box(rotation=REFLECTION), ValueError, "rotation"),
    (lambda: tc.Box(rotation=-np.eye(3)), ValueError, "rotation"),
    (lambda: tc.Box(rotation=np.eye(2)), ValueError, "rotation"),
    (lambda: tc.Box(rotation=np.full((3, 3), NAN)), ValueError, "rotation"),
    (lambda: tc.Cylinder(radius=0), ValueError, "radius"),
    (lambda: tc.Cylinder(radius=-0.1), ValueError, "radius"),
    (lambda: tc.Cylinder(half_height=0), ValueError, "half_height"),
    (lambda: tc.Cylinder(half_height=-1), ValueError, "half_height"),
    (lambda: tc.Cylinder(axis=(0, 0, 0)), ValueError, "axis"),
    (lambda: tc.Capsule(radius=0), ValueError, "radius"),
    (lambda: tc.Capsule(radius=-0.1), ValueError, "radius"),
    (lambda: tc.Capsule(half_height=0), ValueError, "half_height"),
    (lambda: tc.Capsule(half_height=-1), ValueError, "half_height"),
    (lambda: tc.Capsule(axis=(0, 0, 0)), ValueError, "axis"),
    (lambda: tc.Capsule.from_endpoints((1, 2, 3), (1, 2, 3), radius=0.1), ValueError, "a and b"),
    (lambda: tc.Capsule.from_endpoints((0, 0, 0), (0, 1, 0), radius=0), ValueError, "radius"),
    (lambda: tc.rotation_matrix((0, 0, 0), 1.0), ValueError, "axis"),
    (lambda: tc.rotation_matrix((0, NAN, 1), 1.0), ValueError, "axis"),
    (lambda: tc.rotation_matrix((INF, 0, 0), 1.0), ValueError, "axis"),
    (lambda: tc.rotation_matrix((1e300, 1e300, 0), 1.0), ValueError, "axis"),  # its length overflows
    (lambda: tc.rotation_matrix((0, 1), 1.0), ValueError, "axis"),
    (lambda: tc.rotation_matrix((0, 0, 1), NAN), ValueError, "angle"),
    (lambda: tc.rotation_matrix((0, 0, 1), INF), ValueError, "angle"),
    (lambda: tc.rotation_matrix((0, 0, 1), -INF), ValueError, "angle"),
    (lambda: tc.rotation_matrix((0, 0, 1), "0.5"), TypeError, "angle"),
])
def test_colliders_reject_bad_shapes(make, error, name, no_kernels):
    with pytest.raises(error, match=name):
        make()


@pytest.mark.parametrize("call, error, name", [
    (lambda s: s.signed_distance([[0, 0, NAN]]), ValueError, "points"),
    (lambda s: s.normal(np.zeros((4, 2))), ValueError, "points"),
    (lambda s: s.crossing(np.zeros((2, 3)), np.ones((3, 3))), ValueError, "starts and ends"),
    (lambda s: s.crossing([[0, 0, INF]], [[0, 0, 0]]), ValueError, "starts"),
    (lambda s: s.crossing([[0, 0, 0]], [[0, NAN, 0]]), ValueError, "ends"),
    (lambda s: s.crossing([[0, 0, 0]], [[0, 1, 0]], radius=-0.1), ValueError, "radius"),
])
def test_geometry_queries_reject_bad_points(call, error, name, no_kernels):
    with pytest.raises(error, match=name):
        call(tc.Sphere(radius=1.0))


# ---------------------------------------------------------------------------- tc.init

@pytest.mark.parametrize("kwargs, error, name", [
    (dict(arch="tpu"), ValueError, "arch"),
    (dict(arch=3), TypeError, "arch"),
    (dict(arch=None), TypeError, "arch"),
    (dict(arch="cpu", precision="f16"), ValueError, "precision"),
    (dict(arch="cpu", precision=64), ValueError, "precision"),
    (dict(arch="vulkan", precision="f64"), ValueError, "precision"),
    (dict(arch="cpu", threads=0), ValueError, "threads"),
    (dict(arch="cpu", threads=-2), ValueError, "threads"),
    (dict(arch="cpu", threads=1.5), TypeError, "threads"),
    (dict(arch="cpu", threads=10**6), ValueError, "threads must be from 1 to 1024"),
    (dict(arch="cpu", threads=runtime.MAX_THREADS + 1), ValueError, "threads"),
    (dict(arch="cpu", seed=-1), ValueError, "seed"),
    (dict(arch="cpu", seed=2**31), ValueError, "seed"),   # Taichi holds its seed in an int32
    (dict(arch="cpu", seed=2**64), ValueError, "seed"),
    (dict(arch="cpu", seed=1.0), ValueError, "seed"),
])
def test_init_rejects_bad_arguments_without_restarting(kwargs, error, name, no_kernels):
    before = runtime.info()
    with pytest.raises(error, match=name):
        tc.init(**kwargs)
    assert runtime.info() is before


def test_init_again_with_the_same_arguments_keeps_the_runtime():
    """Same arguments as tests/conftest.py: the same RuntimeInfo comes back, and a scene
    built before the call keeps running (its fields were not reset)."""
    before = runtime.info()
    scene = tc.Scene(dt=1e-3, substeps=5)
    scene.add_particles(positions=[[0.0, 1.0, 0.0]], radius=0.01)
    scene.step()
    info = tc.init(arch=before.requested_arch, precision="f64", threads=before.threads, seed=0)
    assert info is before
    assert (info.arch, info.precision) == (TEST_ARCH, "f64")
    scene.step()
    y = scene.positions()[0, 1]
    assert y == pytest.approx(free_fall_y(1.0, -9.81, 1e-3, 10), abs=1e-12)


# ---------------------------------------------------------------------------- ImpulseSolver

@pytest.mark.parametrize("kwargs, error, name", [
    (dict(scheme="bogus"), ValueError, "scheme"),
    (dict(max_iterations=0), ValueError, "max_iterations"),
    (dict(max_iterations=2.5), TypeError, "max_iterations"),
    (dict(elastic_iterations=-1), ValueError, "elastic_iterations"),
    (dict(push_fraction=0), ValueError, "push_fraction"),
    (dict(push_fraction=-0.1), ValueError, "push_fraction"),
    (dict(push_fraction=1.5), ValueError, "push_fraction"),
    (dict(max_push_speed=0), ValueError, "max_push_speed"),
    (dict(slop=-1e-3), ValueError, "slop"),
    (dict(rest_speed=-1.0), ValueError, "rest_speed"),
    (dict(wet_law="sticky"), ValueError, "wet_law"),
])
def test_impulse_solver_rejects_bad_settings(kwargs, error, name, no_kernels):
    with pytest.raises(error, match=name):
        tc.ImpulseSolver(**kwargs)


# ---------------------------------------------------------------------------- collide, collide_pair

V3 = np.array([[0.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, -2.0, 1.0]])
N3 = np.array([[0.0, 1.0, 0.0]] * 3)


@pytest.mark.parametrize("kwargs, error, name", [
    (dict(v=V3, n=(0.0, 0.0, 0.0)), ValueError, "^n must be non-zero"),
    (dict(v=V3, n=np.array([[0, 1, 0], [0, 0, 0], [1, 0, 0]])), ValueError, "^n must be non-zero"),
    (dict(v=V3, n=N3[:2]), ValueError, "^n must have shape"),
    (dict(v=V3, n=(0, 1)), ValueError, "^n must have shape"),
    (dict(v=V3, n=N3, restitution=2), ValueError, "restitution"),
    (dict(v=V3, n=N3, restitution=-0.5), ValueError, "restitution"),
    (dict(v=V3, n=N3, friction=-1), ValueError, "friction"),
    (dict(v=V3, n=N3, wet_friction=-1), ValueError, "wet_friction"),
    (dict(v=V3, n=N3, wet_law="sticky"), ValueError, "wet_law"),
    (dict(v=V3, n=N3, object_velocity=np.zeros((2, 3))), ValueError, "object_velocity"),
    (dict(v=V3, n=N3, object_velocity=(0, NAN, 0)), ValueError, "object_velocity"),
    (dict(v=[[0, NAN, 0]], n=(0, 1, 0)), ValueError, "^v must be finite"),
    (dict(v=np.zeros((3, 2)), n=(0, 1, 0)), ValueError, "^v must have shape"),
])
def test_collide_rejects_bad_input(kwargs, error, name, no_kernels):
    with pytest.raises(error, match=name):
        tc.collide(**kwargs)


@pytest.mark.parametrize("kwargs, error, name", [
    (dict(mass_a=0.0, mass_b=1.0), ValueError, "mass_a"),
    (dict(mass_a=1.0, mass_b=0.0), ValueError, "mass_b"),
    (dict(mass_a=-1.0, mass_b=1.0), ValueError, "mass_a"),
    (dict(mass_a=np.array([1.0, 0.0, 1.0]), mass_b=1.0), ValueError, "mass_a"),
    (dict(mass_a=NAN, mass_b=1.0), ValueError, "mass_a"),
    (dict(mass_a=INF, mass_b=INF), ValueError, "mass_a and mass_b"),
    (dict(mass_a=1.0, mass_b=1.0, vb=np.zeros((2, 3))), ValueError, "vb"),
    (dict(mass_a=1.0, mass_b=1.0, n=(0, 0, 0)), ValueError, "^n must be non-zero"),
    (dict(mass_a=1.0, mass_b=1.0, restitution=2.0), ValueError, "restitution"),
])
def test_collide_pair_rejects_bad_input(kwargs, error, name, no_kernels):
    args = dict(va=V3, vb=np.zeros((3, 3)), n=N3)
    args.update(kwargs)
    with pytest.raises(error, match=name):
        tc.collide_pair(**args)


# ---------------------------------------------------------------------------- add_collider

PLANE = tc.Plane()


@pytest.mark.parametrize("call, error, name", [
    (lambda s: s.add_collider("floor"), TypeError, "collider"),
    (lambda s: s.add_collider(None), TypeError, "collider"),
    (lambda s: s.add_collider({"kind": "plane"}), TypeError, "collider"),
    (lambda s: s.add_collider(PLANE, material={"restitution": 0.5}), TypeError, "material"),
    (lambda s: s.add_collider(PLANE, material=0.5), TypeError, "material"),
    (lambda s: s.add_collider(PLANE, velocity=(1, 0, 0), motion=lambda t: ((0, 0, 0), np.eye(3))),
     ValueError, "motion"),
    (lambda s: s.add_collider(PLANE, angular_velocity=(0, 1, 0), motion=lambda t: ((0, 0, 0), np.eye(3))),
     ValueError, "motion"),
    (lambda s: s.add_collider(PLANE, motion=3.0), TypeError, "motion"),
    (lambda s: s.add_collider(PLANE, motion=((0, 0, 0), np.eye(3))), TypeError, "motion"),
    (lambda s: s.add_collider(PLANE, velocity=(1, 0)), ValueError, "velocity"),
    (lambda s: s.add_collider(PLANE, velocity=(NAN, 0, 0)), ValueError, "velocity"),
    (lambda s: s.add_collider(PLANE, angular_velocity=(0, INF, 0)), ValueError, "angular_velocity"),
    (lambda s: s.add_collider(PLANE, motion=lambda t: "garbage"), TypeError, "motion"),
    (lambda s: s.add_collider(PLANE, motion=lambda t: ((0, 0), np.eye(3))), ValueError, "motion"),
    (lambda s: s.add_collider(PLANE, motion=lambda t: ((0, 0, 0), 2 * np.eye(3))), ValueError, "motion"),
])
def test_add_collider_rejects_bad_input(scene, call, error, name, no_kernels):
    with pytest.raises(error, match=name):
        call(scene)
    assert len(scene.colliders) == 0


def garbage_after_start(bad):
    """A motion that is fine at t = 0 (when the collider is added) and returns `bad` later."""
    def motion(t):
        return ((0.0, 0.0, 0.0), np.eye(3)) if t == 0 else bad
    return motion


@pytest.mark.parametrize("bad, error", [
    ("garbage", TypeError),
    (None, TypeError),
    (((0.0, 0.0, 0.0),), (TypeError, ValueError)),
    (((0.0, 0.0), np.eye(3)), ValueError),
    (((0.0, NAN, 0.0), np.eye(3)), ValueError),
    (((0.0, 0.0, 0.0), REFLECTION), ValueError),
    (((0.0, 0.0, 0.0), np.ones((3, 3))), ValueError),
])
def test_motion_returning_garbage_fails_at_step_naming_motion(scene, bad, error, no_kernels):
    scene.add_collider(tc.Plane(), motion=garbage_after_start(bad))
    before = scene.positions()
    with pytest.raises(error, match="motion"):
        scene.step()
    assert scene.time == 0.0
    np.testing.assert_array_equal(scene.positions(), before)


# ---------------------------------------------------------------------------- step, set_velocities

@pytest.mark.parametrize("frames, error", [(-1, ValueError), (1.5, TypeError), ("2", TypeError)])
def test_step_rejects_bad_frames(scene, frames, error, no_kernels):
    with pytest.raises(error, match="frames"):
        scene.step(frames=frames)
    assert scene.time == 0.0


def test_step_zero_frames_does_nothing(scene, no_kernels):
    before = scene.positions()
    scene.step(frames=0)
    assert scene.time == 0.0
    np.testing.assert_array_equal(scene.positions(), before)


@pytest.mark.parametrize("values", [np.zeros((3, 3)), np.zeros((2, 2)), np.zeros(6), [[0, 0, 0], [0, NAN, 0]]])
def test_set_velocities_rejects_bad_shape(scene, values, no_kernels):
    with pytest.raises(ValueError, match="velocities"):
        scene.set_velocities(values)
    np.testing.assert_array_equal(scene.velocities(), 0.0)


@pytest.mark.parametrize("values", [np.zeros((1, 3)), [[0, 0, 0], [INF, 0, 0]]])
def test_set_positions_rejects_bad_shape(scene, values, no_kernels):
    before = scene.positions()
    with pytest.raises(ValueError, match="positions"):
        scene.set_positions(values)
    np.testing.assert_array_equal(scene.positions(), before)


# ---------------------------------------------------------------------------- run-time failures

def test_particle_leaving_the_domain_is_frozen_with_a_warning():
    dt, substeps = 1e-3, 5
    scene = tc.Scene(dt=dt, substeps=substeps, domain=((-1, -1, -1), (1, 3, 1)))
    scene.add_particles(positions=[[0.0, 1.0, 0.0], [0.0, 2.0, 0.0], [0.5, 0.5, 0.5]],
                        velocities=[[0.0, 0.0, 0.0], [3000.0, 0.0, 0.0], [0.0, 0.0, 0.0]], radius=0.01)
    with pytest.warns(RuntimeWarning, match="left the domain"):
        scene.step()
    np.testing.assert_array_equal(scene.particle_status(), ["active", "left_domain", "active"])
    assert scene.stats()["left_domain"] == 1
    frozen = scene.positions()[1]
    assert frozen[0] > 1.0  # frozen where it left, outside the box

    # no new warning for the same particle; the others keep simulating
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        scene.step(frames=2)
    x = scene.positions()
    np.testing.assert_array_equal(x[1], frozen)
    n = 3 * substeps
    np.testing.assert_allclose(x[[0, 2], 1], [free_fall_y(1.0, -9.81, dt, n), free_fall_y(0.5, -9.81, dt, n)],
                               atol=1e-12)
    np.testing.assert_array_equal(scene.particle_status(), ["active", "left_domain", "active"])


def test_non_finite_particle_raises_simulation_error_naming_it():
    """dt * 1e308 m/s overflows the candidate position to inf in the integrator."""
    dt = 2.0
    scene = tc.Scene(dt=dt, substeps=1)
    scene.add_particles(positions=[[0.0, 1.0, 0.0], [0.0, 2.0, 0.0], [0.0, 3.0, 0.0]], radius=0.01)
    scene.set_velocities([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1e308, 0.0, 0.0]])
    with pytest.raises(tc.SimulationError, match=r"indices \[2\]"):
        scene.step()
    np.testing.assert_array_equal(scene.particle_status(), ["active", "active", "non_finite"])
    # frozen at its last finite state
    np.testing.assert_array_equal(scene.positions()[2], [0.0, 3.0, 0.0])
    assert np.all(np.isfinite(scene.positions())) and np.all(np.isfinite(scene.velocities()))
    # the others went on: one substep of free fall
    np.testing.assert_allclose(scene.positions()[:2, 1], [1.0 - 9.81 * dt * dt, 2.0 - 9.81 * dt * dt], atol=1e-12)
    # reported once: the next frame runs without raising, the frozen particle stays put
    scene.step()
    np.testing.assert_array_equal(scene.positions()[2], [0.0, 3.0, 0.0])
    np.testing.assert_allclose(scene.positions()[0, 1], free_fall_y(1.0, -9.81, dt, 2), atol=1e-9)
