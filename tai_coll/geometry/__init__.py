"""Geometry queries (docs/physics.md 1): signed distance, normal, trajectory crossing."""

from .colliders import Box, Capsule, Collider, Cylinder, Plane, Sphere
from .frames import rotation_matrix
from .height_field import HeightField
from .triangle_mesh import TriangleMesh

__all__ = ["Box", "Capsule", "Collider", "Cylinder", "HeightField", "Plane", "Sphere", "TriangleMesh",
           "rotation_matrix"]
