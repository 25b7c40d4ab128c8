"""Resolution schemes and time integration (PHYSICS.md 3)."""

from .impulse import ImpulseSolver

__all__ = ["ImpulseSolver"]
