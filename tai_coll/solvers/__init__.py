"""Resolution schemes and time integration (docs/physics.md 3-6): the Solver interface a Scene
calls (base.py), the impulse and penalty solvers, and particle pairs (pairs/)."""

from .base import Solver, World
from .impulse import ImpulseSolver
from .penalty import PenaltySolver

__all__ = ["ImpulseSolver", "PenaltySolver", "Solver", "World"]
