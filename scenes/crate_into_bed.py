"""A crate dropped onto a bed of sand lands and rests on top of it (docs/physics.md 6:
rigid bodies and particles, two-way; 6.2: a body lying on particles held by what they rest
on stops on them).

A bed of 1,600 grains (r = 5 mm, 2,500 kg/m^3) four layers deep in a walled box, settled; a
wooden crate (10 x 6 x 10 cm, 500 kg/m^3, 0.3 kg) falls onto it from 5 cm, tilted. It
kicks up a few grains, rocks, and comes to rest on the bed: its bottom within a grain's
radius of the bed's top, no grain inside it, at rest.
Run it: `python scenes/crate_into_bed.py` prints where the crate came to rest.
"""

import numpy as np

import tai_coll as tc

RADIUS = 0.005      # m
HALF_WIDTH = 0.1    # m: the bed is 20 x 20 cm
LAYERS = 4
CRATE = (0.05, 0.03, 0.05)  # m, half extents
DROP = 0.05         # m, from the bed's top to the crate's bottom
SETTLE_FRAMES = 20
FRAMES = 80         # after the drop: 1.3 s at 60 frames per second


def bed_positions() -> np.ndarray:
    n = int(2 * HALF_WIDTH / (2.1 * RADIUS))
    g = (np.arange(n) + 0.5) * (2 * HALF_WIDTH / n) - HALF_WIDTH
    X, Y, Z = np.meshgrid(g, (np.arange(LAYERS) + 0.5) * 2.1 * RADIUS, g, indexing="ij")
    return np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])


def scene() -> tc.Scene:
    s = tc.Scene(dt=1.0 / 600.0, substeps=10)
    s.add_collider(tc.Plane(point=(0, 0, 0), normal=(0, 1, 0)), material=tc.Material(restitution=0.2))
    wall = 0.01
    for sx, sz in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        half = (wall if sx else HALF_WIDTH + 2 * wall, 0.1, wall if sz else HALF_WIDTH + 2 * wall)
        s.add_collider(tc.Box(center=(sx * (HALF_WIDTH + wall), 0.1, sz * (HALF_WIDTH + wall)), half_extents=half))
    s.add_particles(positions=bed_positions(), radius=RADIUS, mass=2500.0 * 4.0 / 3.0 * np.pi * RADIUS ** 3)
    s.enable_particle_collisions(material=tc.Material(restitution=0.2, friction=0.5))
    return s


def drop_crate(s: tc.Scene) -> tuple:
    """The crate, above the settled bed: (body, the bed's top)."""
    top = float(s.positions()[:, 1].max()) + RADIUS
    tilt = tc.rotation_matrix(axis=(1.0, 0.0, 1.0), angle=np.radians(10.0))
    crate = s.add_body(tc.Box(center=(0.0, top + DROP + 0.05, 0.0), half_extents=CRATE, rotation=tilt),
                       density=500.0, material=tc.Material(restitution=0.2, friction=0.5))
    return crate, top


def grains_inside(s: tc.Scene, crate: tc.Body) -> int:
    """Grains whose centre lies inside the crate."""
    local = (s.positions() - crate.position) @ crate.rotation
    return int(np.all(np.abs(local) < np.asarray(CRATE), axis=1).sum())


def main():
    s = scene()
    s.step(SETTLE_FRAMES)
    crate, top = drop_crate(s)
    inside = 0
    for _ in range(FRAMES):
        s.step()
        inside = max(inside, grains_inside(s, crate))
    lowest = float(np.min(crate.position[1] + (np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                                                          for sz in (-1, 1)]) * CRATE) @ crate.rotation.T[:, 1]))
    speed = float(np.linalg.norm(crate.velocity))
    print(f"crate of {crate.mass:.3f} kg on {s.num_particles} grains after {s.time:.2f} s: lowest corner "
          f"{(lowest - top) * 1e3:+.2f} mm from the bed's top, speed {speed * 1e3:.2f} mm/s, "
          f"{inside} grain(s) inside it at any frame")
    assert inside == 0, "a grain got inside the crate"
    assert lowest > top - 2.0 * RADIUS, "the crate sank into the bed"
    assert speed < 0.01, "the crate should be at rest"
    print("the crate landed on the bed and rests on top of it")


if __name__ == "__main__":
    tc.init(arch="cpu")
    main()
