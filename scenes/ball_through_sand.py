"""A ball rolls down a ramp and ploughs through a patch of sand on it (docs/physics.md 7:
rigid bodies and particles, two-way; 6.4: a body rolls on a collider with friction).

A 20 degree ramp (friction 0.6, steeper than nothing the sand's friction angle holds: the
sand stays put); a patch of 700 grains (r = 4 mm, two layers, 30 cm long) lies on it 40 cm
below a solid ball (r = 3 cm, 1,000 kg/m^3). The ball rolls at 5/7 g sin(20 deg) until it
meets the sand, which it pushes aside and ahead of it and climbs over, losing speed, and
rolls on below the patch. Checked: before the sand it rolls as the closed form says (2 %); it gets through the
patch, slower than a ball on a bare ramp; it moved the sand; no grain got inside it.
Run it: `python scenes/ball_through_sand.py` prints the ball's progress.
"""

import numpy as np

import tai_coll as tc

THETA = np.radians(20.0)
DOWN = np.array([np.cos(THETA), -np.sin(THETA), 0.0])  # down the slope
NORMAL = np.array([np.sin(THETA), np.cos(THETA), 0.0])  # out of the ramp
ACROSS = np.array([0.0, 0.0, 1.0])
BALL = 0.03         # m, radius
GRAIN = 0.004       # m, radius
PATCH = (0.4, 0.7)  # m along the slope from the ball's start
FRAMES = 80         # 1.33 s at 60 frames per second
ROLLING = 5.0 / 7.0 * 9.81 * np.sin(THETA)  # m/s^2: a solid ball rolling without slipping


def sand_positions() -> np.ndarray:
    step = 2.1 * GRAIN
    along = np.arange(PATCH[0], PATCH[1], step)
    across = np.arange(-0.06, 0.06 + 1e-9, step)
    rows = []
    for layer in range(2):
        height = GRAIN + layer * step
        for s in along:
            for w in across:
                shift = 0.5 * step * (layer % 2)
                rows.append((s + shift) * DOWN + height * NORMAL + (w + shift) * ACROSS)
    return np.array(rows)


def render_settings() -> dict:
    """For `tai-coll run`: across the ramp, from above the sand."""
    from tai_coll.render import Camera

    return {"camera": Camera(position=(0.6, 0.5, 1.0), look_at=(0.6, -0.2, 0.0), fov=45.0)}


def scene() -> tc.Scene:
    s = tc.Scene(dt=1.0 / 1200.0, substeps=20)
    s.add_collider(tc.Plane(point=(0, 0, 0), normal=NORMAL), material=tc.Material(restitution=0.1, friction=0.6))
    s.add_particles(positions=sand_positions(), radius=GRAIN, mass=2500.0 * 4.0 / 3.0 * np.pi * GRAIN ** 3)
    s.enable_particle_collisions(material=tc.Material(restitution=0.1, friction=0.6))
    s.add_body(tc.Sphere(center=BALL * NORMAL, radius=BALL), density=1000.0,
               material=tc.Material(restitution=0.1, friction=0.6))
    return s


def main():
    s = scene()
    ball = s.bodies[0]
    start = ball.position
    sand0 = None  # the sand as the ball meets it (it settles into its hollows before)
    checked = False
    inside = 0
    for _ in range(FRAMES):
        s.step()
        travelled = float((ball.position - start) @ DOWN)
        if not checked and travelled + BALL > PATCH[0] - 0.05:  # just before the sand
            free = 0.5 * ROLLING * s.time ** 2
            print(f"before the sand, t = {s.time:.3f} s: travelled {travelled:.4f} m, closed form {free:.4f} m")
            assert abs(travelled - free) < 0.02 * free, "the ball should roll at 5/7 g sin(theta)"
            checked = True
            sand0 = s.positions().copy()
        gaps = np.linalg.norm(s.positions() - ball.position, axis=1)
        inside = max(inside, int(np.sum(gaps < BALL)))
    travelled = float((ball.position - start) @ DOWN)
    bare = 0.5 * ROLLING * s.time ** 2
    moved = np.linalg.norm(s.positions() - sand0, axis=1) if sand0 is not None else np.zeros(1)
    print(f"after {s.time:.2f} s: ball travelled {travelled:.3f} m (on a bare ramp {bare:.3f} m), speed "
          f"{np.linalg.norm(ball.velocity):.3f} m/s; {int(np.sum(moved > GRAIN))} of {len(moved)} grains moved "
          f"more than a radius since it met them; {inside} grain centre(s) inside the ball at any frame")
    assert checked, "the ball should reach the sand"
    assert travelled > PATCH[1], "the ball should get through the sand"
    assert travelled < bare, "the sand should slow the ball"
    assert np.sum(moved > GRAIN) > 20, "the ball should move the sand"
    assert inside == 0, "a grain got inside the ball"
    print("the ball rolled down, through the sand, and on")


if __name__ == "__main__":
    tc.init(arch="cpu")
    main()
