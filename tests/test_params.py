"""`tc.params`: the constants of seed 002's 1-D contact model m a = -K x - D v, against
closed forms and against the model integrated step by step (symplectic Euler, in numpy)."""

import math

import numpy as np
import pytest

import tai_coll as tc

P = tc.params


def symplectic_euler_1d(m, k, d, dt, steps, x0=1.0, v0=0.0):
    """x after each step of v += dt (-k x - d v) / m, x += dt v."""
    x, v = x0, v0
    out = np.empty(steps)
    for i in range(steps):
        v += dt * (-k * x - d * v) / m
        x += dt * v
        out[i] = x
    return out


def test_closed_forms():
    m, k = 2.0, 8.0
    assert P.critical_damping(m, k) == pytest.approx(8.0)  # 2 sqrt(16)
    assert P.damping_ratio(m, k, 4.0) == pytest.approx(0.5)
    assert P.damping_from_ratio(m, k, 0.5) == pytest.approx(4.0)
    assert P.natural_period(m, k) == pytest.approx(2 * math.pi * 0.5)
    assert P.decay_time(m, 4.0) == pytest.approx(1.0)  # 2m / D
    assert P.decay_time(m, 0.0) == math.inf
    assert P.stiffness_from_hertz(m, 3.0) == pytest.approx(m * (6 * math.pi) ** 2)
    # one frequency, every mass: the same period
    for mass in (0.01, 1.0, 70.0):
        assert P.natural_period(mass, P.stiffness_from_hertz(mass, 25.0)) == pytest.approx(1 / 25.0)


def test_regimes_and_characteristic_times():
    m, k = 1.0, 100.0  # w = 10 rad/s, critical D = 20
    assert P.regime(m, k, 0.0) == "underdamped"
    assert P.regime(m, k, 10.0) == "underdamped"
    assert P.regime(m, k) == "critically damped"  # None: critical
    assert P.regime(m, k, 20.0) == "critically damped"
    assert P.regime(m, k, 40.0) == "overdamped"
    assert P.characteristic_times(m, k, 10.0) == pytest.approx({"period": 2 * math.pi / 10, "decay": 0.2})
    assert P.characteristic_times(m, k, 20.0) == pytest.approx({"decay": 0.1})  # 2m/D = 1/w
    over = P.characteristic_times(m, k, 40.0)
    # exact roots of m s^2 + D s + K: rates 20 -+ sqrt(300); their product K/m, sum D/m
    assert 1 / over["slow decay"] == pytest.approx(20 - math.sqrt(300))
    assert 1 / over["fast decay"] == pytest.approx(20 + math.sqrt(300))
    # heavily overdamped: close to seed 002's D/K and m/D
    heavy = P.characteristic_times(m, k, 2000.0)
    assert heavy["slow decay"] == pytest.approx(2000.0 / k, rel=1e-3)
    assert heavy["fast decay"] == pytest.approx(m / 2000.0, rel=1e-3)


def test_smallest_time_is_continuous_through_critical_damping():
    m, k = 1.0, 100.0
    near = [P.smallest_time(m, k, zeta * 20.0) for zeta in (0.999, 1.0, 1.001)]
    assert near == pytest.approx([0.1, 0.1, 0.1], rel=0.05)
    assert P.smallest_time(m, k, 0.0) == pytest.approx(2 * math.pi / 10)  # undamped: the period


@pytest.mark.parametrize("zeta", [0.0, 0.1, 0.3, 1.0, 3.0])
def test_stability_limit_against_the_integrated_model(zeta):
    # Just inside the limit the step map stays bounded; just outside it grows.
    m, k = 1.0, 100.0
    d = zeta * P.critical_damping(m, k)
    limit = P.stability_limit(m, k, d)
    inside = symplectic_euler_1d(m, k, d, 0.98 * limit, 300)
    outside = symplectic_euler_1d(m, k, d, 1.02 * limit, 300)
    assert np.abs(inside).max() < 10.0
    assert np.abs(outside[-50:]).max() > 1e3
    if zeta == 0.0:
        assert limit == pytest.approx(2 / 10.0)           # 2 / w
    if zeta == 1.0:
        assert limit == pytest.approx((2 * math.sqrt(2) - 2) / 10.0)  # 0.83 / w


def exact_release(m, k, d, t):
    """x(t) of m x'' = -k x - d x' from x = 1 at rest."""
    w = math.sqrt(k / m)
    zeta = d / P.critical_damping(m, k)
    if abs(zeta - 1.0) < 1e-9:
        return (1 + w * t) * np.exp(-w * t)
    if zeta < 1.0:
        wd = w * math.sqrt(1 - zeta ** 2)
        return np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta * w / wd * np.sin(wd * t))
    r_slow, r_fast = (-d + math.sqrt(d * d - 4 * m * k)) / (2 * m), (-d - math.sqrt(d * d - 4 * m * k)) / (2 * m)
    a = -r_fast / (r_slow - r_fast)
    return a * np.exp(r_slow * t) + (1 - a) * np.exp(r_fast * t)


@pytest.mark.parametrize("zeta", [0.0, 0.05, 1 / (2 * math.pi), 0.5, 1.0, 2.0, 10.0])
def test_recommended_dt_is_well_inside_the_stability_limit(zeta):
    # At least 2.7x inside the explicit limit whatever the damping (the least margin is at
    # zeta = 1/2pi, where the period and the decay time are equal); integrated at that dt,
    # a release from x = 1 stays within its energy (symplectic Euler's modified energy:
    # amplitude <= 1.05 undamped) and decays as the exact solution does.
    m, k = 1.0, 100.0
    d = zeta * P.critical_damping(m, k)
    dt = P.recommended_dt(m, k, d)
    assert dt == pytest.approx(0.1 * P.smallest_time(m, k, d))
    assert P.stability_limit(m, k, d) >= 2.7 * dt
    steps = int(5 * max(P.characteristic_times(m, k, d).values()) / dt) if zeta > 0 else 200
    numeric = symplectic_euler_1d(m, k, d, dt, steps)
    assert np.abs(numeric).max() <= 1.06
    tail = slice(steps - steps // 4, steps)
    exact = exact_release(m, k, d, dt * np.arange(1, steps + 1))
    assert np.abs(numeric[tail]).max() <= 1.5 * np.abs(exact[tail]).max() + 1e-3


def test_recommended_dt_fraction():
    assert P.recommended_dt(1.0, 100.0, fraction=0.05) == pytest.approx(0.05 * 0.1)
    with pytest.raises(ValueError, match="fraction"):
        P.recommended_dt(1.0, 100.0, fraction=0.0)


def test_contact_summary():
    c = P.contact(0.5, 2e4)
    assert c.regime == "critically damped"
    assert c.damping == pytest.approx(c.critical_damping) == pytest.approx(200.0)
    assert c.damping_ratio == pytest.approx(1.0)
    assert c.natural_period == pytest.approx(2 * math.pi * 0.005)
    assert c.natural_frequency == pytest.approx(1 / c.natural_period)
    assert c.smallest_time == pytest.approx(0.005)
    assert c.recommended_dt == pytest.approx(0.0005)
    text = str(c)
    assert "critically damped" in text and "recommended dt 0.0005 s" in text
    # the penalty solver reports the same numbers for its particles
    solver = tc.PenaltySolver(hertz=1 / c.natural_period)
    assert solver.contact_params(0.5).recommended_dt == pytest.approx(c.recommended_dt)
    assert solver.contact_params(0.5).stiffness == pytest.approx(2e4)


@pytest.mark.parametrize("call, name", [
    (lambda: P.critical_damping(0.0, 1.0), "mass"),
    (lambda: P.critical_damping(1.0, -1.0), "stiffness"),
    (lambda: P.damping_ratio(1.0, 1.0, -1.0), "damping"),
    (lambda: P.natural_period(float("nan"), 1.0), "mass"),
    (lambda: P.decay_time(1.0, -0.1), "damping"),
    (lambda: P.stiffness_from_hertz(1.0, 0.0), "hertz"),
    (lambda: P.damping_from_ratio(1.0, 1.0, -1.0), "damping_ratio"),
    (lambda: P.contact(1.0, 0.0), "stiffness"),
    (lambda: P.regime(-1.0, 1.0), "mass"),
])
def test_bad_arguments_name_themselves(call, name):
    with pytest.raises(ValueError, match=name):
        call()
