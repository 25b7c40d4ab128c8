"""Surface samples of a rigid body's shape: the points whose contacts the rigid-body solver
finds (bodies/rigid.py; docs/physics.md 7.4).

A body touches another collider where one of its samples does: a sample is a ball (a point
with a radius) that lies on the body's surface, and its contact with the other collider is
that collider's own signed distance at the sample minus the sample's radius (docs/physics.md
1.1). Curved shapes that are sphere-swept need few samples and are then exact: a sphere is
its centre with its radius, a capsule points along its axis with its radius. Flat and
polyhedral shapes have samples of radius 0 on their surface: the corners, points along the
edges and grids on the faces, so that a face resting on a face or a box edge across another
body's face has a sample near every point of contact.

Everything is in the shape's local frame (the one its signed distance is written in: the
analytic shapes centred on the origin, cylinder and capsule along y, a mesh's origin the
centre of its bounding box). Deterministic: the same shape always gives the same samples, in
the same order. Host side only (numpy, and trimesh's area-weighted sampling for meshes).
"""

from __future__ import annotations

import math
import weakref

import numpy as np

from ..geometry.colliders import Box, Capsule, Collider, Cylinder, Sphere
from ..geometry.mesh_sdf import MeshSDF
from ..geometry.triangle_mesh import TriangleMesh

#: At most this many samples per body: the contact solve runs every substep over every
#: sample near another collider, so a body's cost is bounded whatever its shape.
MAX_SAMPLES = 400
#: The target spacing of samples on flat faces and edges, as a fraction of the body's smallest
#: extent (a side of a box, a cylinder's diameter or length); coarser when MAX_SAMPLES needs it.
SPACING_FRACTION = 0.25
#: A capsule's axis points are at most this fraction of its radius apart: the swept balls'
#: envelope then dips at most r (1 - sqrt(1 - 1/16)), 3 % of r, between two of them.
CAPSULE_SPACING = 0.5
#: The seed of the area-weighted face samples of meshes.
MESH_SEED = 0

ACCEPTED = "Sphere, Box, Cylinder, Capsule, a closed TriangleMesh or a MeshSDF"

_cache: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()  # shape -> (points, radii), read-only


def surface_samples(shape, max_samples: int = MAX_SAMPLES):
    """(points (S, 3), radii (S,)) of a body shape, in its local frame (float64, read-only
    arrays). A sample's ball touches the surface from inside: its centre lies a radius
    below the surface, phi(point) = -radius (docs/physics.md 1.1). At most max_samples.
    Computed once per shape and max_samples, then cached."""
    if not isinstance(shape, Collider):
        raise TypeError(f"shape must be a tai_coll collider ({ACCEPTED}); got {type(shape).__name__}")
    if isinstance(max_samples, bool) or not isinstance(max_samples, int) or max_samples < 8:
        raise ValueError(f"max_samples must be an integer >= 8; got {max_samples!r}")
    cached = _cache.get(shape)
    if cached is not None and max_samples in cached:
        return cached[max_samples]
    points, radii = _samples(shape, max_samples)
    points = np.ascontiguousarray(points, dtype=np.float64) + 0.0  # (+ 0.0: no negative zeros)
    radii = np.ascontiguousarray(radii, dtype=np.float64)
    points.flags.writeable = False
    radii.flags.writeable = False
    _cache.setdefault(shape, {})[max_samples] = (points, radii)
    return points, radii


def _samples(shape, cap):
    if isinstance(shape, Sphere):
        return np.zeros((1, 3)), np.array([shape.radius])  # the ball itself: exact contacts
    if isinstance(shape, Capsule):
        return _capsule(shape.radius, shape.half_height, cap)
    if isinstance(shape, Box):
        points = _box(shape.half_extents, cap)
        return points, np.zeros(len(points))
    if isinstance(shape, Cylinder):
        points = _cylinder(shape.radius, shape.half_height, cap)
        return points, np.zeros(len(points))
    if isinstance(shape, TriangleMesh):
        points = _mesh(shape.vertices, shape.faces, cap)
        return points, np.zeros(len(points))
    if isinstance(shape, MeshSDF):
        vertices = np.asarray(shape.mesh.vertices, dtype=np.float64) - shape.mesh_center  # its local frame
        points = _mesh(vertices, np.asarray(shape.mesh.faces, dtype=np.int64), cap)
        return points, np.zeros(len(points))
    raise ValueError(f"shape: a {type(shape).__name__} cannot be a body; a body needs {ACCEPTED}")


def _capsule(r, h, cap):
    """Points on the axis segment (0, -h, 0) -> (0, h, 0), ends included, each with the
    capsule's radius: CAPSULE_SPACING r apart (farther only past `cap` points)."""
    count = min(max(2, math.ceil(2.0 * h / (CAPSULE_SPACING * r)) + 1), cap)
    points = np.zeros((count, 3))
    points[:, 1] = np.linspace(-h, h, count)
    return points, np.full(count, r)


def _box(half, cap):
    """The nodes of a lattice over the box that lie on its surface: the 8 corners, points
    along the 12 edges and grids on the 6 faces. Spacing SPACING_FRACTION of the smallest
    side, widened by 10 % steps until the count is at most `cap`."""
    sides = 2.0 * np.asarray(half, dtype=np.float64)
    spacing = SPACING_FRACTION * float(sides.min())
    while True:
        cells = np.maximum(1, np.ceil(sides / spacing - 1e-9)).astype(int)  # intervals per axis
        inner = np.maximum(cells - 1, 0)
        if int(np.prod(cells + 1) - np.prod(inner)) <= cap:
            break
        spacing *= 1.1
    axes = [np.linspace(-h, h, n + 1) for h, n in zip(half, cells)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    index = np.stack(np.meshgrid(*[np.arange(n + 1) for n in cells], indexing="ij"), axis=-1).reshape(-1, 3)
    on_surface = np.any((index == 0) | (index == cells), axis=1)
    return grid[on_surface]


def _cylinder(r, h, cap):
    """The two rims, lines along the side at the rims' angles, and a square grid on each cap
    (its points inside the rim by at least half a spacing). Spacing SPACING_FRACTION of the
    smaller of diameter and length, widened by 10 % steps until the count is at most `cap`."""
    spacing = SPACING_FRACTION * min(2.0 * r, 2.0 * h)
    while True:
        around = max(8, math.ceil(2.0 * math.pi * r / spacing))
        along = max(1, math.ceil(2.0 * h / spacing))  # intervals along the axis
        ticks = np.arange(-r, r + 1e-12 * r, spacing)
        ticks = ticks - 0.5 * (ticks[0] + ticks[-1])  # centred on the axis
        u, w = np.meshgrid(ticks, ticks, indexing="ij")
        disc = np.hypot(u, w) <= r - 0.5 * spacing
        count = around * (along + 1) + 2 * int(disc.sum())
        if count <= cap:
            break
        spacing *= 1.1
    angle = 2.0 * np.pi * np.arange(around) / around
    ring = np.stack([r * np.cos(angle), np.zeros(around), r * np.sin(angle)], axis=1)
    side = [ring + np.array([0.0, y, 0.0]) for y in np.linspace(-h, h, along + 1)]  # rims first and last
    caps = [np.stack([u[disc], np.full(int(disc.sum()), y), w[disc]], axis=1) for y in (-h, h)]
    return np.concatenate(side + caps)


def _mesh(vertices, faces, cap):
    """The vertices (evenly strided down to half of `cap` when there are more) and
    area-weighted samples on the triangles (trimesh, seed MESH_SEED): one per square of side
    SPACING_FRACTION of the smallest bounding-box side, at most the rest of `cap`."""
    import trimesh

    vertices = np.asarray(vertices, dtype=np.float64)
    used = np.unique(np.asarray(faces).ravel())
    corners = vertices[used]
    if len(corners) > cap // 2:
        corners = corners[np.linspace(0, len(corners) - 1, cap // 2).round().astype(int)]
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False, validate=False)
    extent = np.ptp(corners if len(used) <= cap // 2 else vertices[used], axis=0)
    smallest = float(extent.min()) if extent.min() > 0 else float(extent.max())
    spacing = SPACING_FRACTION * smallest
    wanted = math.ceil(float(mesh.area) / (spacing * spacing)) if spacing > 0 else 0
    count = min(wanted, cap - len(corners))
    if count <= 0:
        return corners
    on_faces, _ = trimesh.sample.sample_surface(mesh, count, seed=MESH_SEED)
    return np.concatenate([corners, np.asarray(on_faces, dtype=np.float64)])
