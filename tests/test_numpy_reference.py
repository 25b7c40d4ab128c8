"""The NumPy reference (tools/numpy_reference.py) against tai_coll: the benchmark's baseline
must compute the same thing as the solver it is compared with.

Both run the default scheme (elastic_contact) in f64 from the same start. They evaluate the
same formulas in the same order, except the rotation into a box's frame, where Taichi's
matrix-vector product and NumPy's BLAS matmul round differently in the last bit. On this
scene no particle diverges (checked for 20,000 particles over 300 substeps), but such a
difference grows on a particle sliding over a curved surface, and once it tips a threshold
(the approach test, the slop band, a grazing crossing) the two runs follow different valid
trajectories. Hence the test asks for agreement of the vast majority, not of all.
"""

import numpy as np
import pytest

import tai_coll as tc
from tools import numpy_reference as nr  # the repository root is on sys.path: pyproject's pythonpath

SHAPES = [
    (tc.Plane(point=(0.0, 0.0, 0.0), normal=(0.0, 1.0, 0.0)), tc.Material()),
    (tc.Sphere(center=(-0.25, 0.2, 0.0), radius=0.15), tc.Material(restitution=0.8, friction=0.1)),
    (tc.Box(center=(0.25, 0.2, 0.0), half_extents=(0.12, 0.1, 0.15),
            rotation=tc.rotation_matrix((0.3, 1.0, 0.2), 0.5)),
     tc.Material(restitution=0.2, friction=0.6, wet_friction=0.05)),
]


def _clear_positions(rng, n):
    out = np.empty((0, 3))
    while len(out) < n:
        x = np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(0.02, 0.6, n), rng.uniform(-0.2, 0.2, n)])
        clear = np.ones(n, bool)
        for shape, _ in SHAPES:
            clear &= shape.signed_distance(x) > 0.006
        out = np.concatenate([out, x[clear]])
    return out[:n]


def _scene(rng, n, substeps=10):
    scene = tc.Scene(dt=1.0 / 600.0, substeps=substeps)
    for shape, material in SHAPES:
        scene.add_collider(shape, material=material)
    scene.add_particles(positions=_clear_positions(rng, n), velocities=rng.normal(scale=0.5, size=(n, 3)),
                        radius=0.005)
    return scene


def test_geometry_matches_tai_coll(rng):
    x = rng.uniform(-0.6, 0.7, (5000, 3))
    x1 = x + rng.normal(scale=0.1, size=x.shape)
    for shape, _ in SHAPES + [(tc.Plane(point=(0, 0.1, 0), normal=(1, 2, 0.3)), None)]:
        col = nr.StaticCollider.from_shape(shape)
        phi, n = col.signed_distance_normal(x.T)
        np.testing.assert_allclose(col.signed_distance(x.T), shape.signed_distance(x), atol=1e-12)
        np.testing.assert_allclose(phi, shape.signed_distance(x), atol=1e-12)
        np.testing.assert_allclose(n.T, shape.normal(x), atol=1e-12)
        for r in (0.0, 0.01):
            hit, t, nc = col.crossing(x.T, x1.T, r)
            hit_t, t_t, nc_t = shape.crossing(x, x1, radius=r)
            np.testing.assert_array_equal(hit, hit_t)
            np.testing.assert_allclose(t[hit], t_t[hit], atol=1e-9)
            np.testing.assert_allclose(nc.T[hit], nc_t[hit], atol=1e-9)


def test_one_substep_matches_to_round_off(rng):
    scene = _scene(rng, 2000, substeps=1)
    ref = nr.NumpyImpulseReference.from_scene(scene)
    for _ in range(30):
        scene.step(1)
        ref.step(1)
    np.testing.assert_allclose(ref.positions(), scene.positions(), atol=1e-12)
    np.testing.assert_allclose(ref.velocities(), scene.velocities(), atol=1e-9)


@pytest.mark.parametrize("reuse_geometry", [True, False])
def test_dropped_particles_agree(rng, reuse_geometry):
    """2000 particles dropped onto plane, sphere and box for 30 frames of 10 substeps."""
    scene = _scene(rng, 2000)
    ref = nr.NumpyImpulseReference.from_scene(scene, reuse_geometry=reuse_geometry)
    x0, v0 = scene.positions(), scene.velocities()
    scene.step(30)
    ref.step(30)
    d = np.linalg.norm(ref.positions() - scene.positions(), axis=1)
    assert np.mean(d < 1e-6) > 0.99, f"{np.sum(d >= 1e-6)} of {d.size} particles differ by >= 1e-6 m"
    assert np.median(d) < 1e-12
    # the scene exercised contacts: most particles left their free-fall parabola
    t = scene.time
    free = x0 + v0 * t + 0.5 * np.asarray(scene.gravity) * t * t
    touched = np.linalg.norm(scene.positions() - free, axis=1) > 1e-3
    assert touched.mean() > 0.9
    stats = scene.stats()
    assert abs(stats["repulsion"] - ref.stats["repulsion"]) <= 0.01 * max(stats["repulsion"], 100)
    assert abs(stats["failsafe"] - ref.stats["failsafe"]) <= 0.01 * max(stats["failsafe"], 100)


def test_float32_runs_and_stays_close(rng):
    """f32 on the NumPy side against the f64 solver: same physics at f32 round-off."""
    scene = _scene(rng, 500)
    ref = nr.NumpyImpulseReference.from_scene(scene, dtype=np.float32)
    scene.step(5)
    ref.step(5)
    assert ref.positions().dtype == np.float32
    d = np.linalg.norm(ref.positions() - scene.positions(), axis=1)
    assert np.mean(d < 1e-4) > 0.98


def test_unsupported_scenes_are_refused():
    scene = tc.Scene()
    scene.add_collider(tc.Capsule())
    scene.add_particles(positions=[[0.0, 2.0, 0.0]])
    with pytest.raises(ValueError, match="not supported"):
        nr.NumpyImpulseReference.from_scene(scene)
    scene = tc.Scene(solver=tc.ImpulseSolver(scheme="micro"))
    scene.add_particles(positions=[[0.0, 2.0, 0.0]])
    with pytest.raises(ValueError, match="elastic_contact"):
        nr.NumpyImpulseReference.from_scene(scene)
    scene = tc.Scene()
    scene.add_collider(tc.Sphere(), velocity=(1.0, 0.0, 0.0))
    scene.add_particles(positions=[[0.0, 2.0, 0.0]])
    with pytest.raises(ValueError, match="moving"):
        nr.NumpyImpulseReference.from_scene(scene)
