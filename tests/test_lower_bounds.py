"""Large particles against terrain, exact meshes and mesh grids: contact needs the true
distance within the particle's radius, however large the particle (issue 25, "distance
lower bounds read as contact"; docs/physics.md 1.2).

Each collider kind used to answer some points with a lower bound on the distance (a height
field beyond a few cells from a steep step, a triangle mesh beyond a few cells, a grid
beyond its padding), and a ball larger than that reach stopped in mid-air. Named scenes
check where a ball comes to rest against closed forms; the queries are checked against
analytic distances (a step, a box) at distances up to and beyond the radius, with and
without a reach (the distance within which a caller needs phi exact).

The session runs in f64 (tests/conftest.py).
"""

import numpy as np
import pytest
import taichi as ti
import trimesh

import tai_coll as tc

PHI_TOL = 1e-9  # exact queries (f64)
REST_TOL = 1e-3  # m: where a ball comes to rest against the closed form (the solver's slop is far below)
STILL = tc.Material(restitution=0.0, friction=0.5)
SLIDING = tc.Material(restitution=0.0, friction=0.0)
APPROACH = 0.1  # m/s: a ball moving into a wall stops within one substep's travel of it (0.17 mm)

# The step: heights 0 for x <= 0.95, 1 for x >= 1.0 (20 of 40 rows each, cells of 5 cm), a
# ramp of slope 20 between; the terrain continues flat beyond its 2 m x 2 m footprint.
STEP_CELL = 0.05
STEP_FOOT = 0.95  # x where the ramp starts
STEP_TOP = 1.0    # x where the plateau starts, at height 1


def step_field():
    return tc.HeightField(heights=np.r_[np.zeros((20, 40)), np.ones((20, 40))], cell_size=STEP_CELL)


def step_distance(p):
    """Signed distance to the step, in closed form: the terrain does not vary along z, so
    it is the distance in the (x, y) plane to the polyline (-inf, 0) - (0.95, 0) - (1, 1) -
    (+inf, 1), negative below it."""
    x, y = p[:, 0], p[:, 1]
    a, b = np.array([STEP_FOOT, 0.0]), np.array([STEP_TOP, 1.0])
    q = np.column_stack([x, y])
    s = np.clip(((q - a) @ (b - a)) / ((b - a) @ (b - a)), 0.0, 1.0)
    ramp = np.linalg.norm(q - (a + s[:, None] * (b - a)), axis=1)
    floor = np.hypot(np.maximum(x - STEP_FOOT, 0.0), y)
    plateau = np.hypot(np.minimum(x - STEP_TOP, 0.0), y - 1.0)
    surface = np.interp(x, [STEP_FOOT, STEP_TOP], [0.0, 1.0])
    return np.where(y < surface, -1.0, 1.0) * np.minimum(np.minimum(ramp, floor), plateau)


def box_distance(p, half=0.5):
    """Signed distance to the cube [-half, half]^3."""
    q = np.abs(p) - half
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def cube_mesh():
    return trimesh.creation.box(extents=(1.0, 1.0, 1.0))


def cube_triangles(cell_size=0.01):
    """The unit cube as exact triangles in cells of 1 cm, a hundredth of its side."""
    return tc.TriangleMesh(cube_mesh(), cell_size=cell_size)


def cube_grid():
    """The unit cube baked at resolution 64: 4 cells of padding, 7 cm, less than the radii below."""
    return tc.MeshSDF(cube_mesh(), resolution=64, cache=False)


def settle(shape, position, radius, *, velocity=(0.0, 0.0, 0.0), gravity=(0.0, -9.81, 0.0), frames=90,
           material=STILL):
    """One ball of `radius` released at `position` with `velocity` against `shape` of
    `material` (default restitution 0, friction 0.5), default impulse solver; its position
    after `frames`."""
    scene = tc.Scene(gravity=gravity)
    scene.add_collider(shape, material=material)
    scene.add_particles(positions=[position], velocities=[velocity], radius=radius)
    scene.step(frames)
    return scene.positions()[0]


# ---------------------------------------------------------------------------- resting heights

@pytest.mark.parametrize("radius", [0.05, 0.15, 0.4])
def test_large_ball_on_a_terrain_with_a_steep_step_rests_on_the_low_floor(radius):
    """x = 0.5 lies on the low half, 0.45 m from the ramp's foot: the ball (up to 0.4 m)
    rests on the floor at y = radius. It used to stop where |dv| / sqrt(1 + 20^2) reached
    the radius (y = 3.0 for 0.15)."""
    x = settle(step_field(), (0.5, 1.5, 1.0), radius)
    assert x[1] == pytest.approx(radius, abs=REST_TOL)
    assert x[0] == pytest.approx(0.5, abs=REST_TOL)


def test_ball_on_the_plateau_rests_at_its_height():
    x = settle(step_field(), (1.3, 2.5, 1.0), 0.15)
    assert x[1] == pytest.approx(1.15, abs=REST_TOL)


def test_ball_sliding_into_the_steep_step_stops_against_its_wall():
    """Sliding on the floor without friction into the ramp (slope 20), from 3 cm short of
    it: it stops on the floor touching the ramp, its centre 0.15 m from the ramp's line
    20 (x - 0.95) = y (it used to stop at its start, 3 cm away)."""
    r = 0.15
    touching = STEP_FOOT - (r * np.sqrt(1.0 + 20.0 ** 2) - r) / 20.0  # 0.807 m
    x = settle(step_field(), (touching - 0.03, r, 1.0), r, velocity=(APPROACH, 0.0, 0.0), frames=60,
               material=SLIDING)
    assert x[1] == pytest.approx(r, abs=REST_TOL)
    assert x[0] == pytest.approx(touching, abs=REST_TOL)


@pytest.mark.parametrize("radius", [0.05, 0.2, 0.5])
def test_large_ball_on_a_fine_triangle_mesh_rests_on_its_top(radius):
    """Cells of 1 cm under balls of 5 to 50 cm: the ball rests on the cube's top face at
    0.5 + radius (0.2 used to stop at 1.067)."""
    x = settle(cube_triangles(), (0.0, 1.5, 0.0), radius)
    assert x[1] == pytest.approx(0.5 + radius, abs=REST_TOL)


@pytest.mark.parametrize("radius", [0.2, 0.5])
def test_large_ball_on_a_mesh_grid_rests_on_its_top_beyond_the_padding(radius):
    """The ball's centre rests outside the grid's box (padding 7 cm): at 0.5 + radius (0.2
    used to stop at 0.759)."""
    x = settle(cube_grid(), (0.0, 1.5, 0.0), radius)
    assert x[1] == pytest.approx(0.5 + radius, abs=REST_TOL)


@pytest.mark.parametrize("shape", ["triangles", "grid"])
def test_large_ball_moving_into_the_side_of_a_cube_stops_touching_it(shape):
    """No gravity: a ball of radius 0.3 moving toward the cube's +x face from 5 cm away
    stops with its centre 0.3 m from the face, at x = 0.8 (it used to stop at its start)."""
    cube = cube_triangles() if shape == "triangles" else cube_grid()
    x = settle(cube, (0.85, 0.1, -0.2), 0.3, velocity=(-APPROACH, 0.0, 0.0), gravity=(0.0, 0.0, 0.0), frames=60)
    assert x[0] == pytest.approx(0.8, abs=REST_TOL)
    assert x[1:] == pytest.approx([0.1, -0.2], abs=REST_TOL)


def test_large_ball_on_a_sampled_function_rests_on_it_beyond_its_bounds():
    """A numpy function (the cube's distance) sampled over bounds 10 cm wider than the
    cube: the ball rests at 0.5 + radius, its centre outside the bounds (it used to stop
    where sqrt(d_box^2 + 0.1^2) reached the radius, at 0.883)."""
    cube = tc.Implicit(box_distance, bounds=((-0.6, -0.6, -0.6), (0.6, 0.6, 0.6)), resolution=16)
    x = settle(cube, (0.1, 1.5, -0.1), 0.3)
    assert x[1] == pytest.approx(0.8, abs=REST_TOL)


@ti.func
def squared_ball(p: ti.math.vec3):
    """|p|^2 - 1: zero on the unit sphere, |grad| = 2 there, not a distance."""
    return p.dot(p) - 1.0


@pytest.mark.parametrize("radius", [0.05, 0.2])
def test_ball_on_a_taichi_function_with_a_loose_bound_rests_on_its_surface(radius):
    """lipschitz=4 bounds |grad f| over |p| <= 2, twice its value at the surface: f / 4 is half
    the distance there, and a ball used to rest where that bound reached its radius
    (|p| = sqrt(1 + 4 r): 1.095 for r = 0.05, 1.342 for 0.2). Within reach, f / |grad f|."""
    ball = tc.Implicit(squared_ball, lipschitz=4.0, bounds=((-2, -2, -2), (2, 2, 2)))
    x = settle(ball, (0.0, 1.6, 0.0), radius, frames=60)
    # f / |grad f| = (|p|^2 - 1) / (2 |p|) equals r at |p| = r + sqrt(1 + r^2): off the true
    # 1 + r by 1e-3 (r = 0.05) and 2e-2 (0.2), the curvature's second-order term
    assert np.linalg.norm(x) == pytest.approx(radius + np.sqrt(1.0 + radius ** 2), abs=REST_TOL)
    hit, t, _ = ball.crossing(np.array([[0.0, 1.9, 0.0]]), np.array([[0.0, -1.9, 0.0]]), radius=radius)
    assert hit[0] and 1.9 - 3.8 * t[0] == pytest.approx(radius + np.sqrt(1.0 + radius ** 2), abs=1e-4)


# ---------------------------------------------------------------------------- queries

def test_step_signed_distance_is_exact_at_every_range(rng):
    """Points from the surface up to 2 m away (the ball sizes above, and many cells past
    the window the search starts with), over the footprint and beyond it."""
    field = step_field()
    p = np.column_stack([rng.uniform(-1.0, 3.0, 3000), rng.uniform(-1.0, 3.0, 3000), rng.uniform(-1.0, 3.0, 3000)])
    assert np.max(np.abs(field.signed_distance(p) - step_distance(p))) < PHI_TOL


@pytest.mark.parametrize("shape", ["triangles", "grid"])
def test_cube_signed_distance_holds_beyond_the_cells_and_the_padding(shape, rng):
    """From the surface to 1.5 m out (150 cells of the triangle mesh, 20 times the grid's
    padding): the triangle mesh gives the exact distance to the cube; the grid, outside its
    box as inside it, the distance to its own accuracy, a fraction of a cell
    (docs/design-notes.md, baking). Outside, the box's own bound sqrt(d_box^2 + phi_c^2)
    fell short by more than 0.1 m."""
    cube = cube_triangles() if shape == "triangles" else cube_grid()
    p = rng.uniform(-2.0, 2.0, (3000, 3))
    phi, want = cube.signed_distance(p), box_distance(p)
    if shape == "triangles":
        assert np.max(np.abs(phi - want)) < PHI_TOL
    else:
        beyond = np.any(np.abs(p) > np.abs(cube.origin), axis=1)  # outside the grid's box
        assert beyond.mean() > 0.5
        assert np.max(np.abs(phi[beyond] - want[beyond])) < 0.2 * cube.voxel_size
        assert np.max(np.abs(phi[~beyond] - want[~beyond])) < 0.5 * cube.voxel_size


def test_sampled_function_distance_beyond_its_bounds_is_the_distance_to_the_grid_accuracy(rng):
    """A ball of radius 0.5 sampled over bounds that touch it: outside the bounds, the
    distance carried out of the box matches |p| - 0.5 to a fraction of a cell, where the
    box's own bound (sqrt(d_box^2 + phi_c^2)) fell short by up to 0.3 m."""
    ball = tc.Implicit(lambda x: np.linalg.norm(x, axis=1) - 0.5, bounds=((-0.5, -0.5, -0.5), (0.5, 0.5, 0.5)),
                       resolution=48)
    p = rng.uniform(-1.2, 1.2, (2000, 3))
    beyond = np.any(np.abs(p) > 0.5, axis=1)
    err = ball.signed_distance(p[beyond]) - (np.linalg.norm(p[beyond], axis=1) - 0.5)
    assert np.max(np.abs(err)) < 0.2 * ball.voxel_size


_KERNELS = {}


def phi_within(collider, points, reach):
    """phi from the collider kind's own query with a `reach` (the distance within which the
    caller needs it exact: a particle's radius), at world points, the collider at rest
    without rotation (its local frame is the world's, shifted by its centre)."""
    import taichi as ti

    from tai_coll.geometry import grid_sdf, kinds, mesh_grid, queries, terrain
    from tai_coll.types import ShapeArgs

    if not _KERNELS:
        @ti.kernel
        def within(shape: ShapeArgs, kind: ti.template(), points: ti.types.ndarray(), reach: float,
                   # outputs
                   phi: ti.types.ndarray()):
            for i in range(points.shape[0]):
                p = ti.math.vec3(points[i, 0], points[i, 1], points[i, 2])
                d = 0.0
                if ti.static(kind == kinds.HEIGHT_FIELD):
                    d, _ = terrain.field_sdf(shape, 0, p, reach)
                elif ti.static(kind == kinds.TRIANGLE_MESH):
                    d, _ = mesh_grid.mesh_sdf(shape, 0, p, reach)
                else:
                    d, _ = grid_sdf.grid_sdf(shape, 0, p, reach)
                phi[i] = d

        _KERNELS["within"] = within
    assert np.allclose(collider.rotation, np.eye(3))
    local = np.ascontiguousarray(points - collider.center)
    phi = np.zeros(len(points))
    _KERNELS["within"](queries._shape_args(collider), collider.kind, local, reach, phi)
    return phi


@pytest.mark.parametrize("shape", ["step", "triangles", "grid"])
def test_a_query_with_a_reach_is_exact_within_it_and_a_bound_past_it(shape, rng):
    """The callers may say how far they need phi exact (a particle's radius): within that
    reach the query answers as it does without one, past it with a lower bound on the
    distance that is no less than the reach, so `phi < r` comes out right for every r up to
    the reach, and the search past it is skipped. Deep inside a closed mesh the distance
    stays exact (a particle found there needs its way out)."""
    reach = 0.2
    collider = step_field() if shape == "step" else cube_triangles() if shape == "triangles" else cube_grid()
    p = rng.uniform(-1.0, 2.0, (3000, 3)) if shape == "step" else rng.uniform(-1.0, 1.0, (3000, 3))
    exact = collider.signed_distance(p)
    phi = phi_within(collider, p, reach)
    near = np.abs(exact) < reach
    assert 0.1 < near.mean() < 0.9
    assert np.max(np.abs(phi[near] - exact[near])) < PHI_TOL
    assert np.all(np.sign(phi) == np.sign(exact))
    assert np.all(np.abs(phi[~near]) >= reach - PHI_TOL)
    assert np.all(np.abs(phi[~near]) <= np.abs(exact[~near]) + PHI_TOL)
    if shape == "triangles":
        deep = exact < -reach
        assert deep.any() and np.max(np.abs(phi[deep] - exact[deep])) < PHI_TOL


@pytest.mark.parametrize("shape", ["step", "triangles", "grid"])
def test_crossing_of_a_large_ball_meets_the_surface_where_it_touches(shape):
    """A ball of radius 0.2 falling from 1.5 m, and one passing 5 cm clear over the top:
    the first touches at the closed-form fraction, the second does not touch at all (a
    lower bound used to report contact at its start)."""
    r = 0.2
    collider = step_field() if shape == "step" else cube_triangles() if shape == "triangles" else cube_grid()
    top, x, z = (0.0, 0.4, 1.0) if shape == "step" else (0.5, 0.0, 0.0)  # the step's floor, 0.55 m from the ramp
    starts = np.array([[x, 1.5, z], [x - 0.3, top + r + 0.05, z]])
    ends = np.array([[x, top - 0.3, z], [x + 0.3, top + r + 0.05, z]])
    hit, t, n = collider.crossing(starts, ends, radius=r)
    assert hit.tolist() == [True, False]
    assert t[0] == pytest.approx((1.5 - top - r) / (1.5 - top + 0.3), abs=1e-4)
    assert n[0] == pytest.approx([0.0, 1.0, 0.0], abs=1e-6)
