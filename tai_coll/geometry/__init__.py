"""Geometry queries (PHYSICS.md 1): signed distance, normal, trajectory crossing."""

from .colliders import Box, Capsule, Collider, Cylinder, Plane, Sphere
from .frames import rotation_matrix

__all__ = ["Box", "Capsule", "Collider", "Cylinder", "Plane", "Sphere", "rotation_matrix"]
