"""Particle-particle collisions (docs/physics.md 5): settings.py (what the user chose),
collisions.py (the orchestrator of a substep with pairs), gauss_seidel.py and jacobi.py (the
impulse passes), predict.py, dem.py (DEM forces), springs.py (tangential springs' memory),
overlap.py (measuring overlap)."""

from .collisions import ParticleCollisions
from .settings import PairSettings

__all__ = ["PairSettings", "ParticleCollisions"]
