"""Rigid bodies against colliders and each other (docs/physics.md 6.4). Placeholder until the
contact solver lands: gravity only."""

import numpy as np


def resolve_contacts(store, table, gravity: np.ndarray, dt: float) -> int:
    """Gravity on every body; contacts: none yet."""
    store.v += dt * gravity
    return 0
