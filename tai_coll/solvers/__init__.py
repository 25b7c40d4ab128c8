"""Resolution schemes and time integration (PHYSICS.md 3 and 4)."""

from .impulse import ImpulseSolver
from .penalty import PenaltySolver

__all__ = ["ImpulseSolver", "PenaltySolver"]
