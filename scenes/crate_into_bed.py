"""A crate dropped onto a bed of sand lands and rests on top of it (docs/physics.md 7:
rigid bodies and particles, two-way; 6.2: a body lying on particles held by what they rest
on stops on them).

A bed of 1,370 grains (r = 5 mm, 2,500 kg/m^3) four layers deep in a walled box; a wooden
crate (10 x 6 x 10 cm, 500 kg/m^3, 0.3 kg) falls onto it from 5 cm, tilted. It
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
FRAMES = 90         # 1.5 s at 60 frames per second
TOP = 2.0 * RADIUS + (LAYERS - 1) * 1.45 * RADIUS  # m: the bed's top, as placed


def bed_positions() -> np.ndarray:
    """Square layers of grains 2.1 r apart, each over the hollows of the one below (a packing
    that holds under load, unlike grains stacked in columns)."""
    step = 2.1 * RADIUS
    rise = 1.45 * RADIUS  # (grains in the hollows touch those below at 1.34 r)
    rows = []
    for layer in range(LAYERS):
        shift = 0.5 * step * (layer % 2)
        g = np.arange(-HALF_WIDTH + RADIUS + shift, HALF_WIDTH - RADIUS, step)
        X, Z = np.meshgrid(g, g, indexing="ij")
        rows.append(np.column_stack([X.ravel(), np.full(X.size, RADIUS + layer * rise), Z.ravel()]))
    return np.concatenate(rows)


def scene() -> tc.Scene:
    s = tc.Scene(dt=1.0 / 600.0, substeps=10)
    s.add_collider(tc.Plane(point=(0, 0, 0), normal=(0, 1, 0)), material=tc.Material(restitution=0.2))
    wall = 0.01
    for sx, sz in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        half = (wall if sx else HALF_WIDTH + 2 * wall, 0.03, wall if sz else HALF_WIDTH + 2 * wall)
        s.add_collider(tc.Box(center=(sx * (HALF_WIDTH + wall), 0.03, sz * (HALF_WIDTH + wall)), half_extents=half))
    s.add_particles(positions=bed_positions(), radius=RADIUS, mass=2500.0 * 4.0 / 3.0 * np.pi * RADIUS ** 3)
    s.enable_particle_collisions(material=tc.Material(restitution=0.2, friction=0.5))
    tilt = tc.rotation_matrix(axis=(1.0, 0.0, 1.0), angle=np.radians(10.0))
    s.add_body(tc.Box(center=(0.0, TOP + DROP + 0.05, 0.0), half_extents=CRATE, rotation=tilt), density=500.0,
               material=tc.Material(restitution=0.2, friction=0.5))
    return s


def render_settings() -> dict:
    """For `tai-coll run`: the bed from above and in front."""
    from tai_coll.render import Camera

    return {"camera": Camera(position=(0.28, 0.32, 0.42), look_at=(0.0, 0.03, 0.0), fov=40.0)}


def grains_inside(s: tc.Scene, crate: tc.Body) -> int:
    """Grains whose centre lies inside the crate."""
    local = (s.positions() - crate.position) @ crate.rotation
    return int(np.all(np.abs(local) < np.asarray(CRATE), axis=1).sum())


def main():
    s = scene()
    crate = s.bodies[0]
    top = TOP
    inside = 0
    for _ in range(FRAMES):
        s.step()
        inside = max(inside, grains_inside(s, crate))
    lowest = float(np.min(crate.position[1] + (np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1)
                                                          for sz in (-1, 1)]) * CRATE) @ crate.rotation.T[:, 1]))
    speed = float(np.linalg.norm(crate.velocity))
    tilt = float(np.degrees(np.arccos(np.clip(crate.rotation[1, 1], -1.0, 1.0))))
    centre = float(crate.position[1]) - CRATE[1]  # its bottom's centre, were it level
    print(f"crate of {crate.mass:.3f} kg on {s.num_particles} grains after {s.time:.2f} s: lowest corner "
          f"{(lowest - top) * 1e3:+.2f} mm from the bed's top, its bottom's centre {(centre - top) * 1e3:+.2f} mm, "
          f"tilted {tilt:.1f} degrees, speed {speed * 1e3:.2f} mm/s, "
          f"{inside} grain(s) inside it at any frame")
    assert inside == 0, "a grain got inside the crate"
    assert lowest > top - 2.0 * RADIUS, "the crate sank into the bed"
    assert speed < 0.01, "the crate should be at rest"
    print("the crate landed on the bed and rests on top of it")


if __name__ == "__main__":
    tc.init(arch="cpu")
    main()
