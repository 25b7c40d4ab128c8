"""Spinning particles (PenaltySolver(spin=True)) against closed-form rigid-sphere answers.

A solid sphere (I = 2/5 m r^2) on an incline of angle theta rolls without slipping at
a = 5/7 g sin(theta) while mu_s >= 2/7 tan(theta), and slides at g (sin - mu cos) with its
spin growing at 5/2 mu g cos / r below that; rolling resistance mu_r (a torque of at most
mu_r r |f_n|) holds it while tan(theta) <= mu_r and otherwise leaves
a = 5/7 g (sin - mu_r cos); on a flat floor it brakes a rolling sphere at 5/7 mu_r g. A
sphere thrown along a floor without spin slides, spins up and rolls on at 5/7 of its speed;
one set on a belt moving at u ends rolling at 2/7 u. The same laws hold between two
particles (DEM pairs), where a particle rolls over a much larger one, and momentum is kept.
Measured errors are in the comments.
"""

import numpy as np
import pytest

import tai_coll as tc
from conftest import DOWNHILL, FLOOR, G, THETA, dem_scene, on_incline, tilted_gravity

R = 0.02
K = 1e5  # N/m, m = 1 kg


def spinning_scene(dt=1 / 2000, substeps=20, gravity=(0.0, -G, 0.0), **solver):
    solver.setdefault("stiffness", K)
    return tc.Scene(gravity=gravity, dt=dt, substeps=substeps, solver=tc.PenaltySolver(spin=True, **solver))


def incline(**material):
    """conftest's 30 degree incline, the particle at its resting depth."""
    scene = spinning_scene()
    start = on_incline(scene, tc.Material(**material), R, depth=G * np.cos(THETA) / K, mass=1.0)
    return scene, start


def spin_about_axis(scene, axis=(0.0, 0.0, 1.0)):
    return scene.angular_velocities()[0].dot(axis)


@pytest.mark.parametrize("mu", [0.5, 0.2])
def test_sphere_rolls_down_an_incline_at_five_sevenths_g_sin(mu):
    # mu >= 2/7 tan 30 = 0.165: no slip. Measured: velocity exact to round-off, distance
    # +0.1 % (symplectic Euler), spin = v / r to round-off.
    scene, start = incline(friction=mu)
    scene.step(50)
    t = scene.time
    a = 5.0 / 7.0 * G * np.sin(THETA)
    v = scene.velocities()[0].dot(DOWNHILL)
    assert v == pytest.approx(a * t, rel=1e-6)
    assert (scene.positions()[0] - start).dot(DOWNHILL) == pytest.approx(0.5 * a * t * t, rel=0.01)
    assert spin_about_axis(scene) == pytest.approx(v / R, rel=1e-6)  # rolls: contact point at rest


def test_sphere_slides_and_spins_up_below_two_sevenths_tan():
    # mu = 0.1 < 2/7 tan 30: kinetic friction mu m g cos acts at the contact point, the centre
    # accelerates at g (sin - mu cos) and the spin grows at 5/2 mu g cos / r. Measured: exact.
    mu = 0.1
    scene, _ = incline(friction=mu)
    scene.step(50)
    t = scene.time
    assert scene.velocities()[0].dot(DOWNHILL) == pytest.approx(G * (np.sin(THETA) - mu * np.cos(THETA)) * t,
                                                                 rel=1e-6)
    assert spin_about_axis(scene) == pytest.approx(2.5 * mu * G * np.cos(THETA) / R * t, rel=1e-6)


def test_rolling_friction_holds_a_sphere_where_tan_theta_is_below_it():
    # mu_r = 0.7 > tan 30 = 0.577 (and mu_s = 0.8): stuck, the force and the torque that stop
    # the sphere are within their limits. Measured: no motion at all.
    scene, start = incline(friction=0.8, rolling_friction=0.7)
    scene.step(50)
    assert np.linalg.norm(scene.positions()[0] - start) < 1e-12
    assert np.linalg.norm(scene.velocities()[0]) < 1e-12
    assert np.linalg.norm(scene.angular_velocities()[0]) < 1e-12


def test_rolling_friction_slows_rolling_down_an_incline():
    # mu_r = 0.2 < tan 30: a = 5/7 g (sin - mu_r cos). Measured: -0.06 % (the torque lags the
    # friction by a substep).
    mu_r = 0.2
    scene, _ = incline(friction=0.8, rolling_friction=mu_r)
    scene.step(50)
    a = 5.0 / 7.0 * G * (np.sin(THETA) - mu_r * np.cos(THETA))
    assert scene.velocities()[0].dot(DOWNHILL) == pytest.approx(a * scene.time, rel=0.005)


def floor_scene(velocity, spin, *, floor_velocity=None, **material):
    scene = spinning_scene(dt=1 / 4000)
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(**material), velocity=floor_velocity)
    scene.add_particles(positions=[(0.0, R - G / K, 0.0)], velocities=[velocity], radius=R, mass=1.0)
    scene.set_angular_velocities([spin])
    return scene


def test_sphere_thrown_without_spin_rolls_on_at_five_sevenths_of_its_speed():
    # v0 = 2 m/s along x, no spin, mu = 0.3: slides until v = 5/7 v0 at t = 2 v0 / (7 mu g)
    # = 0.19 s, then rolls (spin -v / r about z). Measured: exact to round-off.
    v0, mu = 2.0, 0.3
    scene = floor_scene((v0, 0.0, 0.0), (0.0, 0.0, 0.0), friction=mu)
    scene.step(15)  # 0.075 s: still sliding
    t = scene.time
    assert scene.velocities()[0, 0] == pytest.approx(v0 - mu * G * t, rel=1e-6)
    scene.step(35)  # 0.25 s
    v = scene.velocities()[0, 0]
    assert v == pytest.approx(5.0 / 7.0 * v0, rel=1e-6)
    assert spin_about_axis(scene) == pytest.approx(-v / R, rel=1e-6)


def test_rolling_resistance_brakes_a_rolling_sphere_at_five_sevenths_mu_r_g():
    # Rolling at 1 m/s on a floor with mu_r = 0.05: a = -5/7 mu_r g. Measured: +0.02 %
    # (the torque lags the friction by a substep).
    v0, mu_r = 1.0, 0.05
    scene = floor_scene((v0, 0.0, 0.0), (0.0, 0.0, -v0 / R), friction=0.5, rolling_friction=mu_r)
    scene.step(40)
    t = scene.time
    v = scene.velocities()[0, 0]
    assert (v0 - v) / t == pytest.approx(5.0 / 7.0 * mu_r * G, rel=0.005)
    assert spin_about_axis(scene) == pytest.approx(-v / R, rel=1e-3)


def test_sphere_set_on_a_moving_belt_ends_rolling_at_two_sevenths_of_its_speed():
    # Friction acts on the velocity relative to the surface: a sphere at rest on a belt
    # moving at u = 1 m/s slides until its contact point moves with the belt, then rolls
    # along at 2/7 u (its angular momentum about the contact line is kept). Measured: exact.
    u = 1.0
    scene = floor_scene((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), floor_velocity=(u, 0.0, 0.0), friction=0.4)
    scene.step(40)  # 0.2 s, rolling from u / (3.5 mu g) = 0.073 s
    v = scene.velocities()[0, 0]
    assert v == pytest.approx(2.0 / 7.0 * u, rel=1e-6)
    assert v + spin_about_axis(scene) * R == pytest.approx(u, rel=1e-6)  # contact point moves with the belt


def test_spin_survives_growth_and_is_zero_for_new_particles():
    scene = spinning_scene(gravity=(0.0, 0.0, 0.0))
    scene.add_particles(positions=[(0.0, 1.0, 0.0)], radius=R)
    scene.set_angular_velocities([(1.0, 2.0, 3.0)])
    scene.add_particles(positions=np.column_stack([np.arange(2000), np.full(2000, 2.0), np.zeros(2000)]), radius=R)
    scene.step()  # free flight: spin kept
    w = scene.angular_velocities()
    assert np.allclose(w[0], (1.0, 2.0, 3.0)) and not w[1:].any()


def test_spin_needs_a_rotating_solver_and_valid_arguments():
    scene = tc.Scene(dt=1e-3)
    scene.add_particles(positions=[(0.0, 1.0, 0.0)])
    assert not scene.angular_velocities().any()
    with pytest.raises(ValueError, match="angular_velocities"):
        scene.set_angular_velocities([(0.0, 0.0, 1.0)])
    with pytest.raises(TypeError, match="spin"):
        tc.PenaltySolver(hertz=100.0, spin="yes")
    with pytest.raises(ValueError, match="rolling_friction"):
        tc.Material(rolling_friction=-0.1)
    spinning = spinning_scene()
    spinning.add_particles(positions=[(0.0, 1.0, 0.0)])
    with pytest.raises(ValueError, match="angular_velocities"):
        spinning.set_angular_velocities([(0.0, 0.0, 1.0), (0.0, 0.0, 1.0)])
    assert "spin=True" in repr(spinning.solver)


# ---------------------------------------------------------------- between particles (DEM pairs)
BIG = 10.0  # radius (m) of the particle the small one rolls on: its top is flat within 0.1 %


def rolling_on_a_big_particle(springs, mu, mu_r, *, theta=np.radians(20.0), small_first=False, skin=0.0):
    """A particle B (1 kg, r = R) resting on top of A (1e6 kg, radius 10 m) that rests on a
    floor, gravity tilted by theta along x: over the 10 mm B travels, A's top is an incline
    of theta. DEM pairs at 200 Hz, critically damped; the floor holds A (mu_r = 1). skin:
    the pairs' Verlet lists (m)."""
    hertz = 200.0
    scene = spinning_scene(dt=5e-5, substeps=100, gravity=tilted_gravity(theta), stiffness=None, hertz=hertz)
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(friction=1.0, rolling_friction=1.0))
    sink = G * np.cos(theta) / (2 * np.pi * hertz) ** 2
    x, mass, radius = np.array([[0.0, BIG - sink, 0.0], [0.0, 2 * BIG + R - sink, 0.0]]), [1e6, 1.0], [BIG, R]
    if small_first:  # B in the first slot: the store's reordering swaps the two
        x, mass, radius = x[::-1], mass[::-1], radius[::-1]
    scene.add_particles(positions=x, mass=mass, radius=radius)
    settings = scene.enable_particle_collisions(material=tc.Material(friction=mu, rolling_friction=mu_r),
                                                tangential_springs=springs, verlet_skin=skin)
    return scene, settings, int(not small_first)


@pytest.mark.parametrize("springs, skin", [(False, 0.0), (True, 0.0), (True, 5e-3)])
@pytest.mark.parametrize("mu_r", [0.0, 0.2])
def test_particle_rolls_over_another_at_the_rolling_incline_law(springs, skin, mu_r):
    # mu = 0.5 > 2/7 tan 20: B rolls over A with a = 5/7 g (sin - mu_r cos) (mu_r < tan 20).
    # Measured over 0.04 -> 0.1 s, with and without springs: mu_r = 0: +0.16 %; mu_r = 0.2:
    # +0.41 %; the contact point's slip within 0.4 % of the speed. skin: the DEM kernel on
    # Verlet lists (5 mm: rebuilt every 2.5 mm B travels), the same figures.
    theta = np.radians(20.0)
    scene, settings, b = rolling_on_a_big_particle(springs, 0.5, mu_r, skin=skin)
    scene.step(8)
    v0, t0 = scene.velocities()[b, 0], scene.time
    scene.step(12)
    a = (scene.velocities()[b, 0] - v0) / (scene.time - t0)
    assert a == pytest.approx(5.0 / 7.0 * G * (np.sin(theta) - mu_r * np.cos(theta)), rel=0.03)
    v = scene.velocities()[b, 0]
    assert -scene.angular_velocities()[b, 2] * R == pytest.approx(v, rel=0.02)  # rolls (A barely turns)
    if skin:
        assert settings.list_builds >= 3


@pytest.mark.parametrize("small_first", [False, True])
def test_rolling_spring_holds_a_particle_on_another(small_first):
    # mu_r = 0.5 > tan 20: with springs the contact holds still, tangentially and in rolling
    # (B's offset stays within 1e-3 of itself, speed and spin below 1e-9). small_first: the
    # store's reordering swaps the two every 8 substeps, the springs and spins move with them.
    scene, settings, b = rolling_on_a_big_particle(True, 0.5, 0.5, small_first=small_first)
    scene.step(20)  # 0.1 s: settled
    early = scene.positions()[b, 0]
    scene.step(20)
    late = scene.positions()[b, 0]
    assert abs(late - early) < 1e-3 * abs(early)
    assert np.abs(scene.velocities()[b]).max() < 1e-9 and np.abs(scene.angular_velocities()).max() < 1e-9
    assert settings.history_overflow == 0


def test_spinning_pair_conserves_momentum():
    # A glancing contact of spinning particles (masses 1 and 3, radii 0.05 and 0.04), no
    # gravity, springs and rolling resistance on: the forces are equal and opposite (momentum
    # to round-off), the tangential force acts at the middle of the overlap, whose levers add
    # up to the distance, and the rolling torques are opposite: angular momentum about the
    # origin (orbital plus 2/5 m r^2 w) is kept to round-off too.
    scene = dem_scene(hertz=100.0, damping_ratio=0.3, spin=True,
                      material=tc.Material(friction=0.6, rolling_friction=0.1), springs=True)
    v0 = np.array([[1.0, 0.0, 0.2], [-0.3, 0.1, 0.0]])
    w0 = np.array([[0.0, 0.0, 20.0], [5.0, 0.0, -10.0]])
    mass, radius = np.array([1.0, 3.0]), np.array([0.05, 0.04])
    scene.add_particles(positions=[[-0.06, 0.04, 0.0], [0.03, 0.0, 0.01]], velocities=v0, mass=mass, radius=radius)
    scene.set_angular_velocities(w0)
    x0 = scene.positions()
    scene.step(150)
    x, v, w = scene.positions(), scene.velocities(), scene.angular_velocities()
    assert np.allclose(mass @ v, mass @ v0, atol=1e-12)
    assert scene.particle_overlap()["pairs"] == 0
    inertia = (0.4 * mass * radius ** 2)[:, None]

    def angular_momentum(x, v, w):
        return (mass[:, None] * np.cross(x, v)).sum(axis=0) + (inertia * w).sum(axis=0)

    before, after = angular_momentum(x0, v0, w0), angular_momentum(x, v, w)
    assert np.linalg.norm(after - before) < 1e-12 * np.linalg.norm(before)
    assert np.abs(w - w0).max() > 1.0  # the contact turned them
