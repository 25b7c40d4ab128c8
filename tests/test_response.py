"""The black-box collision routine (docs/physics.md 2) against hand-computed cases and a numpy
re-implementation: `tc.collide` for a particle against an object, `tc.collide_pair` for two
movable bodies."""

import numpy as np
import pytest

import tai_coll as tc

UP = np.array([0.0, 1.0, 0.0])


def reference_collide(v, n, e, mu, v_obj=None, wet=0.0, wet_law="linear"):
    """docs/physics.md 2, steps 1-5, row by row in numpy."""
    v = np.atleast_2d(np.asarray(v, dtype=float))
    n = np.broadcast_to(np.asarray(n, dtype=float), v.shape)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    v_obj = np.zeros_like(v) if v_obj is None else np.broadcast_to(np.asarray(v_obj, dtype=float), v.shape)
    out = v.copy()
    for i in range(len(v)):
        v_rel = v[i] - v_obj[i]
        vn = v_rel @ n[i]
        if vn >= 0.0:
            continue
        vt = v_rel - vn * n[i]
        dvn = (1.0 + e) * abs(vn)
        vt_len = np.linalg.norm(vt)
        scale = max(0.0, 1.0 - mu * dvn / vt_len) if vt_len > 0 else 0.0
        if wet_law == "linear":
            scale *= max(0.0, 1.0 - wet * dvn)
        else:
            scale *= np.exp(-wet * dvn)
        out[i] = v_obj[i] + scale * vt - e * vn * n[i]
    return out


# ---------------------------------------------------------------- restitution
@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_restitution_only(e):
    v = np.array([0.3, -2.0, -0.1])
    out = tc.collide(v, UP, restitution=e, friction=0.0)
    np.testing.assert_allclose(out, [0.3, 2.0 * e, -0.1], rtol=0, atol=1e-14)


def test_restitution_oblique_normal():
    # Normal along (1, 1, 0)/sqrt(2); v = (-1, -1, 0) is purely normal, speed sqrt(2).
    n = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    out = tc.collide(np.array([-1.0, -1.0, 0.0]), n, restitution=0.5, friction=0.0)
    np.testing.assert_allclose(out, [0.5, 0.5, 0.0], atol=1e-14)


# ---------------------------------------------------------------- dry friction
def test_static_dry_friction_stops_tangential():
    # v_N = -2, e = 0 -> dv_N = 2; mu dv_N = 1.0 >= |v_T| = 0.8 -> static: v_T = 0.
    v = np.array([0.8, -2.0, 0.0])
    out = tc.collide(v, UP, restitution=0.0, friction=0.5)
    np.testing.assert_allclose(out, [0.0, 0.0, 0.0], atol=1e-14)


def test_static_dry_friction_exact_threshold():
    # mu dv_N == |v_T| exactly: the bracket hits 0.
    v = np.array([0.0, -1.0, 0.6])
    out = tc.collide(v, UP, restitution=0.5, friction=0.4)  # dv_N = 1.5, mu dv_N = 0.6
    np.testing.assert_allclose(out, [0.0, 0.5, 0.0], atol=1e-14)


def test_kinetic_dry_friction_reduces_magnitude_keeps_direction():
    # v_T = (3, 0, 4) (|v_T| = 5), v_N = -1, e = 0.5 -> dv_N = 1.5, mu = 2 -> |v_T| drops by 3.
    v = np.array([3.0, -1.0, 4.0])
    out = tc.collide(v, UP, restitution=0.5, friction=2.0)
    vt = np.array([out[0], 0.0, out[2]])
    assert np.linalg.norm(vt) == pytest.approx(2.0, abs=1e-13)
    np.testing.assert_allclose(vt / np.linalg.norm(vt), [0.6, 0.0, 0.8], atol=1e-13)
    assert out[1] == pytest.approx(0.5, abs=1e-14)


# ---------------------------------------------------------------- wet friction
def test_wet_friction_linear():
    # dv_N = (1 + 0) * 2 = 2; D = 0.2 -> v_T *= 1 - 0.4 = 0.6.
    v = np.array([1.0, -2.0, -0.5])
    out = tc.collide(v, UP, restitution=0.0, friction=0.0, wet_friction=0.2, wet_law="linear")
    np.testing.assert_allclose(out, [0.6, 0.0, -0.3], atol=1e-14)


def test_wet_friction_linear_caps_at_zero():
    # D dv_N = 3 > 1: the linear law would reverse v_T; it is capped at 0 instead.
    v = np.array([1.0, -2.0, 0.0])
    out = tc.collide(v, UP, restitution=0.5, friction=0.0, wet_friction=1.0, wet_law="linear")
    np.testing.assert_allclose(out, [0.0, 1.0, 0.0], atol=1e-14)


@pytest.mark.parametrize("wet", [0.2, 1.0, 5.0])
def test_wet_friction_exponential(wet):
    v = np.array([1.0, -2.0, -0.5])
    out = tc.collide(v, UP, restitution=0.5, friction=0.0, wet_friction=wet, wet_law="exponential")
    k = np.exp(-wet * 3.0)  # dv_N = 1.5 * 2
    np.testing.assert_allclose(out, [k, 1.0, -0.5 * k], rtol=1e-13, atol=1e-15)


def test_dry_and_wet_combine():
    # Dry first: |v_T| = 2, dv_N = 1, mu = 0.5 -> 1.5; then wet linear D = 0.25 -> * 0.75.
    v = np.array([2.0, -1.0, 0.0])
    out = tc.collide(v, UP, restitution=0.0, friction=0.5, wet_friction=0.25)
    np.testing.assert_allclose(out, [1.125, 0.0, 0.0], atol=1e-14)


# ---------------------------------------------------------------- moving object
def test_moving_wall_hits_resting_particle_elastic():
    # A wall moving at u toward a particle at rest: relative law gives 2u.
    u = 1.5
    out = tc.collide(np.zeros(3), np.array([1.0, 0.0, 0.0]), restitution=1.0, friction=0.0,
                     object_velocity=np.array([u, 0.0, 0.0]))
    np.testing.assert_allclose(out, [2 * u, 0.0, 0.0], atol=1e-14)


def test_moving_wall_inelastic_carries_particle():
    u = 0.7
    out = tc.collide(np.array([0.0, 0.0, 0.2]), np.array([1.0, 0.0, 0.0]), restitution=0.0, friction=0.0,
                     object_velocity=np.array([u, 0.0, 0.0]))
    np.testing.assert_allclose(out, [u, 0.0, 0.2], atol=1e-14)


def test_moving_object_friction_acts_on_relative_tangential_velocity():
    # Conveyor: floor surface moves at (1, 0, 0); particle lands at (0, -3, 0) with e = 0, mu = 1:
    # v_rel_T = (-1, 0, 0), dv_N = 3 >= 1 -> static: the particle takes the belt's velocity.
    out = tc.collide(np.array([0.0, -3.0, 0.0]), UP, restitution=0.0, friction=1.0,
                     object_velocity=np.array([1.0, 0.0, 0.0]))
    np.testing.assert_allclose(out, [1.0, 0.0, 0.0], atol=1e-14)


def test_particle_faster_than_receding_object_unchanged_if_separating():
    # The object recedes faster than the particle follows: v_rel . n > 0, no change.
    v = np.array([0.0, -1.0, 0.0])
    out = tc.collide(v, UP, restitution=1.0, friction=1.0, object_velocity=np.array([0.0, -2.0, 0.0]))
    np.testing.assert_array_equal(out, v)


# ---------------------------------------------------------------- separating, shapes
@pytest.mark.parametrize("v", [[0.3, 1.0, -0.2], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
def test_separating_or_tangential_contact_unchanged(v):
    v = np.array(v)
    out = tc.collide(v, UP, restitution=0.5, friction=1.0, wet_friction=1.0)
    np.testing.assert_array_equal(out, v)


def test_single_input_returns_single_row():
    out = tc.collide(np.array([0.0, -1.0, 0.0]), UP, restitution=0.5)
    assert out.shape == (3,)


def test_broadcast_single_normal():
    rng = np.random.default_rng(1)
    v = rng.normal(size=(50, 3))
    n = np.array([0.0, 0.0, 1.0])
    out = tc.collide(v, n, restitution=0.3, friction=0.2)
    assert out.shape == (50, 3)
    np.testing.assert_allclose(out, reference_collide(v, n, 0.3, 0.2), atol=1e-13)


def test_broadcast_single_object_velocity():
    rng = np.random.default_rng(2)
    v = rng.normal(size=(20, 3))
    vo = np.array([0.5, -0.2, 0.1])
    out = tc.collide(v, UP, restitution=0.6, friction=0.3, object_velocity=vo)
    np.testing.assert_allclose(out, reference_collide(v, UP, 0.6, 0.3, v_obj=vo), atol=1e-13)


def test_non_unit_normal_is_normalised():
    v = np.array([0.4, -2.0, 0.1])
    a = tc.collide(v, 7.5 * UP, restitution=0.5, friction=0.1)
    b = tc.collide(v, UP, restitution=0.5, friction=0.1)
    np.testing.assert_allclose(a, b, atol=1e-14)
    n = np.array([[3.0, 4.0, 0.0]])
    np.testing.assert_allclose(tc.collide(np.array([[-3.0, -4.0, 0.0]]), n, restitution=1.0, friction=0.0),
                               [[3.0, 4.0, 0.0]], atol=1e-13)


def test_zero_normal_rejected():
    with pytest.raises(ValueError):
        tc.collide(np.array([0.0, -1.0, 0.0]), np.zeros(3))


def test_empty_batch():
    out = tc.collide(np.zeros((0, 3)), UP)
    assert out.shape == (0, 3)


# ---------------------------------------------------------------- random batch vs reference
@pytest.mark.parametrize("wet_law", ["linear", "exponential"])
@pytest.mark.parametrize("e,mu,wet", [(0.0, 0.0, 0.0), (0.5, 0.3, 0.0), (1.0, 2.0, 0.0),
                                      (0.2, 0.4, 0.3), (0.8, 0.0, 2.0)])
def test_random_batch_matches_reference(rng, e, mu, wet, wet_law):
    count = 400
    v = rng.normal(size=(count, 3)) * rng.uniform(0.1, 10.0, size=(count, 1))
    n = rng.normal(size=(count, 3)) * rng.uniform(0.5, 3.0, size=(count, 1))  # not unit length
    vo = rng.normal(size=(count, 3)) * 0.5
    out = tc.collide(v, n, restitution=e, friction=mu, object_velocity=vo, wet_friction=wet, wet_law=wet_law)
    ref = reference_collide(v, n, e, mu, v_obj=vo, wet=wet, wet_law=wet_law)
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-12)
    # Invariants: approaching rows now separate with -e v_N; separating rows untouched.
    nu = n / np.linalg.norm(n, axis=1, keepdims=True)
    vn = np.einsum("ij,ij->i", v - vo, nu)
    vn_new = np.einsum("ij,ij->i", out - vo, nu)
    np.testing.assert_allclose(vn_new[vn < 0], -e * vn[vn < 0], atol=1e-12)
    # (v - v_obj) + v_obj may differ from v in the last bit; nothing more.
    np.testing.assert_allclose(out[vn >= 0], v[vn >= 0], rtol=0, atol=1e-14)
    # Friction never increases the relative tangential speed.
    vt = (v - vo) - vn[:, None] * nu
    vt_new = (out - vo) - vn_new[:, None] * nu
    assert np.all(np.linalg.norm(vt_new, axis=1) <= np.linalg.norm(vt, axis=1) + 1e-12)


# ---------------------------------------------------------------- two movable bodies
def test_pair_head_on_textbook():
    ma, mb, e = 1.0, 3.0, 0.5
    va, vb = 2.0, -1.0  # along x; b sits at +x of a, so the normal from b to a is -x
    ref_a = (ma * va + mb * vb - mb * e * (va - vb)) / (ma + mb)
    ref_b = (ma * va + mb * vb + ma * e * (va - vb)) / (ma + mb)
    out_a, out_b = tc.collide_pair(np.array([va, 0.0, 0.0]), np.array([vb, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0]),
                                   ma, mb, restitution=e, friction=0.0)
    np.testing.assert_allclose(out_a, [ref_a, 0.0, 0.0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(out_b, [ref_b, 0.0, 0.0], rtol=0, atol=1e-9)
    assert ref_a == pytest.approx(-1.375) and ref_b == pytest.approx(0.125)


def test_pair_equal_masses_elastic_swap():
    a, b = tc.collide_pair(np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0]),
                           2.0, 2.0, restitution=1.0, friction=0.0)
    np.testing.assert_allclose(a, [0.0, 0.0, 0.0], atol=1e-14)
    np.testing.assert_allclose(b, [1.0, 0.0, 0.0], atol=1e-14)


def test_pair_separating_unchanged():
    va, vb = np.array([-1.0, 0.2, 0.0]), np.array([1.0, 0.0, 0.0])
    a, b = tc.collide_pair(va, vb, np.array([-1.0, 0.0, 0.0]), 1.0, 1.0, restitution=0.5, friction=0.5)
    np.testing.assert_array_equal(a, va)
    np.testing.assert_array_equal(b, vb)


@pytest.mark.parametrize("e,mu,wet", [(0.5, 0.0, 0.0), (0.3, 0.5, 0.0), (0.9, 3.0, 0.0), (0.0, 0.2, 0.5)])
def test_pair_random_batch_momentum_and_relative_law(rng, e, mu, wet):
    count = 300
    va = rng.normal(size=(count, 3)) * 3
    vb = rng.normal(size=(count, 3)) * 3
    n = rng.normal(size=(count, 3))
    ma = rng.uniform(0.1, 10.0, size=count)
    mb = rng.uniform(0.1, 10.0, size=count)
    a, b = tc.collide_pair(va, vb, n, ma, mb, restitution=e, friction=mu, wet_friction=wet)
    p0 = ma[:, None] * va + mb[:, None] * vb
    p1 = ma[:, None] * a + mb[:, None] * b
    scale = np.abs(ma[:, None] * va).max() + np.abs(mb[:, None] * vb).max()
    np.testing.assert_allclose(p1, p0, rtol=0, atol=1e-13 * scale)
    # The relative velocity follows the single-body law.
    ref_rel = reference_collide(va - vb, n, e, mu, wet=wet)
    np.testing.assert_allclose(a - b, ref_rel, rtol=1e-11, atol=1e-11)
    # Energy does not increase (e <= 1, friction dissipates).
    ke0 = 0.5 * (ma * (va ** 2).sum(1) + mb * (vb ** 2).sum(1))
    ke1 = 0.5 * (ma * (a ** 2).sum(1) + mb * (b ** 2).sum(1))
    assert np.all(ke1 <= ke0 * (1 + 1e-12) + 1e-12)


def test_pair_infinite_mass_behaves_like_collide(rng):
    count = 100
    va = rng.normal(size=(count, 3))
    vb = rng.normal(size=(count, 3)) * 0.5
    n = rng.normal(size=(count, 3))
    a, b = tc.collide_pair(va, vb, n, 1.0, np.inf, restitution=0.7, friction=0.4)
    ref = tc.collide(va, n, restitution=0.7, friction=0.4, object_velocity=vb)
    np.testing.assert_allclose(a, ref, rtol=1e-12, atol=1e-13)
    np.testing.assert_array_equal(b, vb)
    # And the other way round: an immovable a; the normal points from b to a, so b sees -n.
    a2, b2 = tc.collide_pair(vb, va, -n, np.inf, 2.0, restitution=0.7, friction=0.4)
    np.testing.assert_allclose(b2, ref, rtol=1e-12, atol=1e-13)
    np.testing.assert_array_equal(a2, vb)


def test_pair_both_infinite_rejected():
    with pytest.raises(ValueError):
        tc.collide_pair(np.zeros(3), np.zeros(3), UP, np.inf, np.inf)
