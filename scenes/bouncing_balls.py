"""A row of balls dropped on tiles of restitution 0 to 1 (seed 000, Newtonian collisions).

Each ball falls from the same height h onto its own tile; its first rebound rises to e^2 h
(the normal velocity is reversed and scaled by e, so the kinetic energy scales by e^2).
Run it: `python scenes/bouncing_balls.py` prints each tile's measured apex against e^2 h.
"""

import numpy as np

import tai_coll as tc

RESTITUTIONS = np.linspace(0.0, 1.0, 6)
DROP_HEIGHT = 1.0   # m, ball bottom above the tile top
RADIUS = 0.02       # m
SPACING = 0.25      # m between tiles
FRAMES = 90         # 1.5 s at 60 frames per second: every ball reaches its first apex


def scene() -> tc.Scene:
    s = tc.Scene(gravity=(0.0, -9.81, 0.0), dt=1.0 / 1200.0, substeps=20)
    for k, e in enumerate(RESTITUTIONS):
        s.add_collider(tc.Box(center=(k * SPACING, -0.05, 0.0), half_extents=(0.1, 0.05, 0.1)),
                       material=tc.Material(restitution=float(e), friction=0.3))
    starts = [[k * SPACING, DROP_HEIGHT + RADIUS, 0.0] for k in range(len(RESTITUTIONS))]
    s.add_particles(positions=starts, radius=RADIUS)
    return s


def first_apex(s: tc.Scene, frames: int = FRAMES) -> np.ndarray:
    """Step the scene and return each ball's highest bottom height after its first bounce."""
    bounced = np.zeros(s.num_particles, dtype=bool)
    apex = np.zeros(s.num_particles)
    for _ in range(frames):
        s.step()
        bottom = s.positions()[:, 1] - RADIUS
        rising = s.velocities()[:, 1] > 1e-3
        bounced |= rising
        apex = np.where(bounced, np.maximum(apex, bottom), apex)
    return apex


def check(apex: np.ndarray) -> None:
    """The physical outcome: apex = e^2 h within 2 % of h."""
    expected = RESTITUTIONS ** 2 * DROP_HEIGHT
    error = np.abs(apex - expected)
    assert np.all(error < 0.02 * DROP_HEIGHT), f"apex {apex} vs e^2 h {expected}"


def main():
    s = scene()
    apex = first_apex(s)
    print(f"{'restitution':>11}  {'apex (m)':>9}  {'e^2 h (m)':>9}")
    for e, a in zip(RESTITUTIONS, apex):
        print(f"{e:11.2f}  {a:9.4f}  {e * e * DROP_HEIGHT:9.4f}")
    check(apex)
    print(f"simulated {s.time:.2f} s of {s.num_particles} balls: every apex within 2 % of e^2 h")


if __name__ == "__main__":
    main()
