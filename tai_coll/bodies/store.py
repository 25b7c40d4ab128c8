"""The state of a scene's rigid bodies, on the host in float64 (docs/physics.md 7).

A scene holds few bodies (tens), each updated once or twice a substep: their state lives in
numpy arrays, and kernels see a body only as an entry of the collider table (its shape at
its pose, moving with its velocities) plus the small per-body arrays of `coupling.py`.

Per body b: x[b] the centre of mass (world, m), R[b] the rotation of the body frame (the
shape's local frame) into the world, v[b] the velocity of the centre of mass (m/s), L[b] the
angular momentum about the centre of mass (world frame, kg m^2/s). Angular momentum, not
angular velocity, is the state: a free body keeps L exactly, and every exchange with a
particle adds to it exactly what the particle loses. The angular velocity is
w = R I^-1 R^T L (I the body-frame inertia).
"""

from __future__ import annotations

import numpy as np

from ..geometry.frames import rotation_from_vector


class BodyStore:
    def __init__(self):
        self.count = 0
        self.x = np.zeros((0, 3))
        self.R = np.zeros((0, 3, 3))
        self.v = np.zeros((0, 3))
        self.L = np.zeros((0, 3))
        self.mass = np.zeros(0)
        self.inertia = np.zeros((0, 3, 3))  # body frame, about the centre of mass
        self.inv_inertia = np.zeros((0, 3, 3))
        self.com_local = np.zeros((0, 3))  # centre of mass in the shape's local frame
        self.supported = np.zeros(0, dtype=bool)  # resting on what holds it (rigid.supported_bodies)
        self.entries = []  # the collider table's ColliderEntry of each body
        self.materials = []

    def add(self, entry, material, props, rotation, velocity, angular_velocity) -> int:
        """Append a body: props (mass_properties.MassProperties), its shape's collider entry,
        the shape's rotation; velocity of the centre of mass and angular velocity (world)."""
        b = self.count
        com_world = entry.shape.center + rotation @ props.center_of_mass
        inertia = np.array(props.inertia, dtype=np.float64)
        self.x = np.vstack([self.x, com_world[None]])
        self.R = np.concatenate([self.R, rotation[None]])
        self.v = np.vstack([self.v, np.asarray(velocity, dtype=np.float64)[None]])
        self.mass = np.append(self.mass, props.mass)
        self.inertia = np.concatenate([self.inertia, inertia[None]])
        self.inv_inertia = np.concatenate([self.inv_inertia, np.linalg.inv(inertia)[None]])
        self.com_local = np.vstack([self.com_local, np.asarray(props.center_of_mass, dtype=np.float64)[None]])
        self.L = np.vstack([self.L, np.zeros((1, 3))])
        self.supported = np.append(self.supported, False)
        self.entries.append(entry)
        self.materials.append(material)
        self.count += 1
        self.set_angular_velocity(b, angular_velocity)
        return b

    # ------------------------------------------------------------------ derived quantities
    def inertia_world(self, b) -> np.ndarray:
        return self.R[b] @ self.inertia[b] @ self.R[b].T

    def inv_inertia_world(self, b) -> np.ndarray:
        return self.R[b] @ self.inv_inertia[b] @ self.R[b].T

    def omega(self, b) -> np.ndarray:
        """Angular velocity (rad/s, world) of body b: R I^-1 R^T L."""
        return self.inv_inertia_world(b) @ self.L[b]

    def inv_mass(self, b) -> float:
        return 1.0 / self.mass[b]

    def set_angular_velocity(self, b, w):
        self.L[b] = self.inertia_world(b) @ np.asarray(w, dtype=np.float64)

    def shape_pose(self, b, x=None, R=None):
        """(center, rotation) of body b's collider shape for the body pose (x, R) (default:
        its current one): the shape's origin sits at x - R com_local."""
        x = self.x[b] if x is None else x
        R = self.R[b] if R is None else R
        return x - R @ self.com_local[b], R

    def apply_impulse(self, b, impulse, point=None):
        """An impulse (N s) at a world point (default: the centre of mass)."""
        impulse = np.asarray(impulse, dtype=np.float64)
        self.v[b] = self.v[b] + impulse / self.mass[b]
        if point is not None:
            self.L[b] = self.L[b] + cross(np.asarray(point, dtype=np.float64) - self.x[b], impulse)

    def advanced_pose(self, b, dt):
        """The pose after dt at the current velocities: x + dt v, exp(w dt) R (orthonormal to
        round-off; `orthonormal` takes the drift of many such products out)."""
        x1 = self.x[b] + dt * self.v[b]
        R1 = rotation_from_vector(dt * self.omega(b)) @ self.R[b]
        return x1, R1

    def kinetic_energy(self, b) -> float:
        return 0.5 * self.mass[b] * float(self.v[b] @ self.v[b]) + 0.5 * float(self.L[b] @ self.omega(b))

    # ------------------------------------------------------------------ state arrays
    def state(self) -> dict:
        """Copies of every body's state (what a checkpoint holds)."""
        return {"x": self.x.copy(), "R": self.R.copy(), "v": self.v.copy(), "L": self.L.copy()}


def cross(a, b) -> np.ndarray:
    """a x b of two 3-vectors (np.cross costs tens of microseconds a call)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def orthonormal(R: np.ndarray) -> np.ndarray:
    """The rotation nearest to R (polar decomposition by SVD): repeated products of rotations
    drift from orthonormality by round-off."""
    u, _, vt = np.linalg.svd(R)
    out = u @ vt
    if np.linalg.det(out) < 0:  # (cannot happen for R near a rotation; kept for safety)
        u[:, -1] *= -1
        out = u @ vt
    return out
