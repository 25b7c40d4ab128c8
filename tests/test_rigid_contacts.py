"""Rigid bodies against colliders and each other (tai_coll/bodies/rigid.py, samples.py;
docs/physics.md 2): surface samples on their shapes, and closed-form dynamics run by a
test-local stepping loop (contacts, then the pose integrated with store.advanced_pose and put
back in the collider table, as the scene does each substep)."""

import numpy as np
import pytest
import trimesh

import tai_coll as tc
from tai_coll.bodies import mass_properties
from tai_coll.bodies.rigid import MARGIN, combined_material, resolve_contacts
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

    def __init__(self, gravity=(0.0, -G, 0.0), dt=DT):
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
        self.contacts.append(resolve_contacts(store, self.table, self.gravity, self.dt))
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
