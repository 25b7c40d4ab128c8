"""Closed-form physics of whole scenes (docs/physics.md 2 and 3), on the CPU in f64.

Every test compares a scene against a number worked out by hand: bounce apex e^2 h, the
bouncing-block problem, a block on an incline, sliding stop distance, moving and rotating
colliders, resting on every collider kind with every scheme (at its radius, at any dt), thin
walls, the micro-collision guarantee, the last-resort repulsion and determinism. Tolerances
are a few percent at most and are met with margin; the measured errors are in the comments.
(Colliders faster than the particles: test_fast_paddle.py.)
"""

import numpy as np
import pytest

import tai_coll as tc
from conftest import DOWNHILL, FLOOR, G, INCLINE_N, THETA, on_incline

R = 0.01  # particle radius used throughout (m)
SCHEMES = ["elastic_contact", "micro", "simple", "exact_time"]
RESTING_SCHEMES = ["elastic_contact", "exact_time"]  # the schemes that solve the bouncing-block problem


def make_scene(scheme="elastic_contact", *, dt=1.0 / 600.0, substeps=10, gravity=(0.0, -G, 0.0), **solver_args):
    return tc.Scene(gravity=gravity, dt=dt, substeps=substeps,
                    solver=tc.ImpulseSolver(scheme=scheme, **solver_args))


def frames_for(scene, seconds):
    return int(round(seconds / scene.frame_time))


# ---------------------------------------------------------------- bounce apex e^2 h
@pytest.mark.parametrize("scheme", ["elastic_contact", "exact_time"])
@pytest.mark.parametrize("e", [0.3, 0.5, 0.8])
def test_bounce_apex_is_e_squared_h(scheme, e):
    # Drop from h (particle bottom above the plane): v_impact = sqrt(2 g h), rebound e v_impact,
    # apex (e v)^2 / 2g = e^2 h. Measured error <= 0.16 % for both schemes at dt = 1/6000.
    h = 0.5
    scene = make_scene(scheme, dt=1.0 / 6000.0, substeps=10)
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(restitution=e, friction=0.0))
    scene.add_particles(positions=[[0.0, h + R, 0.0]], radius=R)
    t_fall = np.sqrt(2 * h / G)
    bottoms = []
    for _ in range(frames_for(scene, t_fall * (1 + e) + 0.05)):
        scene.step()
        bottoms.append(scene.positions()[0, 1] - R)
    bottoms = np.array(bottoms)
    impact = int(np.argmin(bottoms[: frames_for(scene, t_fall) + 5]))
    apex = bottoms[impact:].max()
    assert apex == pytest.approx(e * e * h, rel=0.01)
    assert bottoms.min() > -1e-3 * R  # never below the plane (beyond the slop)


# ---------------------------------------------------------------- bouncing-block problem
@pytest.mark.parametrize("scheme", RESTING_SCHEMES)
def test_resting_particle_stays_at_rest_with_high_restitution(scheme):
    # docs/physics.md 3, Implementation 3: e = 0.9, resting on the floor, stays exactly at rest.
    scene = make_scene(scheme)
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(restitution=0.9, friction=0.3))
    scene.add_particles(positions=[[0.0, R, 0.0]], radius=R)
    max_speed = max_dy = 0.0
    for _ in range(frames_for(scene, 2.0)):
        scene.step()
        max_speed = max(max_speed, np.linalg.norm(scene.velocities()[0]))
        max_dy = max(max_dy, abs(scene.positions()[0, 1] - R))
    assert max_speed < 1e-6
    assert max_dy < 1e-6
    assert scene.stats()["failsafe"] == 0 and scene.stats()["repulsion"] == 0


@pytest.mark.parametrize("scheme", ["simple", "micro"])
def test_simple_and_micro_jitter_on_resting_contact(scheme):
    # The contrast (seed 000, "bouncing block problem"): the law on the average velocity with
    # e = 0.9 bounces the particle on the speed gravity gave it in one substep. Measured:
    # |v| up to 0.15 m/s and 1.3 mm hops at dt = 1/600; both shrink with dt.
    scene = make_scene(scheme)
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(restitution=0.9, friction=0.3))
    scene.add_particles(positions=[[0.0, R, 0.0]], radius=R)
    max_speed = 0.0
    heights = []
    for _ in range(frames_for(scene, 2.0)):
        scene.step()
        max_speed = max(max_speed, np.linalg.norm(scene.velocities()[0]))
        heights.append(scene.positions()[0, 1])
    assert max_speed > 1e-2
    assert max(heights) - R > 1e-4
    assert min(heights) > R - 1e-3 * R  # it jitters, but above the floor


# ---------------------------------------------------------------- incline (conftest's: 30 degrees)
def incline_scene(scheme, mu, e=0.5, dt=1.0 / 600.0):
    scene = make_scene(scheme, dt=dt)
    on_incline(scene, tc.Material(restitution=e, friction=mu), R)  # touching it, at R * INCLINE_N
    return scene


@pytest.mark.parametrize("scheme", RESTING_SCHEMES)
def test_incline_static_friction_holds(scheme):
    # mu = 0.7 > tan 30 = 0.577: static; measured displacement exactly 0.
    scene = incline_scene(scheme, mu=0.7)
    scene.step(frames_for(scene, 1.0))
    assert np.linalg.norm(scene.positions()[0] - R * INCLINE_N) < 1e-6
    assert np.linalg.norm(scene.velocities()[0]) < 1e-6


def test_incline_static_friction_holds_micro_inelastic():
    # With e = 0 the micro-collision scheme has nothing to bounce on and holds exactly too.
    scene = incline_scene("micro", mu=0.7, e=0.0)
    scene.step(frames_for(scene, 1.0))
    assert np.linalg.norm(scene.positions()[0] - R * INCLINE_N) < 1e-6


def test_incline_micro_collisions_creep_first_order():
    # Seed 001's "block on incline" example: with e > 0 micro-collisions hop, and in each
    # hop gravity's downhill part moves the particle before static friction stops it on
    # landing. The creep is an O(dt) artefact of the scheme: measured 4.0 mm over 0.5 s at
    # dt = 1/600 and 0.81 mm at dt = 1/3000 (ratio 4.93 for a dt ratio of 5).
    creep = []
    for dt in (1.0 / 600.0, 1.0 / 3000.0):
        scene = incline_scene("micro", mu=0.7, dt=dt)
        scene.step(frames_for(scene, 0.5))
        creep.append((scene.positions()[0] - R * INCLINE_N) @ DOWNHILL)
    assert 0 < creep[0] < 0.01
    assert creep[0] / creep[1] == pytest.approx(5.0, rel=0.1)


@pytest.mark.parametrize("scheme", ["elastic_contact", "micro", "exact_time"])
def test_incline_kinetic_friction_acceleration(scheme):
    # mu = 0.2 < tan 30: slides with a = g (sin - mu cos) = 3.2059 m/s^2. Fit from the
    # displacement over 0.5 s: measured +0.33 % (symplectic Euler's dt/T) for all schemes.
    mu = 0.2
    scene = incline_scene(scheme, mu=mu)
    scene.step(frames_for(scene, 0.5))
    x = scene.positions()[0]
    a_fit = 2.0 * ((x - R * INCLINE_N) @ DOWNHILL) / scene.time ** 2
    assert a_fit == pytest.approx(G * (np.sin(THETA) - mu * np.cos(THETA)), rel=0.02)
    assert abs(x @ INCLINE_N - R) < 0.02 * R  # still on the plane


# ---------------------------------------------------------------- sliding stop distance
@pytest.mark.parametrize("scheme", SCHEMES)
def test_sliding_stop_distance(scheme):
    # v0 = 2 m/s, mu = 0.4: stops after v0^2 / (2 mu g) = 0.5097 m; measured -0.33 %.
    v0, mu = 2.0, 0.4
    scene = make_scene(scheme)
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(restitution=0.0, friction=mu))
    scene.add_particles(positions=[[0.0, R, 0.0]], velocities=[[v0, 0.0, 0.0]], radius=R)
    scene.step(frames_for(scene, 0.8))  # stops at v0 / (mu g) = 0.51 s
    assert scene.positions()[0, 0] == pytest.approx(v0 ** 2 / (2 * mu * G), rel=0.02)
    assert np.linalg.norm(scene.velocities()[0]) < 1e-9


@pytest.mark.parametrize("scheme", SCHEMES)
def test_conveyor_belt_friction_spin_up(scheme):
    # A floor whose surface moves at u along x (its plane is unchanged by the motion): kinetic
    # friction accelerates the particle at mu g until it rides at u, after t_s = u / (mu g).
    # Distance after T: u T - u t_s / 2 = 0.8981 m; measured +0.09 %.
    u, mu, T = 1.0, 0.5, 1.0
    scene = make_scene(scheme)
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(restitution=0.0, friction=mu), velocity=(u, 0, 0))
    scene.add_particles(positions=[[0.0, R, 0.0]], radius=R)
    scene.step(frames_for(scene, T))
    t_s = u / (mu * G)
    assert scene.positions()[0, 0] == pytest.approx(u * T - u * t_s / 2, rel=0.01)
    np.testing.assert_allclose(scene.velocities()[0], [u, 0, 0], atol=1e-9)


# ---------------------------------------------------------------- moving colliders
@pytest.mark.parametrize("how", ["velocity", "motion"])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_moving_sphere_kicks_resting_particle_to_2u(scheme, how):
    # A ball moving at u hits a particle at rest, e = 1, no friction, no gravity: the
    # relative-velocity law (docs/physics.md 2) sends it off at 2u. Measured exact (to 1e-12)
    # for elastic_contact, micro and simple.
    u = 1.0
    scene = make_scene(scheme, gravity=(0, 0, 0))
    kinematic = (dict(velocity=(u, 0, 0)) if how == "velocity"
                 else dict(motion=lambda t: (np.array([u * t, 0.0, 0.0]), np.eye(3))))
    scene.add_collider(tc.Sphere(center=(0, 0, 0), radius=0.1),
                       material=tc.Material(restitution=1.0, friction=0.0), **kinematic)
    scene.add_particles(positions=[[0.2, 0.0, 0.0]], radius=R)
    scene.step(frames_for(scene, 0.3))  # contact at t = 0.09 s
    np.testing.assert_allclose(scene.velocities()[0], [2 * u, 0, 0], rtol=0, atol=0.02 * 2 * u)
    assert scene.stats()["repulsion"] == 0


@pytest.mark.parametrize("how", ["velocity", "motion"])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_rising_floor_carries_resting_particle(scheme, how):
    # A floor rising at u with e = 0 lifts a resting particle: y = r + u t, v = u.
    u, T = 0.5, 1.0
    scene = make_scene(scheme)
    kinematic = (dict(velocity=(0, u, 0)) if how == "velocity"
                 else dict(motion=lambda t: (np.array([0.0, u * t, 0.0]), np.eye(3))))
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(restitution=0.0, friction=0.5), **kinematic)
    scene.add_particles(positions=[[0.0, R, 0.0]], radius=R)
    scene.step(frames_for(scene, T))
    assert scene.positions()[0, 1] == pytest.approx(R + u * scene.time, rel=0.01)
    np.testing.assert_allclose(scene.velocities()[0], [0, u, 0], rtol=0, atol=0.01 * u)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_resting_on_moving_floor_is_an_ordinary_contact(scheme):
    # Riding a uniformly rising floor is plain resting contact: neither the loop cap's
    # failsafe nor the last-resort repulsion (meant for round-off trouble and penetrations
    # already there at time t) has any business firing.
    scene = make_scene(scheme)
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(restitution=0.0, friction=0.5), velocity=(0, 0.5, 0))
    scene.add_particles(positions=[[0.0, R, 0.0]], radius=R)
    scene.step(frames_for(scene, 1.0))
    stats = scene.stats()
    assert stats["failsafe"] == 0, stats
    assert stats["repulsion"] == 0, stats


# ---------------------------------------------------------------- rotating colliders
@pytest.mark.parametrize("scheme", SCHEMES)
def test_spinning_paddle_imparts_surface_velocity(scheme):
    # A thin box (half height h) spins about z at w through a particle at rest at (X, Y),
    # e = 1, no friction, no gravity. The face touches it at the along-face coordinate
    # s = sqrt(X^2 + Y^2 - (h + r)^2), where w x p has normal component w s: the particle
    # leaves at 2 w s along the face normal n = (-sin th, cos th). Measured (dt = 1/600):
    # speed +0.009 %, direction 0.07 degrees off, for elastic_contact, micro and simple.
    w, X, Y, h = 2.0, 0.4, 0.1, 0.02
    scene = make_scene(scheme, gravity=(0, 0, 0))
    scene.add_collider(tc.Box(center=(0, 0, 0), half_extents=(0.5, h, 0.05)),
                       material=tc.Material(restitution=1.0, friction=0.0), angular_velocity=(0, 0, w))
    scene.add_particles(positions=[[X, Y, 0.0]], radius=R)
    scene.step(frames_for(scene, 0.3))  # contact at th / w = 0.086 s
    s = np.sqrt(X * X + Y * Y - (h + R) ** 2)
    th = np.arctan2(Y, X) - np.arctan2(h + R, s)
    expected = 2 * w * s * np.array([-np.sin(th), np.cos(th), 0.0])
    np.testing.assert_allclose(scene.velocities()[0], expected, rtol=0, atol=0.02 * np.linalg.norm(expected))


@pytest.mark.parametrize("shape", ["cylinder", "box"])
@pytest.mark.parametrize("scheme", ["elastic_contact", "exact_time", "micro"])
def test_turntable_carries_particle_at_surface_velocity(scheme, shape):
    # A particle at rest on a turntable spinning at w (about +y) at radius rho: friction
    # accelerates it at mu g for t_s = w rho / (mu g), then it rides at w x r. After T its
    # angle is w T - w t_s / 2. Measured (all three schemes, both shapes): angle +0.08 %,
    # radius +0.42 % (straight steps drift outward, O(dt)), |v - w x r| 0.34 % of w rho (O(w dt)).
    w, rho, h, mu, T = 2.0, 0.2, 0.05, 0.5, 1.0
    scene = make_scene(scheme)
    collider = (tc.Cylinder(center=(0, 0, 0), radius=0.5, half_height=h) if shape == "cylinder"
                else tc.Box(center=(0, 0, 0), half_extents=(0.5, h, 0.5)))
    scene.add_collider(collider, material=tc.Material(restitution=0.0, friction=mu), angular_velocity=(0, w, 0))
    scene.add_particles(positions=[[rho, h + R, 0.0]], radius=R)
    scene.step(frames_for(scene, T))
    x, v = scene.positions()[0], scene.velocities()[0]
    radial = np.array([x[0], 0.0, x[2]])
    surface_v = np.cross([0.0, w, 0.0], radial)
    angle = np.arctan2(-x[2], x[0])  # +y rotation turns +x toward -z
    t_s = w * rho / (mu * G)
    assert np.linalg.norm(radial) == pytest.approx(rho, rel=0.02)
    assert angle == pytest.approx(w * T - w * t_s / 2, rel=0.02)
    assert np.linalg.norm(v - surface_v) < 0.02 * w * rho
    assert abs(x[1] - (h + R)) < 0.02 * R


# ---------------------------------------------------------------- every collider x every scheme
def _top_shapes():
    # Each shape's top surface passes through y = 0 above the origin.
    return {
        "plane": tc.Plane(**FLOOR),
        "sphere": tc.Sphere(center=(0, -0.5, 0), radius=0.5),
        "box": tc.Box(center=(0, -0.1, 0), half_extents=(0.3, 0.1, 0.3)),
        "cylinder": tc.Cylinder(center=(0, -0.1, 0), radius=0.3, half_height=0.1),
        "capsule": tc.Capsule(center=(0, -0.1, 0), radius=0.1, half_height=0.3, axis=(1, 0, 0)),
    }


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("shape", ["plane", "sphere", "box", "cylinder", "capsule"])
def test_every_collider_holds_dropped_particle(shape, scheme):
    # Dropped 5 cm onto the top, a little off the apex; e = 0.3, mu = 0.5; after 1 s it rests
    # on the surface. Measured phi/r in [1.00000, 1.0022] (elastic_contact hovers up to
    # g dt^2 above: its contact pass zeroes the approach of the whole step); simple and micro
    # keep hopping with |v| < 0.009 m/s (the bouncing-block problem at e = 0.3).
    collider = _top_shapes()[shape]
    scene = make_scene(scheme)
    scene.add_collider(collider, material=tc.Material(restitution=0.3, friction=0.5))
    scene.add_particles(positions=[[0.0123, 0.05 + R, -0.0071]], radius=R)
    scene.step(frames_for(scene, 1.0))
    phis, speeds = [], []
    for _ in range(frames_for(scene, 0.2)):
        scene.step()
        phis.append(collider.signed_distance(scene.positions())[0])
        speeds.append(np.linalg.norm(scene.velocities()[0]))
    assert min(phis) >= R - 1e-3 * R
    assert max(phis) <= R + 0.02 * R
    assert max(speeds) < (1e-9 if scheme in RESTING_SCHEMES else G * scene.dt)
    assert scene.stats()["failsafe"] == 0 and scene.stats()["repulsion"] == 0


# ---------------------------------------------------------------- resting height at any dt
@pytest.mark.parametrize("dt", [1.0 / 600.0, 1.0 / 60.0, 0.1])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_dropped_particle_rests_at_its_radius_at_any_dt(scheme, dt):
    # Issue 25: at dt = 0.1 s a particle of radius 5 mm dropped on a floor (e = 0) came to rest
    # at y = 9.5 mm, 4.5 mm up, silently: the inelastic pass re-integrated from where the
    # particle stood at time t, up to |g| dt^2 (98 mm at 0.1 s) above the floor. It now follows
    # its path to the contact and stops there (docs/physics.md 3.2). Measured: y - r below
    # 1e-15 m for every scheme and dt; at rest exactly.
    r = 0.005
    scene = make_scene(scheme, dt=dt, substeps=1)
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(restitution=0.0, friction=0.5))
    scene.add_particles(positions=[[0.0, 0.5, 0.0]], radius=r)
    scene.step(int(np.ceil(1.0 / dt)))  # lands at t = 0.32 s
    assert scene.positions()[0, 1] == pytest.approx(r, abs=1e-3 * r)
    assert np.linalg.norm(scene.velocities()[0]) < 1e-12


@pytest.mark.parametrize("scheme", RESTING_SCHEMES)
@pytest.mark.parametrize("shape", ["plane", "sphere", "box", "cylinder", "capsule"])
def test_every_collider_holds_dropped_particle_at_large_dt(shape, scheme):
    # test_every_collider_holds_dropped_particle at dt = 1/60 s, one substep a frame (|g| dt^2
    # = 2.7 cm, 2.7 radii): on the surface within the slop, not hovering above it.
    collider = _top_shapes()[shape]
    scene = make_scene(scheme, dt=1.0 / 60.0, substeps=1)
    scene.add_collider(collider, material=tc.Material(restitution=0.3, friction=0.5))
    scene.add_particles(positions=[[0.0123, 0.05 + R, -0.0071]], radius=R)
    scene.step(120)
    phi = collider.signed_distance(scene.positions())[0]
    assert phi == pytest.approx(R, abs=1e-3 * R)
    assert np.linalg.norm(scene.velocities()[0]) < 1e-9


@pytest.mark.parametrize("scheme", SCHEMES)
def test_rising_floor_carries_resting_particle_at_large_dt(scheme):
    # test_rising_floor_carries_resting_particle at dt = 1/20 s: y = r + u t on the floor.
    u = 0.5
    scene = make_scene(scheme, dt=0.05, substeps=1)
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(restitution=0.0, friction=0.5), velocity=(0, u, 0))
    scene.add_particles(positions=[[0.0, R, 0.0]], radius=R)
    scene.step(20)
    assert scene.positions()[0, 1] == pytest.approx(R + u * scene.time, abs=1e-3 * R)
    np.testing.assert_allclose(scene.velocities()[0], [0, u, 0], atol=1e-9)


def test_resting_particle_stays_at_rest_at_large_dt():
    # The bouncing-block problem at dt = 0.1 s, e = 0.9: Implementation 3 keeps it at rest.
    scene = make_scene("elastic_contact", dt=0.1, substeps=1)
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(restitution=0.9, friction=0.3))
    scene.add_particles(positions=[[0.0, R, 0.0]], radius=R)
    scene.step(50)
    np.testing.assert_allclose(scene.positions()[0], [0.0, R, 0.0], atol=1e-12)
    assert np.linalg.norm(scene.velocities()[0]) < 1e-12


# ---------------------------------------------------------------- thin wall (continuous detection)
@pytest.mark.parametrize("x_start", [-0.3, -0.2917, -50.0 / 600.0])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_fast_particle_bounces_off_thin_wall(scheme, x_start):
    # 50 m/s moves 83 mm per substep against a 1 mm wall: interference at x1 alone misses it
    # (except for x_start = -50/600, whose candidate lands inside). All four schemes use
    # continuous detection (simple included: it shares `detect` with micro and
    # elastic_contact) and bounce back at -50 m/s. exact_time also gets the position right:
    # it reflects at the contact, not at the start of the substep.
    half = 0.0005
    scene = make_scene(scheme, gravity=(0, 0, 0), substeps=1)
    scene.add_collider(tc.Box(center=(0, 0, 0), half_extents=(half, 0.5, 0.5)),
                       material=tc.Material(restitution=1.0, friction=0.0))
    scene.add_particles(positions=[[x_start, 0.01, 0.02]], velocities=[[50.0, 0, 0]], radius=R)
    scene.step(20)
    x, v = scene.positions()[0], scene.velocities()[0]
    np.testing.assert_allclose(v, [-50.0, 0, 0], atol=1e-9)
    assert x[0] < -(half + R)
    if scheme == "exact_time":
        travelled = 50.0 * scene.time
        contact = -(half + R)
        assert x[0] == pytest.approx(contact - (travelled - (contact - x_start)), abs=1e-9)


# ---------------------------------------------------------------- start outside, end outside
def _pile_colliders():
    return [tc.Sphere(center=(0, 0.2, 0), radius=0.2), tc.Plane(**FLOOR),
            tc.Box(center=(0.25, 0.1, 0), half_extents=(0.05, 0.1, 0.3), rotation=tc.rotation_matrix((0, 0, 1), 0.3))]


def _pile_min_gap(scheme, e):
    rng = np.random.default_rng(7)
    n = 300
    colliders = _pile_colliders()
    positions = np.column_stack([rng.uniform(-0.3, 0.3, n), rng.uniform(0.45, 0.8, n), rng.uniform(-0.3, 0.3, n)])
    velocities = rng.normal(size=(n, 3))
    scene = make_scene(scheme)
    for c in colliders:
        scene.add_collider(c, material=tc.Material(restitution=e, friction=0.3))
    scene.add_particles(positions=positions, velocities=velocities, radius=R)
    worst = np.inf
    for _ in range(frames_for(scene, 1.5)):
        scene.step()
        phi = np.min([c.signed_distance(scene.positions()) for c in colliders], axis=0)
        worst = min(worst, phi.min() - R)
    return worst


@pytest.mark.parametrize("e", [0.0, 0.5, 0.9])
@pytest.mark.parametrize("scheme", ["micro", "elastic_contact", "exact_time"])
def test_start_outside_end_outside(scheme, e):
    # Seed 001: micro-collisions guarantee that particles starting outside end outside. Drops
    # onto a ball resting on a floor next to a tilted box (crevices, several colliders at once).
    # Measured worst gap >= -2e-15 r (round-off) for all three schemes.
    slop = 1e-3
    assert _pile_min_gap(scheme, e) >= -slop * R


def test_simple_scheme_can_leave_particles_inside():
    # The contrast (docs/physics.md 3, Implementation 1 "can leave particles inside"): one pass of
    # the law is not enough in the crevices; measured worst gap -3.9 r.
    assert _pile_min_gap("simple", 0.0) < -0.5 * R


# ---------------------------------------------------------------- last-resort repulsion
@pytest.mark.parametrize("scheme", ["elastic_contact", "micro", "exact_time"])
def test_repulsion_pushes_particle_out_of_box(scheme):
    # Created 3 cm deep inside a box (no gravity): the last resort accepts the penetration and
    # pushes the position out by `repulsion` x depth per substep (10 %): phi grows every frame,
    # the depth shrinks geometrically into the slop band, and the particle does not fly off.
    box = tc.Box(center=(0, 0, 0), half_extents=(0.1, 0.1, 0.1))
    start = np.array([[0.03, 0.07, 0.01]])
    scene = make_scene(scheme, gravity=(0, 0, 0))
    scene.add_collider(box, material=tc.Material(restitution=0.5, friction=0.3))
    scene.add_particles(positions=start, radius=R)
    phis = [box.signed_distance(start)[0]]
    for _ in range(20):
        scene.step()
        phis.append(box.signed_distance(scene.positions())[0])
    phis = np.array(phis)
    depth = R - phis
    # Each substep removes min(push_fraction x depth, max_push_speed x dt) of the depth
    # (defaults 0.1 and 1 m/s): linear at first, then geometric.
    expected = [depth[0]]
    d = depth[0]
    for _ in range(3 * 10):
        d -= min(0.1 * d, 1.0 * scene.dt)
        expected.append(d)
    assert depth[1:4] == pytest.approx(expected[10::10], rel=1e-6)
    assert np.all(np.diff(phis[:8]) > 0)
    assert phis[-1] >= R * (1 - 1e-3)  # out, up to the slop
    assert np.linalg.norm(scene.velocities()[0]) < 1e-9  # the push is not kept as velocity
    assert scene.stats()["repulsion"] > 0
    x = scene.positions()[0]
    assert x[0] == pytest.approx(0.03) and x[2] == pytest.approx(0.01)  # pushed along the face normal +y


def test_repulsion_pushes_particle_out_and_onto_box_under_gravity():
    box = tc.Box(center=(0, 0, 0), half_extents=(0.1, 0.1, 0.1))
    scene = make_scene("elastic_contact")
    scene.add_collider(box, material=tc.Material(restitution=0.5, friction=0.3))
    scene.add_particles(positions=[[0.03, 0.07, 0.01]], radius=R)
    scene.step(frames_for(scene, 0.5))
    assert box.signed_distance(scene.positions())[0] == pytest.approx(R, rel=0.02)
    assert np.linalg.norm(scene.velocities()[0]) < 1e-6
    assert scene.stats()["repulsion"] > 0


def test_simple_scheme_has_no_repulsion():
    # Implementation 1 has no last resort: a particle created inside stays there.
    box = tc.Box(center=(0, 0, 0), half_extents=(0.1, 0.1, 0.1))
    scene = make_scene("simple", gravity=(0, 0, 0))
    scene.add_collider(box)
    scene.add_particles(positions=[[0.03, 0.07, 0.01]], radius=R)
    scene.step(10)
    assert scene.stats()["repulsion"] == 0
    assert box.signed_distance(scene.positions())[0] < 0


# ---------------------------------------------------------------- determinism
@pytest.mark.parametrize("scheme", SCHEMES)
def test_f64_runs_are_bit_identical(scheme):
    def run():
        rng = np.random.default_rng(3)
        scene = make_scene(scheme)
        for c in _pile_colliders():
            scene.add_collider(c, material=tc.Material(restitution=0.5, friction=0.3, wet_friction=0.1))
        scene.add_collider(tc.Cylinder(center=(-0.2, 0.05, 0), radius=0.05, half_height=0.05),
                           angular_velocity=(0, 3, 0))
        n = 200
        scene.add_particles(positions=np.column_stack([rng.uniform(-0.3, 0.3, n), rng.uniform(0.1, 0.6, n),
                                                       rng.uniform(-0.3, 0.3, n)]),
                            velocities=rng.normal(size=(n, 3)), radius=R)
        scene.step(30)
        return scene.positions(), scene.velocities(), scene.stats()

    x1, v1, s1 = run()
    x2, v2, s2 = run()
    assert x1.dtype == np.float64
    np.testing.assert_array_equal(x1, x2)
    np.testing.assert_array_equal(v1, v2)
    assert s1 == s2


# ---------------------------------------------------------------- free flight and kept clearances
def _symplectic_euler(x, v, g, dt, steps):
    for _ in range(steps):
        v = v + dt * g
        x = x + dt * v
    return x, v


def test_free_flight_in_closed_form_matches_substep_integration():
    # Far from every collider the solver jumps whole frames in closed form; the result is
    # symplectic Euler substep by substep, to round-off.
    g = np.array([0.3, -G, 0.2])
    scene = make_scene(gravity=tuple(g))
    scene.add_collider(tc.Plane(**FLOOR))
    x0 = np.array([[0.0, 50.0, 0.0], [1.0, 80.0, -2.0]])
    v0 = np.array([[1.0, 3.0, -0.5], [-2.0, 0.0, 4.0]])
    scene.add_particles(positions=x0, velocities=v0, radius=R)
    scene.step(7)
    for k in range(2):
        x, v = _symplectic_euler(x0[k], v0[k], g, scene.dt, 70)
        np.testing.assert_allclose(scene.positions()[k], x, rtol=0, atol=1e-11)
        np.testing.assert_allclose(scene.velocities()[k], v, rtol=0, atol=1e-11)


def _bouncer(setup, substeps):
    """A particle bouncing (e = 0.7, no friction) in one of the set-ups below, substeps a
    frame; returns the scene and its colliders."""
    scene = make_scene(dt=1.0 / 1200.0, substeps=substeps)
    bouncy = tc.Material(restitution=0.7, friction=0.0)
    x0, v0 = [0.0, 0.05 + R, 0.0], [0.3, 0.0, 0.1]
    colliders = []
    if setup == "sphere":  # on top of a sphere of 1 m, then down its side
        colliders.append((tc.Sphere(center=(0.0, -1.0, 0.0), radius=1.0), bouncy))
    elif setup == "box":
        colliders.append((tc.Box(center=(0.0, -0.5, 0.0), half_extents=(1.0, 0.5, 1.0)), bouncy))
    else:
        colliders.append((tc.Plane(**FLOOR), bouncy))
    if setup == "channel":  # back and forth between two walls 6 cm apart, e = 1
        for side in (-1.0, 1.0):
            colliders.append((tc.Plane(point=(0.03 * side, 0.0, 0.0), normal=(-side, 0.0, 0.0)),
                              tc.Material(restitution=1.0, friction=0.0)))
        v0 = [1.9, 0.5, 0.0]  # (2 m/s would touch the walls exactly at substep ends: ties)
    elif setup == "ceiling":  # thrown up against a ceiling 10 cm up, gravity pointing away from it
        colliders.append((tc.Plane(point=(0.0, 0.1, 0.0), normal=(0.0, -1.0, 0.0)), bouncy))
        v0 = [0.0, 2.0, 0.0]
    for shape, material in colliders:
        scene.add_collider(shape, material=material)
    scene.add_particles(positions=[x0], velocities=[v0], radius=R)
    return scene, [shape for shape, _ in colliders]


@pytest.mark.parametrize("setup", ["plane", "sphere", "box", "channel", "ceiling"])
def test_bounces_within_a_frame_follow_the_substeps(setup):
    # A particle that queried the colliders keeps the nearest one's separating plane and flies
    # in closed form while it stays in front of it (and within the others' clearance): whole
    # arcs between bounces, 60 substeps a frame, and the plane and the others' clearance kept
    # from one frame to the next (also with one substep a frame). Substep by substep with
    # nothing kept (the velocity written back from the host after every substep) gives the same
    # motion to round-off, every bounce included; nothing penetrates and the walls of e = 1
    # keep the speed across the channel.
    frames, substeps = 12, 60
    fast, shapes = _bouncer(setup, substeps)
    single, _ = _bouncer(setup, 1)
    reference, _ = _bouncer(setup, 1)
    bounces = 0
    for _ in range(frames):
        vy = fast.velocities()[0, 1]
        fast.step(1)
        single.step(substeps)
        for _ in range(substeps):
            reference.step(1)
            reference.set_velocities(reference.velocities())  # (a host write: nothing is kept)
        for scene in (fast, single):
            np.testing.assert_allclose(scene.positions(), reference.positions(), rtol=0, atol=1e-9)
            np.testing.assert_allclose(scene.velocities(), reference.velocities(), rtol=0, atol=1e-8)
        bounces += (vy < 0.0) != (fast.velocities()[0, 1] < 0.0)
        for shape in shapes:
            assert shape.signed_distance(fast.positions())[0] >= R * (1 - 2e-3)
        if setup == "channel":
            assert abs(fast.velocities()[0, 0]) == pytest.approx(1.9, rel=1e-9)
    assert bounces >= 3


def test_kept_separating_planes_follow_many_particles_in_a_box():
    # Particles thrown about a box of five planes around a sphere, 10 substeps a frame: the
    # separating planes and the other colliders' clearances kept from frame to frame give the
    # motion that nothing kept (a host write after every frame) gives, to round-off; nothing
    # ends inside a collider.
    rng = np.random.default_rng(3)
    n = 200
    x0 = rng.uniform((-0.4, 0.1, -0.4), (0.4, 0.6, 0.4), size=(n, 3))
    x0 = x0[np.linalg.norm(x0 - [0.0, 0.2, 0.0], axis=1) > 0.15 + 2 * R]
    v0 = rng.uniform(-1.0, 1.0, size=(len(x0), 3))
    shapes = [tc.Sphere(center=(0.0, 0.2, 0.0), radius=0.15)]
    walls = [((0, 0, 0), (0, 1, 0)), ((-0.5, 0, 0), (1, 0, 0)), ((0.5, 0, 0), (-1, 0, 0)),
             ((0, 0, -0.5), (0, 0, 1)), ((0, 0, 0.5), (0, 0, -1))]
    shapes += [tc.Plane(point=p, normal=nrm) for p, nrm in walls]
    scenes = []
    for _ in range(2):
        scene = make_scene(dt=1.0 / 1200.0, substeps=10)
        for shape in shapes:
            scene.add_collider(shape, material=tc.Material(restitution=0.8, friction=0.2))
        scene.add_particles(positions=x0, velocities=v0, radius=R)
        scenes.append(scene)
    kept, reference = scenes
    for _ in range(15):
        kept.step(1)
        reference.step(1)
        reference.set_velocities(reference.velocities())
        np.testing.assert_allclose(kept.positions(), reference.positions(), rtol=0, atol=1e-9)
        np.testing.assert_allclose(kept.velocities(), reference.velocities(), rtol=0, atol=1e-7)
    for shape in shapes:
        assert np.all(shape.signed_distance(kept.positions()) >= R * (1 - 2e-3))


def test_kept_clearance_is_dropped_when_particles_are_moved():
    # Step once far from the floor (a large clearance is kept), then teleport the particle
    # just above the floor moving down fast: the next step must see the floor.
    scene = make_scene()
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(restitution=0.0, friction=0.0))
    scene.add_particles(positions=[[0.0, 5.0, 0.0]], radius=R)
    scene.step(1)
    scene.set_positions([[0.0, 0.02, 0.0]])
    scene.set_velocities([[0.0, -3.0, 0.0]])
    scene.step(3)
    assert scene.positions()[0, 1] >= R * (1 - 2e-3)


def test_kept_clearance_is_dropped_when_a_collider_is_added():
    scene = make_scene()
    scene.add_collider(tc.Plane(**FLOOR))
    scene.add_particles(positions=[[0.0, 2.0, 0.0]], velocities=[[0.0, -2.0, 0.0]], radius=R)
    scene.step(1)  # clearance ~ 2 m kept
    shelf = tc.Box(center=(0.0, 1.5, 0.0), half_extents=(0.5, 0.05, 0.5))
    scene.add_collider(shelf, material=tc.Material(restitution=0.0, friction=0.0))
    scene.step(60)
    assert shelf.signed_distance(scene.positions())[0] >= R * (1 - 2e-3)
    assert scene.positions()[0, 1] > 1.5


def test_flight_leaving_the_domain_and_coming_back_within_a_frame_is_caught():
    # Thrown up through the domain's ceiling and falling back below it inside one frame of
    # 10 substeps: the closed-form flight checks every substep's end, like the loop does.
    dt, substeps = 1.0 / 600.0, 10
    scene = tc.Scene(dt=dt, substeps=substeps, domain=((-1, -1, -1), (1, 1.0, 1)))
    scene.add_collider(tc.Plane(**FLOOR))
    # x_j = 0.9999 + j dt v + g dt^2 j (j + 1) / 2 with v = 0.06 m/s peaks 0.08 mm above 1.0 mid-frame
    x, _ = _symplectic_euler(np.array([0.0, 0.9999, 0.0]), np.array([0.0, 0.06, 0.0]), np.array([0, -G, 0]),
                             dt, substeps)
    peak = max(_symplectic_euler(np.array([0.0, 0.9999, 0.0]), np.array([0.0, 0.06, 0.0]),
                                 np.array([0, -G, 0]), dt, j)[0][1] for j in range(1, substeps + 1))
    assert x[1] < 1.0 < peak  # the premise: out and back in within the frame
    scene.add_particles(positions=[[0.0, 0.9999, 0.0]], velocities=[[0.0, 0.06, 0.0]], radius=R)
    with pytest.warns(RuntimeWarning, match="left the domain"):
        scene.step(1)
    assert scene.particle_status()[0] == "left_domain"


# ---------------------------------------------------------------- particles at rest skipped across launches
def test_a_particle_at_rest_is_skipped_until_the_substep_changes_and_then_slides_as_the_incline_says():
    """A particle at a fixed point of its substep is skipped by the next launches
    (solvers/impulse.py AT_REST) only while that substep is the same map: tilting gravity
    (an incline of 30 degrees, mu = 0.2 < tan 30) must start it sliding at g (sin - mu cos)."""
    from tai_coll.solvers.impulse import AT_REST

    scene = make_scene()
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(restitution=0.5, friction=0.2))
    scene.add_particles(positions=[[0.0, R, 0.0], [0.5, R + 0.05, 0.0]], radius=R)
    scene.step(60)
    assert scene._particles.clearance.to_numpy()[0] == AT_REST  # found at rest, and skipped since
    rest = scene.positions()
    assert rest[0, 1] == pytest.approx(R, abs=1e-9) and np.all(scene.velocities()[0] == 0.0)
    scene.step(5)
    assert np.array_equal(scene.positions(), rest)  # (the second one landed too)
    scene.gravity = (G * np.sin(THETA), -G * np.cos(THETA), 0.0)  # the floor is now an incline
    t = 0.5
    scene.step(frames_for(scene, t))
    expected = 0.5 * G * (np.sin(THETA) - 0.2 * np.cos(THETA)) * t ** 2
    assert scene.positions()[0, 0] - rest[0, 0] == pytest.approx(expected, rel=0.01)
    # a host write ends the skip too: a resting particle pushed slides off (no friction)
    level = make_scene()
    level.add_collider(tc.Plane(**FLOOR), material=tc.Material(friction=0.0))
    level.add_particles(positions=[[0.0, R, 0.0]], radius=R)
    level.step(10)
    assert level._particles.clearance.to_numpy()[0] == AT_REST
    level.set_velocities([[1.0, 0.0, 0.0]])
    level.step(1)
    assert level.positions()[0, 0] == pytest.approx(level.frame_time * 1.0, rel=1e-9)


# ---------------------------------------------------------------- a lone still plane (docs/physics.md 3.8)
@pytest.mark.parametrize("elastic_iterations", [1, 0, 2])
def test_lone_plane_path_agrees_with_the_general_scheme(elastic_iterations):
    """Particles bouncing and sliding on a tilted, raised floor (wet friction) beside a wall:
    where one still plane is all a substep can reach, the impulse kernel resolves it on its
    own short path (solvers/lone_plane.py). A far-away collider that moves makes the table
    kinematic, which compiles that path out, so the same scene then runs the general scheme
    alone: the two agree to round-off (measured: 4e-14 m, 1e-14 m/s)."""
    rng = np.random.default_rng(3)
    n = 3000
    x0 = np.column_stack([rng.uniform(-1.0, 0.45, n), rng.uniform(0.3, 0.6, n), rng.uniform(-1.0, 1.0, n)])
    v0 = rng.normal(0.0, 1.0, (n, 3))
    floor = tc.Plane(point=(0.0, 0.2, 0.0), normal=(0.2, 1.0, -0.1))
    results = []
    for general in (False, True):
        scene = make_scene(elastic_iterations=elastic_iterations)
        scene.add_collider(floor, material=tc.Material(restitution=0.5, friction=0.3, wet_friction=0.2))
        scene.add_collider(tc.Plane(point=(0.5, 0.0, 0.0), normal=(-1.0, 0.0, 0.0)),
                           material=tc.Material(restitution=0.8, friction=0.1))
        if general:
            scene.add_collider(tc.Sphere(center=(50.0, 50.0, 50.0), radius=0.1), velocity=(0.0, 0.0, 0.0))
        scene.add_particles(positions=x0, velocities=v0, radius=0.005)
        scene.step(60)
        results.append((scene.positions(), scene.velocities()))
        if not general:  # a kept row with a separating direction names the collider it belongs to
            kept = scene._particles.separation.to_numpy()[:n]
            usable = (scene._particles.clearance.to_numpy()[:n] >= 0.0) & (np.abs(kept[:, :3]).sum(axis=1) > 0.0)
            assert usable.any() and set(kept[usable, 5]) <= {0.0, 1.0}
    (x_fast, v_fast), (x_general, v_general) = results
    np.testing.assert_allclose(x_fast, x_general, rtol=0, atol=1e-9)
    np.testing.assert_allclose(v_fast, v_general, rtol=0, atol=1e-9)
    assert np.all(floor.signed_distance(x_fast) >= 0.005 * (1 - 2e-3))
