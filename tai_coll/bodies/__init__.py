"""Rigid bodies (docs/physics.md 2): closed collider shapes that move under contact forces.
So far their mass properties, computed on the host."""

from .mass_properties import MassProperties, mass_properties

__all__ = ["MassProperties", "mass_properties"]
