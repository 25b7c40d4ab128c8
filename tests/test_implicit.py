"""tc.Implicit: a user's f(x) = 0, as a Taichi function or a sampled numpy function.

References are the closed-form sphere and torus distances, written here in numpy.
"""

import numpy as np
import pytest
import taichi as ti

import tai_coll as tc

vec3 = ti.math.vec3


@ti.func
def unit_ball(p: vec3):
    return p.norm() - 1.0


@ti.func
def unit_ball_gradient(p: vec3):
    return p / ti.max(p.norm(), 1e-12)


@ti.func
def squared_ball(p: vec3):
    """|p|^2 - 1: zero on the unit sphere, not a distance (|grad| = 2|p|)."""
    return p.dot(p) - 1.0


@ti.func
def ring(p: vec3):
    """Torus about the y axis, radii 0.6 and 0.2."""
    q = ti.math.vec2(ti.sqrt(p.x * p.x + p.z * p.z) - 0.6, p.y)
    return q.norm() - 0.2


def ref_ring(x):
    return np.hypot(np.hypot(x[:, 0], x[:, 2]) - 0.6, x[:, 1]) - 0.2


def test_taichi_function_matches_analytic_sphere(rng):
    ball = tc.Implicit(unit_ball, center=(0.5, 0.0, 0.0), bounds=((-1, -1, -1), (1, 1, 1)))
    with_gradient = tc.Implicit(unit_ball, gradient=unit_ball_gradient, center=(0.5, 0.0, 0.0))
    x = rng.uniform(-2.0, 2.0, size=(500, 3))
    r = np.linalg.norm(x - [0.5, 0.0, 0.0], axis=1)
    for shape in (ball, with_gradient):
        assert np.allclose(shape.signed_distance(x), r - 1.0, atol=1e-12)
        assert np.allclose(shape.normal(x), (x - [0.5, 0.0, 0.0]) / r[:, None], atol=1e-6)
    assert ball.kind != with_gradient.kind  # one kind per (function, gradient) pair
    assert tc.Implicit(unit_ball).kind == ball.kind
    assert ball.params[3] == pytest.approx(np.sqrt(3.0))
    # Crossing by root finding against the quadratic's first root.
    starts = np.array([[0.5, 3.0, 0.0], [3.0, 0.3, 0.1], [3.0, 3.0, 0.0]])
    ends = np.array([[0.5, -3.0, 0.0], [-3.0, 0.3, 0.1], [4.0, 3.0, 0.0]])
    hit, t, n = ball.crossing(starts, ends, radius=0.1)
    assert hit.tolist() == [True, True, False]
    d = ends - starts
    o = starts - [0.5, 0.0, 0.0]
    a, b, c = (d * d).sum(1), (o * d).sum(1), (o * o).sum(1) - 1.1 ** 2
    expected = (-b[:2] - np.sqrt(b[:2] ** 2 - a[:2] * c[:2])) / a[:2]
    assert np.allclose(t[:2], expected, atol=1e-6)


def test_lipschitz_scaling_keeps_phi_conservative(rng):
    """f = |p|^2 - 1 has |grad f| <= 4 within |p| <= 2: phi = f / 4 never exceeds the
    distance, its zero set is the unit sphere, and the crossing of points is exact."""
    shape = tc.Implicit(squared_ball, lipschitz=4.0, bounds=((-2, -2, -2), (2, 2, 2)))
    x = rng.uniform(-1.1, 1.1, size=(500, 3))
    x = x[np.linalg.norm(x, axis=1) < 2.0]
    phi = shape.signed_distance(x)
    true = np.linalg.norm(x, axis=1) - 1.0
    assert np.all(np.abs(phi) <= np.abs(true) + 1e-12) and np.all(np.sign(phi) == np.sign(true))
    hit, t, _ = shape.crossing(np.array([[0.0, 1.9, 0.0]]), np.array([[0.0, -1.9, 0.0]]), radius=0.0)
    assert hit[0] and t[0] == pytest.approx(0.9 / 3.8, abs=1e-6)


def test_nonconvex_taichi_function_crossing():
    """A torus: a drop through the hole misses, one started in the hole finds the inner wall."""
    shape = tc.Implicit(ring, bounds=((-0.8, -0.2, -0.8), (0.8, 0.2, 0.8)))
    starts = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 0.0], [0.6, 1.0, 0.0]])
    ends = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.6, -1.0, 0.0]])
    hit, t, n = shape.crossing(starts, ends, radius=0.05)
    assert hit.tolist() == [False, True, True]
    assert t[1] == pytest.approx(0.35, abs=1e-5)
    assert t[2] == pytest.approx((1.0 - 0.25) / 2.0, abs=1e-5)
    assert np.allclose(n[1], [-1.0, 0.0, 0.0], atol=1e-5)


def test_numpy_function_sampled_on_a_grid(rng):
    def ring_numpy(points):
        return ref_ring(points)

    shape = tc.Implicit(ring_numpy, bounds=((-0.9, -0.3, -0.9), (0.9, 0.3, 0.9)), resolution=64,
                        center=(0.0, 1.0, 0.0))
    assert shape.kind == tc.MeshSDF.kind  # the same grid path as a baked mesh
    h = shape.voxel_size
    x = rng.uniform([-0.85, -0.25, -0.85], [0.85, 0.25, 0.85], size=(3000, 3))
    phi = shape.signed_distance(x + [0.0, 1.0, 0.0])
    exact = ref_ring(x)
    band = np.abs(exact) < 3 * h  # away from the kink of the distance at the tube's core circle
    assert np.max(np.abs(phi - exact)[band]) < 0.1 * h
    with pytest.raises(ValueError, match="bounds"):
        tc.Implicit(ring_numpy)
    with pytest.raises(ValueError, match="one value per point"):
        tc.Implicit(lambda p: p, bounds=((-1, -1, -1), (1, 1, 1)), resolution=8)
    with pytest.raises(ValueError, match="NaN"):
        tc.Implicit(lambda p: np.full(len(p), np.nan), bounds=((-1, -1, -1), (1, 1, 1)), resolution=8)


def test_validation():
    with pytest.raises(TypeError):
        tc.Implicit(42)
    with pytest.raises(ValueError, match="lipschitz"):
        tc.Implicit(unit_ball, lipschitz=0.0)
    with pytest.raises(ValueError, match="numpy functions only"):
        tc.Implicit(unit_ball, resolution=32)
    with pytest.raises(ValueError, match="upper corner"):
        tc.Implicit(unit_ball, bounds=((1, 1, 1), (0, 0, 0)))


def test_particles_bounce_on_an_implicit_ball():
    """Particles dropped on an implicit ball stay outside and rebound (restitution 0.5)."""
    scene = tc.Scene(gravity=(0.0, -9.81, 0.0), dt=1.0 / 1200.0, substeps=20)
    scene.add_collider(tc.Implicit(unit_ball, bounds=((-1, -1, -1), (1, 1, 1))),
                       material=tc.Material(restitution=0.5, friction=0.0))
    starts = np.array([[0.0, 1.5, 0.0], [0.1, 1.6, 0.05], [-0.2, 1.4, 0.1]])
    scene.add_particles(positions=starts, radius=0.02)
    rose = np.zeros(3, dtype=bool)
    for _ in range(30):
        scene.step()
        x = scene.positions()
        assert np.all(np.linalg.norm(x, axis=1) > 1.0 + 0.02 - 2e-3)
        rose |= scene.velocities()[:, 1] > 0.1
    assert rose.all()
