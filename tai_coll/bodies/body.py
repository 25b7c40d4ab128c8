"""`tc.Body`: the handle `Scene.add_body` returns (docs/physics.md 7)."""

from __future__ import annotations

import numpy as np

from .. import validate


class Body:
    """A rigid body in a scene: a closed collider shape with mass that particles push and that
    pushes back, falls under gravity and collides with colliders and other bodies.

    position: its centre of mass (m, world); rotation: 3x3, body frame (the shape's local
    frame) to world; velocity (m/s) and angular_velocity (rad/s) in the world frame; mass
    (kg); inertia: 3x3 about the centre of mass in the body frame (kg m^2; in the world it
    is R I R^T). Reading returns copies; change the motion with set_velocity,
    set_angular_velocity and apply_impulse.
    """

    def __init__(self, system, index: int):
        self._system = system
        self._index = index

    @property
    def index(self) -> int:
        """Its place among the scene's bodies (Scene.bodies)."""
        return self._index

    @property
    def _store(self):
        return self._system.store

    @property
    def shape(self):
        return self._store.entries[self._index].shape

    @property
    def material(self):
        return self._store.materials[self._index]

    @property
    def collider(self):
        """The scene's collider entry for the body's shape (its current pose)."""
        return self._store.entries[self._index]

    @property
    def position(self) -> np.ndarray:
        return self._store.x[self._index].copy()

    @property
    def rotation(self) -> np.ndarray:
        return self._store.R[self._index].copy()

    @property
    def velocity(self) -> np.ndarray:
        return self._store.v[self._index].copy()

    @property
    def angular_velocity(self) -> np.ndarray:
        return self._store.omega(self._index)

    @property
    def angular_momentum(self) -> np.ndarray:
        """About the centre of mass, world frame (kg m^2/s)."""
        return self._store.L[self._index].copy()

    @property
    def mass(self) -> float:
        return float(self._store.mass[self._index])

    @property
    def inertia(self) -> np.ndarray:
        return self._store.inertia[self._index].copy()

    @property
    def kinetic_energy(self) -> float:
        """Translational plus rotational kinetic energy (J)."""
        return self._store.kinetic_energy(self._index)

    def set_velocity(self, velocity) -> None:
        """Set the velocity of the centre of mass (m/s, world)."""
        self._store.v[self._index] = validate.vector3("velocity", velocity)

    def set_angular_velocity(self, angular_velocity) -> None:
        """Set the angular velocity (rad/s, world frame)."""
        self._store.set_angular_velocity(self._index, validate.vector3("angular_velocity", angular_velocity))

    def apply_impulse(self, impulse, point=None) -> None:
        """Apply an impulse (N s, world) at a world point (default: the centre of mass, which
        changes no spin)."""
        impulse = validate.vector3("impulse", impulse)
        point = None if point is None else validate.vector3("point", point)
        self._store.apply_impulse(self._index, impulse, point)

    def __repr__(self):
        p = self.position
        return (f"Body({type(self.shape).__name__}, mass={self.mass:.4g} kg, "
                f"position=({p[0]:.4g}, {p[1]:.4g}, {p[2]:.4g}))")
