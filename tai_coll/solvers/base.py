"""The interface between a Scene and its solver: what the scene hands a solver (`World`) and
the methods it calls (`Solver`).

A solver never reads a scene's private fields: each call gets the World, whose particle
store and collider table the solver's kernels read and write. The scene's frame loop, per
frame (docs/physics.md 3):

- before the first step and whenever particles or colliders were added: `check(world, dt)`,
  whose messages the scene warns with (once each);
- colliders that hold still: `advance(world, dt, substeps)`, every substep of the frame in
  one call;
- moving colliders: their poses for each substep, then `advance(world, dt, 1)`;
- particles that collide with each other: `pair_substep(world, pairs, dt)` each substep;
- a particle whose state turned NaN or inf: `stability_advice(world)` joins the error.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class World:
    """What a solver advances: the scene's particle store (scene/particles.py), its collider
    table (scene/colliders.py), gravity (m/s^2) and the domain box ((lower, upper) corners
    in m, or None)."""

    particles: object
    colliders: object
    gravity: np.ndarray
    domain: tuple | None
    pair_contacts: bool = False  # whether particles collide with each other
    bodies: object = None  # the scene's rigid bodies (bodies/system.py BodySystem), if any

    def domain_bounds(self) -> tuple:
        """(use_domain, lower corner, upper corner) as kernels take them (corners 0 without)."""
        if self.domain is None:
            return False, np.zeros(3), np.zeros(3)
        return True, self.domain[0], self.domain[1]

    def rest_speed(self, dt: float) -> float:
        """Twice the speed gravity adds in a substep of dt (m/s): an approach slower than this is
        a resting contact, not a bounce (docs/physics.md 3.5 and 5)."""
        return 2.0 * float(np.linalg.norm(self.gravity)) * dt


class Solver(abc.ABC):
    """A contact solver: how a Scene's particles are resolved against its colliders and, when
    particle collisions are on, against each other.

    pair_model: the kind of particle-pair contact the solver pairs with, "impulses"
        (two-body impulses, docs/physics.md 5) or "dem" (spring-dashpots, forces).
    spin: whether particles spin (keep angular velocities); False for point particles.
    """

    pair_model: str = "impulses"
    spin: bool = False

    @abc.abstractmethod
    def advance(self, world: World, dt: float, substeps: int = 1) -> None:
        """Advance every active particle by `substeps` substeps of dt against the colliders,
        which keep their current poses for the whole call."""

    @abc.abstractmethod
    def pair_substep(self, world: World, pairs, dt: float) -> None:
        """One substep with particle-particle contacts (pairs: solvers.pairs.ParticleCollisions)
        and then the colliders."""

    def check(self, world: World, dt: float) -> list[str]:
        """Warnings about the scene as it stands (no warnings by default)."""
        return []

    def place_out(self, world: World, first: int) -> None:
        """Before the next step: particles placed from the host (storage slots first..) that
        lie inside colliders, where the solver would turn that into speed, moved out. By
        default none are (the impulse solver's last resort pushes them out by positions,
        docs/physics.md 3.4)."""

    def time_step_limits(self, world: World) -> tuple | None:
        """(recommended dt, stability limit) in s of the stiffest contact the solver integrates
        explicitly: beyond the limit a run diverges (Scene stops it); None: no such limit."""
        return None

    def stability_advice(self, world: World) -> str | None:
        """What to change when a run went non-finite (None: nothing specific)."""
        return None
