"""Particles released on the slopes of a height-field valley slide down into it (seed 002:
height fields; seed 001: Coulomb friction).

The terrain is y = 0.4 x^2 + a ripple, 4 m x 3 m in cells of 5 cm: its flanks are steeper
than the friction angle (slope 0.8 to 1.4 against mu = 0.3), its floor is not. Particles
dropped onto both flanks slide, overshoot, and settle on the valley floor. None sinks
into the terrain (checked every frame against the exact distance to its triangles).
Run it: `python scenes/avalanche.py` prints where the particles settled.
"""

import numpy as np

import tai_coll as tc

CELL = 0.05         # m
WIDTH = 4.0         # m, across the valley (x)
LENGTH = 3.0        # m, along it (z)
COUNT = 1500
RADIUS = 0.01       # m
FRICTION = 0.3
FRAMES = 180        # 3 s at 60 frames per second
FLOOR = 0.5         # m: settled particles lie within this distance of the valley's axis


def terrain() -> tc.HeightField:
    x = -WIDTH / 2 + CELL * np.arange(int(round(WIDTH / CELL)) + 1)
    z = -LENGTH / 2 + CELL * np.arange(int(round(LENGTH / CELL)) + 1)
    X, Z = np.meshgrid(x, z, indexing="ij")
    heights = 0.4 * X ** 2 + 0.03 * np.sin(4.0 * Z) * np.cos(3.0 * X)
    return tc.HeightField(heights=heights, cell_size=CELL, origin=(-WIDTH / 2, 0.0, -LENGTH / 2))


def scene(seed: int = 0) -> tc.Scene:
    rng = np.random.default_rng(seed)
    s = tc.Scene(gravity=(0.0, -9.81, 0.0), dt=1.0 / 1200.0, substeps=20)
    field = terrain()
    s.add_collider(field, material=tc.Material(restitution=0.1, friction=FRICTION))
    x = rng.uniform(1.0, 1.8, COUNT) * rng.choice([-1.0, 1.0], COUNT)
    z = rng.uniform(-1.2, 1.2, COUNT)
    y = field.height(x, z) + 2.0 * RADIUS + rng.uniform(0.0, 0.3, COUNT)  # clear of slopes up to 1.7
    s.add_particles(positions=np.column_stack([x, y, z]), radius=RADIUS)
    return s


def main():
    s = scene()
    field = s.colliders[0].shape
    lowest = np.inf  # the smallest distance from a particle's center to the terrain, over all frames
    for _ in range(FRAMES):
        s.step()
        lowest = min(lowest, float(np.min(field.signed_distance(s.positions()))))
    p, v = s.positions(), s.velocities()
    settled = np.abs(p[:, 0]) < FLOOR
    print(f"{COUNT} particles after {s.time:.1f} s: {settled.sum()} on the valley floor (|x| < {FLOOR} m), "
          f"mean |x| {np.mean(np.abs(p[:, 0])):.3f} m, mean speed {np.mean(np.linalg.norm(v, axis=1)):.4f} m/s; "
          f"closest center {lowest * 1e3:.3f} mm from the terrain (radius {RADIUS * 1e3:g} mm)")
    assert lowest > 0.99 * RADIUS, "a particle sank into the terrain"
    assert settled.mean() > 0.98, "the particles should end up in the valley"
    print("every particle stayed on the terrain and the avalanche reached the valley floor")


if __name__ == "__main__":
    main()
