"""Rigid bodies (docs/physics.md 7): closed collider shapes with mass that particles push and
that push back, fall under gravity and collide with colliders and each other."""

from .body import Body
from .mass_properties import MassProperties, mass_properties

__all__ = ["Body", "MassProperties", "mass_properties"]
