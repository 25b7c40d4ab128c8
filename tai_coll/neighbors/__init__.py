"""Neighbour search: a spatial hash grid built in parallel every substep."""

from .hash_grid import HashGrid

__all__ = ["HashGrid"]
