"""Moving paddles striking particles at rest: collisions in the paddle's frame (relative velocity).

A paddle moving at V hits a particle at rest. In the paddle's frame the particle approaches
at -V and leaves at +e V (docs/physics.md 2: v_rel = v - v_obj, v_N' = -e v_N), so in the world
it leaves at V + e V = (1 + e) V: twice the paddle's speed when e = 1, the paddle's own
speed when e = 0 (it is pushed along). Processing the collision with the particle's own
velocity instead would leave it at rest.

Three kinematic box paddles in separate lanes, e = 0, 0.5 and 1, frictionless, sweep +x at
V = 2 m/s through columns of particles floating at rest (no gravity).
Run it: `python scenes/moving_paddle.py` prints each lane's particle speed against (1 + e) V.
"""

import numpy as np

import tai_coll as tc

SPEED = 2.0                        # m/s, the paddles' velocity along +x
RESTITUTIONS = (0.0, 0.5, 1.0)
LANE = 0.5                         # m between lanes along z
RADIUS = 0.03                      # m
PADDLE_HALF = (0.05, 0.3, 0.18)    # m; the paddle face is at x = -0.25 + 0.05 at t = 0
PARTICLES_X = (0.0, 0.15, 0.3)     # m: each lane has a column of particles at each x
FRAMES = 24                        # 0.4 s at 60 frames per second: every particle struck


def scene() -> tc.Scene:
    s = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=1.0 / 1200.0, substeps=20)
    positions = []
    for k, e in enumerate(RESTITUTIONS):
        z = k * LANE
        s.add_collider(tc.Box(center=(-0.25, 0.3, z), half_extents=PADDLE_HALF),
                       material=tc.Material(restitution=e, friction=0.0), velocity=(SPEED, 0.0, 0.0))
        positions += [[x, y, z + dz] for x in PARTICLES_X for y in (0.1, 0.3, 0.5) for dz in (-0.08, 0.08)]
    s.add_particles(positions=positions, radius=RADIUS)
    return s


def render_settings() -> dict:
    """For `tai-coll run`: a view from above and in front, across the three lanes."""
    from tai_coll.render import Camera

    return {"camera": Camera(position=(-0.5, 1.6, 2.6), look_at=(0.55, 0.25, 0.5), fov=40.0)}


def lane_of_particles() -> np.ndarray:
    per_lane = len(PARTICLES_X) * 3 * 2
    return np.repeat(np.arange(len(RESTITUTIONS)), per_lane)


def check(v: np.ndarray) -> None:
    """Every particle leaves along +x at (1 + e) V within 1 %, nothing across."""
    lanes = lane_of_particles()
    for k, e in enumerate(RESTITUTIONS):
        lane_v = v[lanes == k]
        want = (1.0 + e) * SPEED
        assert np.all(np.abs(lane_v[:, 0] - want) < 0.01 * want), f"e = {e}: vx {lane_v[:, 0]} vs (1 + e) V = {want}"
        assert np.all(np.abs(lane_v[:, 1:]) < 1e-6 * SPEED), f"e = {e}: sideways velocity {lane_v[:, 1:]}"


def main():
    s = scene()
    s.step(FRAMES)
    v = s.velocities()
    lanes = lane_of_particles()
    print(f"paddles at V = {SPEED} m/s; after {s.time:.2f} s:")
    print(f"{'e':>4}  {'particle vx (m/s)':>24}  {'(1 + e) V':>9}")
    for k, e in enumerate(RESTITUTIONS):
        vx = v[lanes == k, 0]
        print(f"{e:4.1f}  {vx.min():11.4f} .. {vx.max():9.4f}  {(1 + e) * SPEED:9.4f}")
    check(v)
    print("every particle leaves at (1 + e) V: the collision is processed in the paddle's frame")


if __name__ == "__main__":
    main()
