"""DEM pairs (tc.PenaltySolver with particle collisions) against closed forms: a spring on
the overlap with the pair's reduced mass, the damping ratio's rebound, the forces on a
crowded particle by brute force, and tangential springs holding a contact where regularised
friction creeps."""

import math

import numpy as np
import pytest

import tai_coll as tc
from conftest import FLOOR, G, crowded_particle, dem_scene, spring_law_velocities, tilted_gravity


# ---------------------------------------------------------------- normal springs
def test_dem_pair_undamped_is_elastic_and_conserves_momentum():
    # Penalty solver: a spring on the overlap with the pair's reduced mass. Undamped, equal
    # masses exchange velocities; masses 1 and 3 keep the total momentum to round-off.
    scene = dem_scene(stiffness=2e4, damping=0.0)
    scene.add_particles(positions=[[-0.06, 0, 0], [0.06, 0, 0]], velocities=[[1, 0, 0], [-1, 0, 0]],
                        mass=np.array([1.0, 3.0]), radius=0.05)
    scene.step(300)
    v = scene.velocities()
    assert np.allclose(1.0 * v[0] + 3.0 * v[1], [-2.0, 0, 0], atol=1e-12)
    # elastic: the relative speed is restored (e = 1) within the integrator's error
    assert (v[1, 0] - v[0, 0]) == pytest.approx(2.0, rel=0.01)
    assert scene.particle_overlap()["pairs"] == 0


def push_only_restitution(zeta: float) -> float:
    """Rebound of the damped oscillator x'' = -w^2 x - 2 zeta w x' (x: overlap) that can only
    push: x(t) = (v0/wd) exp(-zeta w t) sin(wd t) until the force w x + 2 zeta x' reaches zero
    (bisection on that closed form), then free flight at -x'(t*)."""
    w = 1.0
    wd = w * np.sqrt(1 - zeta ** 2)

    def x(t):
        return np.exp(-zeta * w * t) * np.sin(wd * t) / wd

    def xdot(t):
        return np.exp(-zeta * w * t) * (np.cos(wd * t) - zeta * w / wd * np.sin(wd * t))

    lo, hi = np.pi / (2 * wd), np.pi / wd  # the force changes sign between the turn and x = 0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if w * x(mid) + 2 * zeta * xdot(mid) > 0:
            lo = mid
        else:
            hi = mid
    return -xdot(lo)


def test_dem_pair_damping_ratio_sets_the_rebound():
    # Damped pair contact, push-only: the rebound follows the closed form above (it is a
    # little above the linear oscillator's exp(-zeta pi / sqrt(1 - zeta^2)), since a
    # push-only contact cannot brake the particles as they separate).
    zeta = 0.2
    scene = dem_scene(hertz=40.0, damping_ratio=zeta)
    scene.add_particles(positions=[[-0.051, 0, 0], [0.051, 0, 0]], velocities=[[0.5, 0, 0], [-0.5, 0, 0]],
                        radius=0.05)
    scene.step(400)
    v = scene.velocities()
    e = push_only_restitution(zeta)
    assert np.exp(-zeta * np.pi / np.sqrt(1 - zeta ** 2)) < e
    assert (v[1, 0] - v[0, 0]) / 1.0 == pytest.approx(e, rel=0.02)
    assert np.allclose(v.sum(axis=0), 0.0, atol=1e-12)


@pytest.mark.parametrize("springs", [False, True])
def test_dem_forces_on_a_crowded_particle_match_the_spring_law(springs):
    # A big particle touched by 40 small ones (more than the kernel's batch of touching
    # neighbours) and a few small ones touching each other, all at rest, no gravity: after one
    # substep every velocity is dt/m times the sum of k overlap n over its contacts (the
    # damper and friction see zero relative velocity), with k = stiffness as given. With
    # tangential springs (new contacts: zero springs) the big one keeps 12 of its 40 and
    # counts the other 28 as overflow.
    k, dt = 3e3, 1e-5
    x, radius, mass = crowded_particle(40, 5, offset=(3.0, -2.0, 1.0))
    scene = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=dt, substeps=1,
                     solver=tc.PenaltySolver(stiffness=k, damping=0.0))
    # (max_push_speed=inf: the law on the overlap these particles are placed with)
    settings = scene.enable_particle_collisions(material=tc.Material(friction=0.5), tangential_springs=springs,
                                                max_push_speed=math.inf)
    scene.add_particles(positions=x, radius=radius, mass=mass)
    scene.step(1)
    expected, touching = spring_law_velocities(x, radius, mass, k, dt)
    assert touching[0].sum() == 40 and touching[1:, 1:].any()
    assert np.allclose(scene.velocities(), expected, rtol=1e-4, atol=1e-9 * np.abs(expected).max())
    assert np.allclose((mass[:, None] * scene.velocities()).sum(axis=0), 0.0, atol=1e-12)
    assert settings.history_overflow == (40 - 12 if springs else 0)


# ---------------------------------------------------------------- friction: regularised and tangential springs
def sphere_incline(theta_deg, mu, springs, *, top_first=False):
    """A particle B (1 kg) resting on a heavy one A (1000 kg) on a floor, gravity tilted by
    theta along x: the contact A-B is an incline of angle theta. DEM pairs, 200 Hz per pair
    (k = m_pair (2 pi 200)^2), critically damped; the floor holds A by friction 2."""
    th = np.radians(theta_deg)
    scene = tc.Scene(gravity=tilted_gravity(th), dt=1e-4, substeps=10,
                     solver=tc.PenaltySolver(hertz=200.0, damping_ratio=1.0))
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(friction=2.0))
    settings = scene.enable_particle_collisions(material=tc.Material(friction=mu), tangential_springs=springs)
    r = 0.05
    x, mass = np.array([[0, r, 0], [0, 3 * r, 0]]), np.array([1000.0, 1.0])
    if top_first:  # B in the first slot: the store's reordering by cell swaps the two
        x, mass = x[::-1], mass[::-1]
    scene.add_particles(positions=x, radius=r, mass=mass)
    a, b = (1, 0) if top_first else (0, 1)
    return scene, settings, a, b


def slip(scene, a, b):
    x, v = scene.positions(), scene.velocities()
    return x[b, 0] - x[a, 0], v[b, 0] - v[a, 0]


@pytest.mark.parametrize("top_first", [False, True])
def test_tangential_spring_holds_a_contact_still_where_regularised_friction_creeps(top_first):
    # mu = 0.5 > tan 20 deg: the contact holds. With a spring it stretches to
    # m g sin(theta) / k_t (k_t = 2/7 k_n) and stays there (B's offset from A also holds the
    # tenths of a micrometre the contact turned while B settled onto A, within 5 %); the
    # regularised friction cancels
    # the tangential velocity every substep after the load has moved it for one, so the
    # contact creeps at g sin(theta) dt. top_first: the store's reordering swaps the two
    # particles every 8 substeps, and the springs must move with them.
    theta, dt = 20.0, 1e-4
    load = G * np.sin(np.radians(theta))
    k_t = 2.0 / 7.0 * (1000.0 / 1001.0) * (2 * np.pi * 200.0) ** 2  # per unit mass of B
    scene, settings, a, b = sphere_incline(theta, 0.5, True, top_first=top_first)
    scene.step(60)  # 0.06 s
    early, _ = slip(scene, a, b)
    scene.step(100)
    late, speed = slip(scene, a, b)
    assert early == pytest.approx(load / k_t, rel=0.05)
    assert abs(late - early) < 1e-3 * early and abs(speed) < 1e-6
    assert settings.history_overflow == 0
    scene, _, a, b = sphere_incline(theta, 0.5, False, top_first=top_first)
    scene.step(60)
    early, _ = slip(scene, a, b)
    scene.step(100)
    late, _ = slip(scene, a, b)
    assert (late - early) / 0.1 == pytest.approx(load * dt, rel=0.05)


@pytest.mark.parametrize("springs", [True, False])
def test_contact_beyond_its_friction_slides_at_the_incline_law(springs):
    # mu = 0.2 < tan 20 deg: B slides off A with a = g (sin - mu cos) (A is 1000 times heavier;
    # after 0.02 s B has moved 0.3 mm, 0.6 % of its radius along A's surface).
    theta, mu = 20.0, 0.2
    th = np.radians(theta)
    expected = G * (np.sin(th) - mu * np.cos(th))
    scene, _, a, b = sphere_incline(theta, mu, springs)
    scene.step(20)
    _, speed = slip(scene, a, b)
    assert speed / scene.time == pytest.approx(expected, rel=0.02)


def test_tangential_springs_conserve_momentum():
    # A glancing DEM contact of masses 1 and 3 with friction by springs, no gravity: each
    # particle keeps the pair's spring, both springs exactly opposite, so are the forces.
    scene = dem_scene(hertz=100.0, damping_ratio=0.3, material=tc.Material(friction=0.6), springs=True)
    v0 = np.array([[1.0, 0.0, 0.2], [-0.3, 0.1, 0.0]])
    mass = np.array([1.0, 3.0])
    scene.add_particles(positions=[[-0.06, 0.04, 0.0], [0.04, 0.0, 0.01]], velocities=v0, mass=mass, radius=0.05)
    scene.step(150)
    v = scene.velocities()
    assert np.allclose(mass @ v, mass @ v0, atol=1e-12)
    assert scene.particle_overlap()["pairs"] == 0
    tangential = v[0] - v0[0]
    assert np.linalg.norm(tangential - tangential.dot([1, 0, 0]) * np.array([1, 0, 0])) > 1e-3  # friction acted
