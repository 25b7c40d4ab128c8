"""Rigid frames on the host (geometry/frames.py): Rodrigues rotations, their logarithm, and
the rotation taking +y to an axis, against independent numpy references."""

import numpy as np
import pytest

import tai_coll as tc
from tai_coll.geometry.frames import align_y, rotation_from_vector, rotation_to_vector

PHI_TOL = 1e-9  # as in test_geometry.py: closed-form agreement in f64


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def ref_rodrigues(axis, angle, v):
    """v rotated by angle about axis: v cos + (k x v) sin + k (k.v)(1 - cos)."""
    k = unit(axis)
    return v * np.cos(angle) + np.cross(k, v) * np.sin(angle) + np.outer(v @ k, k) * (1 - np.cos(angle))


def test_rotation_matrix_is_rodrigues(rng):
    for _ in range(20):
        axis = rng.normal(size=3) * rng.uniform(0.1, 10.0)  # any length
        angle = rng.uniform(-2 * np.pi, 2 * np.pi)
        R = tc.rotation_matrix(axis, angle)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-14)
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)
        v = rng.normal(size=(5, 3))
        np.testing.assert_allclose(v @ R.T, ref_rodrigues(axis, angle, v), atol=1e-14)
        np.testing.assert_allclose(R @ unit(axis), unit(axis), atol=1e-14)  # the axis is fixed
    # a quarter turn about z takes x to y
    np.testing.assert_allclose(tc.rotation_matrix((0, 0, 1), np.pi / 2) @ [1, 0, 0], [0, 1, 0], atol=1e-15)


def test_rotation_to_vector_inverts_rotation_from_vector(rng):
    for _ in range(50):
        k = unit(rng.normal(size=3))
        w = k * rng.uniform(0.0, np.pi - 1e-2)
        R = rotation_from_vector(w)
        np.testing.assert_allclose(rotation_to_vector(R), w, atol=1e-12)
    small = np.array([1e-10, -2e-10, 3e-11])
    np.testing.assert_allclose(rotation_to_vector(rotation_from_vector(small)), small, atol=1e-18)
    np.testing.assert_allclose(rotation_to_vector(np.eye(3)), 0.0, atol=0)


@pytest.mark.parametrize("gap", [1e-3, 1e-4, 1e-5, 3e-6, 1.1e-6, 5e-7, 1e-9, 0.0])
@pytest.mark.parametrize("axis", [(0.3, -0.8, 0.5), (-1.0, 0.2, 0.1), (0.0, 0.0, 1.0)])
def test_rotation_to_vector_near_half_turn(axis, gap):
    """log(exp(w)) for |w| = pi - gap. The round trip must reproduce R, and below a half
    turn the vector is unique: w itself (at exactly pi, w or -w)."""
    w = (np.pi - gap) * unit(axis)
    R = rotation_from_vector(w)
    out = rotation_to_vector(R)
    np.testing.assert_allclose(rotation_from_vector(out), R, atol=1e-8)
    if gap == 0.0:
        assert min(np.abs(out - w).max(), np.abs(out + w).max()) < 1e-8
    else:
        np.testing.assert_allclose(out, w, atol=1e-8)


@pytest.mark.parametrize("direction", [
    (0.0, 1.0, 0.0), (0.0, -1.0, 0.0), (0.0, 3.0, 0.0), (0.0, -0.2, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, -1.0),
    (1.0, 2.0, -3.0), (-0.3, -1.0, 0.2), (1e-3, -1.0, 0.0), (1e-6, -1.0, 0.0), (2e-7, 1.0, -1e-7), (1e-13, -1.0, 0.0),
])
def test_align_y_maps_y_to_direction(direction):
    R = align_y(np.array(direction))
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-14)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(R @ np.array([0.0, 1.0, 0.0]), unit(direction), atol=1e-12)


def test_axial_colliders_follow_their_axis():
    """Cylinder and capsule poses come from the axis: the cap centers lie along it."""
    axis = unit([1.0, -2.0, 0.5])
    c = np.array([0.1, 0.2, 0.3])
    cyl = tc.Cylinder(center=c, radius=0.2, half_height=0.7, axis=axis)
    cap = tc.Capsule(center=c, radius=0.2, half_height=0.7, axis=axis)
    caps = c + np.array([[0.7], [-0.7]]) * axis
    np.testing.assert_allclose(cyl.signed_distance(caps + 0.1 * np.array([[1.0], [-1.0]]) * axis), 0.1, atol=PHI_TOL)
    np.testing.assert_allclose(cyl.normal(caps + 0.1 * np.array([[1.0], [-1.0]]) * axis), [axis, -axis], atol=PHI_TOL)
    np.testing.assert_allclose(cap.signed_distance(caps + 0.5 * np.array([[1.0], [-1.0]]) * axis), 0.3, atol=PHI_TOL)
