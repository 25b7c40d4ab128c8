"""Kinematic motion of colliders: where a collider is at time t, and how fast its surface moves.

docs/physics.md 3, moving objects. A pose is (center, R). Motion is either constant (a linear
velocity of the center and an angular velocity about the center) or a user callable
t -> (translation, rotation_matrix) applied to the collider's rest pose.
"""

from __future__ import annotations

import numpy as np

from .. import validate
from ..geometry.frames import rotation_from_vector, rotation_to_vector


class ConstantMotion:
    def __init__(self, velocity, angular_velocity):
        self.velocity = validate.vector3("velocity", velocity) if velocity is not None else np.zeros(3)
        self.angular_velocity = (validate.vector3("angular_velocity", angular_velocity)
                                 if angular_velocity is not None else np.zeros(3))

    def pose(self, rest_center, rest_rotation, t):
        return rest_center + self.velocity * t, rotation_from_vector(self.angular_velocity * t) @ rest_rotation

    def rates(self, pose0, pose1, dt):
        return self.velocity, self.angular_velocity


class CallableMotion:
    def __init__(self, fn):
        if not callable(fn):
            raise TypeError(f"motion must be a callable t -> (translation, rotation_matrix); got {type(fn).__name__}")
        self.fn = fn

    def pose(self, rest_center, rest_rotation, t):
        result = self.fn(t)
        try:
            translation, rotation = result
        except (TypeError, ValueError):
            raise TypeError("motion(t) must return (translation, rotation_matrix); "
                            f"got {type(result).__name__} at t={t}") from None
        translation = validate.vector3(f"motion({t:g}) translation", translation)
        rotation = validate.rotation(f"motion({t:g}) rotation", rotation)
        return rest_center + translation, rotation @ rest_rotation

    def rates(self, pose0, pose1, dt):
        """Finite-difference velocities over the substep."""
        velocity = (pose1[0] - pose0[0]) / dt
        angular = rotation_to_vector(pose1[1] @ pose0[1].T) / dt
        return velocity, angular


def make_motion(velocity, angular_velocity, motion):
    if motion is not None:
        if velocity is not None or angular_velocity is not None:
            raise ValueError("give either motion or velocity/angular_velocity, not both")
        return CallableMotion(motion)
    if velocity is None and angular_velocity is None:
        return None
    return ConstantMotion(velocity, angular_velocity)
