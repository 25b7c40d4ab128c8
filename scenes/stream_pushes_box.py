"""A jet of sand pushes a box across the floor (docs/physics.md 7: rigid bodies and
particles, two-way: each grain's impulse on the box is the opposite of the box's on it).

A box (10 cm cube, 300 kg/m^3, 0.3 kg) stands on a floor (friction 0.4); a jet of 1,200
grains (r = 4 mm, 2,500 kg/m^3) at 4 m/s strikes its face above the centre for half a
second. The box slides away from the jet, then friction stops it; without the grains it
would stand still. Checked: it moved along the jet by more than 10 cm and stayed upright on
the floor, no grain ever got inside it, and the box's momentum along the jet never exceeded
what the grains brought.
Run it: `python scenes/stream_pushes_box.py` prints how far the box went.
"""

import numpy as np

import tai_coll as tc

RADIUS = 0.004      # m
SPEED = 4.0         # m/s, along +x
HALF = 0.05         # m, the box's half side
COUNT = 1200
FRAMES = 45         # 0.75 s at 60 frames per second


def jet_positions(rng) -> np.ndarray:
    """A jet 2 cm across, aimed at the box's face 2 cm above its centre, its grains spread
    over 0.5 s of flow (the farthest starts 2 m back)."""
    x = -0.12 - rng.uniform(0.0, SPEED * 0.5, COUNT)
    fall = 0.5 * 9.81 * ((-HALF - x) / SPEED) ** 2  # (so each arrives at the aimed height)
    y = HALF + 0.02 + fall + rng.uniform(-0.01, 0.01, COUNT)
    z = rng.uniform(-0.01, 0.01, COUNT)
    return np.column_stack([x, y, z])


def render_settings() -> dict:
    """For `tai-coll run`: from the side, the jet coming in from the left."""
    from tai_coll.render import Camera

    return {"camera": Camera(position=(0.2, 0.5, 1.6), look_at=(0.2, 0.05, 0.0), fov=45.0)}


def scene(seed: int = 0) -> tc.Scene:
    rng = np.random.default_rng(seed)
    s = tc.Scene(dt=1.0 / 1200.0, substeps=20)
    s.add_collider(tc.Plane(point=(0, 0, 0), normal=(0, 1, 0)), material=tc.Material(restitution=0.1, friction=0.4))
    s.add_body(tc.Box(center=(0.0, HALF, 0.0), half_extents=(HALF, HALF, HALF)), density=300.0,
               material=tc.Material(restitution=0.2, friction=0.4))
    s.add_particles(positions=jet_positions(rng), velocities=np.tile([SPEED, 0.0, 0.0], (COUNT, 1)),
                    radius=RADIUS, mass=2500.0 * 4.0 / 3.0 * np.pi * RADIUS ** 3)
    return s


def main():
    s = scene()
    box = s.bodies[0]
    start = box.position
    brought = float(np.sum(s.masses()) * SPEED)
    inside = 0
    most = 0.0
    for _ in range(FRAMES):
        s.step()
        local = (s.positions() - box.position) @ box.rotation
        inside = max(inside, int(np.all(np.abs(local) < HALF, axis=1).sum()))
        most = max(most, box.mass * float(box.velocity[0]))
    moved = box.position - start
    tilt = np.degrees(np.arccos(np.clip(box.rotation[1, 1], -1.0, 1.0)))  # of its up axis from the vertical
    print(f"box of {box.mass:.2f} kg pushed by {COUNT} grains ({brought:.3f} N s along x): moved "
          f"{moved[0] * 100:.1f} cm along the jet, {moved[2] * 100:+.1f} cm across it, tilted {tilt:.1f} degrees, "
          f"height {box.position[1] * 100:.2f} cm; most momentum {most:.3f} N s; {inside} grain(s) inside it")
    assert moved[0] > 0.1, "the jet should push the box along it"
    assert tilt < 5.0 and abs(box.position[1] - HALF) < 2e-3, "the box should stay upright on the floor"
    assert inside == 0, "a grain got inside the box"
    assert most <= brought, "the box cannot take more momentum than the grains brought"
    print("the jet pushed the box across the floor")


if __name__ == "__main__":
    tc.init(arch="cpu")
    main()
