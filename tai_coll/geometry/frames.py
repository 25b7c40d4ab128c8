"""Rigid frames on the host (numpy): rotations, axis alignment, and their rates.

A collider's geometry lives in its local frame; the world point x maps to the local point
R^T (x - c). Kernels do the same arithmetic with the matrices computed here.
"""

from __future__ import annotations

import numpy as np

from .. import validate


def skew(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def rotation_matrix(axis, angle: float) -> np.ndarray:
    """Rotation by `angle` radians about `axis` (Rodrigues' formula): a finite, non-zero
    axis and a finite angle, or ValueError naming the one that is not."""
    # stored=False: the matrix is float64 on the host; only its entries, in [-1, 1], reach kernels
    axis = validate.vector3("axis", axis, nonzero=True, stored=False)
    angle = validate.real("angle", angle, stored=False)
    return _rodrigues(axis, angle)


def _rodrigues(axis: np.ndarray, angle: float) -> np.ndarray:
    """rotation_matrix without the argument checks, for the rotations computed here."""
    k = axis / np.linalg.norm(axis)
    K = skew(k)
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


def rotation_from_vector(rotvec: np.ndarray) -> np.ndarray:
    """exp([rotvec]x): rotation about rotvec by |rotvec| radians."""
    angle = float(np.linalg.norm(rotvec))
    if angle < 1e-15:
        return np.eye(3) + skew(rotvec)
    return _rodrigues(rotvec, angle)


def rotation_to_vector(R: np.ndarray) -> np.ndarray:
    """log(R) as a rotation vector (axis * angle), the inverse of `rotation_from_vector`.

    The angle comes from atan2(sin, cos), well conditioned at every angle; near a half turn
    the axis comes from the symmetric part (R + R^T)/2 - cos I = (1 - cos) k k^T, its sign
    from the antisymmetric part.
    """
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    sin = np.linalg.norm(w) / 2.0
    cos = (np.trace(R) - 1.0) / 2.0
    angle = np.arctan2(sin, cos)
    if angle < 1e-8:
        return 0.5 * w
    if cos > -0.5:
        return angle / (2.0 * sin) * w
    M = (R + R.T) / 2.0 - cos * np.eye(3)
    k = M[np.argmax(np.diag(M))]
    k = k / np.linalg.norm(k)
    if np.dot(k, w) < 0.0:
        k = -k
    return angle * k


def align_y(direction: np.ndarray) -> np.ndarray:
    """A rotation taking the local +y axis to the unit vector along `direction`."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    y = np.array([0.0, 1.0, 0.0])
    axis = np.cross(y, d)
    sin = np.linalg.norm(axis)
    cos = float(np.dot(y, d))
    if sin < 1e-15:
        return np.eye(3) if cos > 0 else np.diag([1.0, -1.0, -1.0])  # identity or a half turn about x
    return _rodrigues(axis / sin, float(np.arctan2(sin, cos)))
