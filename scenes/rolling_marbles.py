"""Marbles on three ramps of 20 degrees, each ramp with its own rolling resistance (spinning
particles: PenaltySolver(spin=True); docs/physics.md 6).

A solid sphere that rolls without slipping accelerates at 5/7 g sin(theta), slower than a
sliding point's g sin(theta): part of gravity's work goes into spin. Rolling resistance
mu_r (a torque of at most mu_r r |f_n|) leaves 5/7 g (sin(theta) - mu_r cos(theta)), and holds
the marble still where tan(theta) <= mu_r. Friction mu = 0.5 > 2/7 tan 20, so none slips.
Run it: `python scenes/rolling_marbles.py` prints how far each marble rolled against the
closed form.
"""

import numpy as np

import tai_coll as tc

THETA = np.radians(20.0)
ROLLING = (0.0, 0.2, 0.5)   # mu_r of the three ramps (tan 20 = 0.364: the last one holds)
RADIUS = 0.02               # m
HERTZ = 50.0                # contact frequency: resting depth g cos(theta) / (2 pi f)^2 = 93 um
FRAMES = 60                 # 1 s at 60 frames per second
HALF = np.array([1.0, 0.05, 0.04])  # m, half extents of each ramp
START = 0.8                 # m up the ramp from its middle
TURN = tc.rotation_matrix((0.0, 0.0, 1.0), THETA)
UP = TURN @ np.array([0.0, 1.0, 0.0])      # the ramps' top normal
DOWNHILL = -(TURN @ np.array([1.0, 0.0, 0.0]))


def lane_center(k: int) -> np.ndarray:
    return np.array([0.0, 0.0, 0.12 * k])


def scene() -> tc.Scene:
    s = tc.Scene(gravity=(0.0, -9.81, 0.0), dt=1.0 / 4000.0, substeps=round(4000 / 60),
                 solver=tc.PenaltySolver(hertz=HERTZ, spin=True))
    sink = 9.81 * np.cos(THETA) / (2 * np.pi * HERTZ) ** 2
    starts = []
    for k, mu_r in enumerate(ROLLING):
        s.add_collider(tc.Box(center=lane_center(k), half_extents=HALF, rotation=TURN),
                       material=tc.Material(friction=0.5, rolling_friction=mu_r))
        starts.append(lane_center(k) - START * DOWNHILL + (HALF[1] + RADIUS - sink) * UP)
    s.add_particles(positions=np.array(starts), radius=RADIUS, mass=0.01)
    return s


def main():
    s = scene()
    start = s.positions()
    s.step(FRAMES)
    t = s.time
    rolled = (s.positions() - start) @ DOWNHILL
    for k, mu_r in enumerate(ROLLING):
        a = 5.0 / 7.0 * 9.81 * max(0.0, np.sin(THETA) - mu_r * np.cos(THETA))
        spin = np.linalg.norm(s.angular_velocities()[k])
        print(f"mu_r = {mu_r:.1f}: rolled {rolled[k]:.4f} m in {t:.2f} s (5/7 g (sin - mu_r cos) t^2 / 2 = "
              f"{0.5 * a * t * t:.4f} m), spin {spin:.1f} rad/s (v / r = {s.velocities()[k] @ DOWNHILL / RADIUS:.1f})")
        if a > 0.0:
            assert abs(rolled[k] - 0.5 * a * t * t) < 0.02 * 0.5 * a * t * t, "the marble should roll at 5/7 g ..."
        else:
            assert abs(rolled[k]) < 1e-4, "rolling resistance above tan(theta) should hold the marble"
    print("each marble rolled as a solid sphere does, and the third one held")


if __name__ == "__main__":
    main()
