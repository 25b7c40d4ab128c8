"""Response laws (docs/physics.md 2): what a collision does to velocities."""

from .collide import collide, collide_pair

__all__ = ["collide", "collide_pair"]
