"""Rigid bodies against colliders and each other (tai_coll/bodies/rigid.py, samples.py;
docs/physics.md 2): surface samples on their shapes, and closed-form dynamics run by a
test-local stepping loop (contacts, then the pose integrated with store.advanced_pose and put
back in the collider table, as the scene does each substep)."""

import numpy as np
import pytest
import trimesh

import tai_coll as tc
from tai_coll.bodies import mass_properties
from tai_coll.bodies.rigid import ContactCache, combined_material, resolve_contacts
from tai_coll.bodies.samples import MAX_SAMPLES, surface_samples
from tai_coll.bodies.store import BodyStore
from tai_coll.geometry.frames import rotation_matrix
from tai_coll.scene.colliders import ColliderTable
from tai_coll.scene.motion import ConstantMotion

G = 9.81
DT = 1 / 600


class Rig:
    """Bodies and colliders in a collider table, stepped substep by substep: each body's
    entry at its pose, kinematic colliders advanced, resolve_contacts, the pose integrated."""

    def __init__(self, gravity=(0.0, -G, 0.0), dt=DT, warm=True):
        self.cache = ContactCache() if warm else None
        self.gravity = np.asarray(gravity, dtype=np.float64)
        self.dt = dt
        self.time = 0.0
        self.table = ColliderTable()
        self.store = BodyStore()
        self.contacts = []

    def collider(self, shape, material=None, velocity=None):
        motion = None if velocity is None else ConstantMotion(velocity, None)
        return self.table.add(shape, material or tc.Material(), motion, 0.0)

    def body(self, shape, material=None, mass=1.0, velocity=(0.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 0.0)):
        material = material or tc.Material()
        entry = self.table.add(shape, material, None, 0.0)
        props = mass_properties(shape, mass=mass)
        return self.store.add(entry, material, props, shape.rotation, velocity, angular_velocity)

    def substep(self):
        store = self.store
        for b in range(store.count):
            entry = store.entries[b]
            entry.center, entry.rotation = store.shape_pose(b)
            entry.velocity, entry.angular_velocity = store.v[b].copy(), store.omega(b)
        self.table.advance(self.time, self.dt)
        self.contacts.append(resolve_contacts(store, self.table, self.gravity, self.dt, self.cache))
        for b in range(store.count):
            store.x[b], store.R[b] = store.advanced_pose(b, self.dt)
        self.time += self.dt

    def run(self, seconds, record=None):
        """Step for `seconds`; record(rig) after every substep, its results returned as a list."""
        out = []
        for _ in range(int(round(seconds / self.dt))):
            self.substep()
            if record is not None:
                out.append(record(self))
        return out

    def corners(self, b):
        """World corners of a Box body."""
        center, rotation = self.store.shape_pose(b)
        half = self.store.entries[b].shape.half_extents
        signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)
        return (signs * half) @ rotation.T + center


def speed_of(rig, b):
    """(|v|, |w|) of body b."""
    return float(np.linalg.norm(rig.store.v[b])), float(np.linalg.norm(rig.store.omega(b)))


# ---------------------------------------------------------------- samples
def body_shapes():
    box_mesh = trimesh.creation.box(extents=(0.3, 0.2, 0.4))
    return {
        "sphere": tc.Sphere(center=(0.1, 0.2, 0.3), radius=0.25),
        "box": tc.Box(center=(0.0, 1.0, 0.0), half_extents=(0.1, 0.2, 0.3), rotation=rotation_matrix((1, 2, 3), 0.7)),
        "plank": tc.Box(half_extents=(0.5, 0.01, 0.1)),
        "cylinder": tc.Cylinder(center=(0.2, 0.0, 0.0), radius=0.2, half_height=0.5, axis=(1, 1, 0)),
        "capsule": tc.Capsule(radius=0.1, half_height=0.4, axis=(0, 0, 1)),
        "triangle_mesh": tc.TriangleMesh(trimesh.creation.icosphere(subdivisions=2, radius=0.3), center=(0, 1, 0)),
        "mesh_sdf": tc.MeshSDF(box_mesh, resolution=48, cache=False),
    }


@pytest.mark.parametrize("name", list(body_shapes()))
def test_samples_lie_on_the_surface_of_every_body_shape(name):
    shape = body_shapes()[name]
    points, radii = surface_samples(shape)
    assert 1 <= len(points) <= MAX_SAMPLES and points.shape == (len(radii), 3)
    world = points @ shape.rotation.T + shape.center
    phi = shape.signed_distance(world)
    # a sample's ball touches the surface from inside: phi = -radius (a baked grid: to its voxel)
    tolerance = 1.5 * shape.voxel_size if name == "mesh_sdf" else 1e-9
    assert np.abs(phi + radii).max() < tolerance
    again = surface_samples(body_shapes()[name])  # a new, equal shape: the same samples
    assert np.array_equal(again[0], points) and np.array_equal(again[1], radii)


def test_samples_cover_a_box_corners_edges_and_faces():
    points, radii = surface_samples(tc.Box(half_extents=(0.1, 0.1, 0.1)))
    assert np.all(radii == 0)
    corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)]) * 0.1
    assert all(np.any(np.all(np.isclose(points, c), axis=1)) for c in corners)
    top = points[np.isclose(points[:, 1], 0.1)]
    assert len(top) >= 9 and np.ptp(top[:, 0]) == pytest.approx(0.2)  # a grid on the face
    capsule_points, capsule_radii = surface_samples(tc.Capsule(radius=0.1, half_height=0.5))
    assert np.all(capsule_radii == 0.1) and np.diff(capsule_points[:, 1]).max() <= 0.1
    assert capsule_points[0, 1] == -0.5 and capsule_points[-1, 1] == 0.5


def test_samples_refuse_shapes_that_cannot_be_bodies():
    with pytest.raises(ValueError, match="cannot be a body"):
        surface_samples(tc.Plane())
    with pytest.raises(TypeError, match="collider"):
        surface_samples("box")


def test_materials_combine_by_the_larger_restitution_and_the_geometric_mean_friction():
    e, mu = combined_material(tc.Material(restitution=0.8, friction=0.4), tc.Material(restitution=0.1, friction=0.9))
    assert e == 0.8 and mu == pytest.approx(0.6)
    assert combined_material(tc.Material(friction=0.0), tc.Material(friction=1.0))[1] == 0.0


# ---------------------------------------------------------------- one body on static colliders
def test_a_sphere_dropped_on_a_plane_bounces_to_e_squared_h():
    rig = Rig()
    rig.collider(tc.Plane(), tc.Material(restitution=0.0))
    rig.body(tc.Sphere(center=(0.0, 1.0, 0.0), radius=0.1), tc.Material(restitution=0.8))  # e = max(0.8, 0)
    heights = np.array(rig.run(1.2, lambda r: r.store.x[0, 1])) - 0.1
    bounce = int(np.argmin(heights))
    assert heights[bounce] > -1e-9  # it never entered the floor
    assert heights[bounce:].max() == pytest.approx(0.8 ** 2 * 0.9, rel=0.02)


def on_incline(friction):
    theta = np.radians(20.0)
    normal = np.array([-np.sin(theta), np.cos(theta), 0.0])
    downhill = -np.array([np.cos(theta), np.sin(theta), 0.0])
    rig = Rig()
    rig.collider(tc.Plane(normal=normal), tc.Material(friction=friction))
    rig.body(tc.Sphere(center=0.1 * normal, radius=0.1), tc.Material(friction=friction))
    rig.run(1.0)
    return rig, theta, normal, downhill


def test_a_ball_rolls_down_an_incline_at_five_sevenths_g_sin_theta():
    rig, theta, normal, downhill = on_incline(friction=1.0)
    v, w = rig.store.v[0], rig.store.omega(0)
    assert v @ downhill / rig.time == pytest.approx(5 / 7 * G * np.sin(theta), rel=0.04)
    assert np.linalg.norm(w) * 0.1 == pytest.approx(np.linalg.norm(v), rel=0.04)  # rolling: |w| r = |v|
    assert abs(rig.store.x[0] @ normal - 0.1) < 1e-6  # on the plane, neither sunk nor hopping


def test_a_ball_on_a_frictionless_incline_slides_at_g_sin_theta_without_spin():
    rig, theta, normal, downhill = on_incline(friction=0.0)
    v = rig.store.v[0]
    assert v @ downhill / rig.time == pytest.approx(G * np.sin(theta), rel=0.04)
    assert np.linalg.norm(rig.store.omega(0)) * 0.1 < 1e-3 * np.linalg.norm(v)


def test_a_tilted_box_dropped_on_the_floor_rests_flat_without_sinking_or_jitter():
    rig = Rig()
    rig.collider(tc.Plane(), tc.Material(friction=0.5))
    tilt = rotation_matrix((1, 0, 0), np.radians(25.0)) @ rotation_matrix((0, 0, 1), np.radians(25.0))
    rig.body(tc.Box(half_extents=(0.1, 0.05, 0.075), rotation=tilt), tc.Material(restitution=0.3, friction=0.5))
    rig.store.x[0, 1] += 0.3 - rig.corners(0)[:, 1].min()  # lowest corner 0.3 m up
    trace = np.array(rig.run(3.0, lambda r: (r.corners(0)[:, 1].min(), *speed_of(r, 0))))
    assert trace[:, 0].min() > -2e-3  # sank less than 2 mm at any time
    assert trace[-300:, 1].max() < 1e-3 and trace[-300:, 2].max() * 0.1 < 1e-3  # still for the last 0.5 s
    up = rig.store.R[0].T @ np.array([0.0, 1.0, 0.0])  # the world's up in the box frame
    assert np.abs(up).max() == pytest.approx(1.0, abs=1e-4)  # flat on a face
    assert abs(rig.corners(0)[:, 1].min()) < 1e-4


@pytest.mark.parametrize("name", ["sphere", "box", "cylinder", "capsule", "triangle_mesh", "mesh_sdf"])
def test_every_body_shape_comes_to_rest_on_the_floor(name):
    shape = body_shapes()[name]
    shape.center = np.array([0.0, 0.6, 0.0])
    rig = Rig()
    rig.collider(tc.Plane(), tc.Material(friction=0.6))
    rig.body(shape, tc.Material(restitution=0.2, friction=0.6), angular_velocity=(1.0, 0.0, 2.0))
    rig.run(3.0)
    center, rotation = rig.store.shape_pose(0)
    points, radii = surface_samples(shape)
    lowest = float(np.min((points @ rotation.T + center)[:, 1] - radii))
    tolerance = shape.voxel_size if name == "mesh_sdf" else 2e-3
    assert abs(lowest) < tolerance  # on the floor, not in it
    if name in ("box", "cylinder", "mesh_sdf"):  # (the balls, the icosphere too, may still roll)
        assert max(speed_of(rig, 0)) < 1e-2


def test_a_plank_leaning_on_a_wall_holds_with_friction_and_slides_down_without():
    lean = rotation_matrix((0, 0, 1), -np.radians(20.0))  # top toward the wall at x = 0.3
    for friction, holds in ((0.5, True), (0.0, False)):
        rig = Rig()
        material = tc.Material(friction=friction)
        rig.collider(tc.Plane(), material)
        rig.collider(tc.Plane(point=(0.3, 0.0, 0.0), normal=(-1.0, 0.0, 0.0)), material)
        rig.body(tc.Box(half_extents=(0.02, 0.5, 0.1), rotation=lean), material)
        corners = rig.corners(0)
        rig.store.x[0] += (0.3 - corners[:, 0].max(), -corners[:, 1].min(), 0.0)
        start = rig.store.x[0].copy()
        rig.run(2.0)
        if holds:
            assert np.abs(rig.store.x[0] - start).max() < 1e-4 and max(speed_of(rig, 0)) < 1e-3
        else:  # a ladder on frictionless floor and wall falls flat
            assert rig.store.x[0, 1] == pytest.approx(0.02, abs=2e-3)
        assert rig.corners(0)[:, 0].max() < 0.3 + 1e-3 and rig.corners(0)[:, 1].min() > -1e-3


def test_a_box_thrown_at_30_m_s_does_not_pass_a_2_cm_wall():
    spin = rotation_matrix((1, 1, 0), 0.5)
    for restitution, rotation, w in ((0.0, None, (0, 0, 0)), (0.5, spin, (3.0, 5.0, 7.0))):
        rig = Rig(gravity=(0.0, 0.0, 0.0))
        rig.collider(tc.Box(center=(0.5, 0.0, 0.0), half_extents=(0.01, 0.5, 0.5)), tc.Material(restitution=restitution))
        rig.body(tc.Box(half_extents=(0.05, 0.05, 0.05), rotation=rotation), tc.Material(restitution=restitution),
                 velocity=(30.0, 0.0, 0.0), angular_velocity=w)
        front = np.array(rig.run(0.1, lambda r: r.corners(0)[:, 0].max()))  # 5 cm a substep
        assert front.max() < 0.49 + 1e-6  # the wall's face
        assert rig.store.v[0, 0] == pytest.approx(-30.0 * restitution, abs=0.5)


# ---------------------------------------------------------------- bodies against bodies
def test_two_equal_elastic_spheres_head_on_swap_velocities():
    rig = Rig(gravity=(0.0, 0.0, 0.0))
    elastic = tc.Material(restitution=1.0)
    rig.body(tc.Sphere(center=(-0.5, 0.0, 0.0), radius=0.1), elastic, velocity=(2.0, 0.0, 0.0))
    rig.body(tc.Sphere(center=(0.5, 0.01, 0.0), radius=0.1), elastic, mass=1.0, velocity=(-1.0, 0.0, 0.0))
    rig.run(0.5)
    assert rig.store.v[0, 0] == pytest.approx(-1.0, rel=0.02) and rig.store.v[1, 0] == pytest.approx(2.0, rel=0.02)
    assert np.allclose(rig.store.v.sum(axis=0), (1.0, 0.0, 0.0), atol=1e-12)  # momentum conserved
    assert sum(rig.store.kinetic_energy(b) for b in range(2)) == pytest.approx(2.5, rel=0.02)


def test_a_box_stacked_on_a_box_on_the_floor_stays():
    rig = Rig()
    material = tc.Material(restitution=0.2, friction=0.6)
    rig.collider(tc.Plane(), material)
    rig.body(tc.Box(center=(0.0, 0.1, 0.0), half_extents=(0.1, 0.1, 0.1)), material)
    rig.body(tc.Box(center=(0.03, 0.3, 0.01), half_extents=(0.1, 0.1, 0.1)), material)
    start = rig.store.x.copy()
    trace = np.array(rig.run(2.0, lambda r: (*speed_of(r, 0), *speed_of(r, 1))))
    assert np.abs(rig.store.x - start).max() < 1e-3
    assert trace[-300:].max() < 1e-3


def test_a_stack_rests_without_warm_starting_too():
    rig = Rig(warm=False)
    material = tc.Material(restitution=0.2, friction=0.6)
    rig.collider(tc.Plane(), material)
    rig.body(tc.Box(center=(0.0, 0.1, 0.0), half_extents=(0.1, 0.1, 0.1)), material)
    rig.body(tc.Box(center=(0.03, 0.3, 0.01), half_extents=(0.1, 0.1, 0.1)), material)
    start = rig.store.x.copy()
    rig.run(1.0)
    assert np.abs(rig.store.x - start).max() < 2e-3


def test_a_huge_mass_barely_moves_when_a_sphere_hits_it():
    rig = Rig(gravity=(0.0, 0.0, 0.0))
    material = tc.Material(restitution=0.5)
    rig.body(tc.Box(center=(0.5, 0.0, 0.0), half_extents=(0.2, 0.2, 0.2)), material, mass=1e9)
    rig.body(tc.Sphere(center=(0.0, 0.05, 0.0), radius=0.1), material, velocity=(5.0, 0.0, 0.0))
    rig.run(0.3)
    assert np.linalg.norm(rig.store.v[0]) < 1e-8 and np.linalg.norm(rig.store.omega(0)) < 1e-7  # 7.5 N s on 1e9 kg
    assert rig.store.v[1, 0] == pytest.approx(-2.5, rel=0.02)
    assert np.allclose(rig.store.v[0] * 1e9 + rig.store.v[1], (5.0, 0.0, 0.0), atol=1e-6)


# ---------------------------------------------------------------- kinematic colliders
def test_a_box_on_a_moving_platform_is_carried_and_a_ball_rolls_at_two_sevenths():
    material = tc.Material(friction=0.5)
    for shape, expected in ((tc.Box(center=(0.0, 0.1, 0.0), half_extents=(0.1, 0.1, 0.1)), 0.5),
                            (tc.Sphere(center=(0.0, 0.1, 0.0), radius=0.1), 0.5 * 2 / 7)):
        rig = Rig()
        rig.collider(tc.Box(center=(0.0, -0.05, 0.0), half_extents=(3.0, 0.05, 1.0)), material, velocity=(0.5, 0, 0))
        rig.body(shape, material)
        rig.run(1.0)
        # a ball set down on a belt keeps its angular momentum about the contact line, zero:
        # it ends rolling at 2/7 of the belt's speed
        assert rig.store.v[0, 0] == pytest.approx(expected, rel=0.02)
        assert rig.store.x[0, 1] == pytest.approx(0.1, abs=1e-4)


def test_a_sphere_on_a_rising_plane_is_carried_up():
    rig = Rig()
    rig.collider(tc.Plane(), tc.Material(), velocity=(0.0, 0.3, 0.0))
    rig.body(tc.Sphere(center=(0.0, 0.1, 0.0), radius=0.1), tc.Material())
    rig.run(1.0)
    assert rig.store.x[0, 1] - 0.3 * rig.time == pytest.approx(0.1, abs=1e-4)
    assert rig.store.v[0, 1] == pytest.approx(0.3, rel=1e-3)


# ---------------------------------------------------------------- determinism, free flight
def tumbling_pile():
    rig = Rig()
    rig.collider(tc.Plane(), tc.Material(restitution=0.3, friction=0.5))
    rig.collider(tc.Box(center=(0.0, 0.0, 0.0), half_extents=(0.3, 0.1, 0.3)), tc.Material(friction=0.5),
                 velocity=(0.1, 0.0, 0.0))
    rig.body(tc.Box(center=(0.0, 0.4, 0.0), half_extents=(0.1, 0.05, 0.08), rotation=rotation_matrix((1, 2, 3), 0.4)),
             tc.Material(restitution=0.3, friction=0.5), angular_velocity=(2.0, 0.0, 1.0))
    rig.body(tc.Capsule(center=(0.05, 0.7, 0.0), radius=0.05, half_height=0.1, axis=(1, 0, 1)),
             tc.Material(friction=0.5), velocity=(0.0, -1.0, 0.0))
    rig.body(tc.Sphere(center=(-0.05, 0.9, 0.02), radius=0.07), tc.Material(restitution=0.6))
    rig.run(0.5)
    return rig


def test_the_same_scene_gives_bit_identical_bodies():
    first, second = tumbling_pile(), tumbling_pile()
    assert sum(first.contacts) > 0
    for name in ("x", "R", "v", "L"):
        assert np.array_equal(getattr(first.store, name), getattr(second.store, name)), name


def test_a_body_far_from_everything_only_falls():
    rig = Rig()
    rig.collider(tc.Plane(), tc.Material())
    rig.body(tc.Box(center=(0.0, 5.0, 0.0), half_extents=(0.1, 0.2, 0.3)), tc.Material(), angular_velocity=(1, 2, 3))
    L = rig.store.L[0].copy()
    rig.substep()
    assert rig.contacts == [0]
    assert np.array_equal(rig.store.L[0], L) and np.array_equal(rig.store.v[0], (0.0, -G * DT, 0.0))


def test_a_restored_contact_cache_reproduces_the_run_bit_for_bit():
    rig = tumbling_pile()
    poses = [(e.center.copy(), e.rotation.copy()) for e in rig.table.entries]  # the moving platform's
    saved = rig.store.state(), rig.cache.state(), rig.time
    first = rig.run(0.1, lambda r: r.store.state())[-1]
    state, cache, rig.time = saved
    for name, value in state.items():
        getattr(rig.store, name)[:] = value
    for entry, (center, rotation) in zip(rig.table.entries, poses):
        entry.center, entry.rotation = center, rotation
    rig.cache.restore(cache)
    second = rig.run(0.1, lambda r: r.store.state())[-1]
    for name in first:
        assert np.array_equal(first[name], second[name]), name


def test_bodies_spawned_into_each_other_come_apart_without_being_thrown():
    rig = Rig(gravity=(0.0, 0.0, 0.0))
    rig.body(tc.Box(center=(0.0, 0.0, 0.0), half_extents=(0.1, 0.1, 0.1)), tc.Material())
    rig.body(tc.Box(center=(0.18, 0.0, 0.0), half_extents=(0.1, 0.1, 0.1)), tc.Material())  # 2 cm deep
    rig.run(0.5)
    assert rig.store.x[1, 0] - rig.store.x[0, 0] > 0.2 - 2e-3  # apart, to the position correction's slop
    assert np.abs(rig.store.v).max() < 1e-6  # by positions: no velocity added


# ---------------------------------------------------------------- through the scene
def test_a_scene_body_bounces_to_e_squared_h_and_a_tilted_box_settles_flat():
    scene = tc.Scene(dt=DT, substeps=10)
    scene.add_collider(tc.Plane(), material=tc.Material(restitution=0.0, friction=0.5))
    ball = scene.add_body(tc.Sphere(center=(0.0, 1.0, 0.0), radius=0.1), mass=1.0,
                          material=tc.Material(restitution=0.8))
    tilt = rotation_matrix((1, 0, 0), np.radians(25.0)) @ rotation_matrix((0, 0, 1), np.radians(25.0))
    box = scene.add_body(tc.Box(center=(1.0, 0.45, 0.0), half_extents=(0.1, 0.05, 0.075), rotation=tilt), mass=2.0,
                         material=tc.Material(restitution=0.3, friction=0.5))
    heights = []
    for _ in range(54):  # 0.9 s: one bounce and its apex
        scene.step()
        heights.append(ball.position[1] - 0.1)
    bounce = int(np.argmin(heights))
    assert max(heights[bounce:]) == pytest.approx(0.8 ** 2 * 0.9, rel=0.02)
    scene.step(frames=150)
    up = box.rotation.T @ np.array([0.0, 1.0, 0.0])
    assert np.abs(up).max() == pytest.approx(1.0, abs=1e-4)
    assert np.linalg.norm(box.velocity) < 1e-3 and np.linalg.norm(box.angular_velocity) * 0.1 < 1e-3
    corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)]) * (0.1, 0.05, 0.075)
    lowest = (corners @ box.rotation.T + box.position)[:, 1].min()
    assert abs(lowest) < 2e-3
