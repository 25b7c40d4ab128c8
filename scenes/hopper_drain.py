"""Grains poured into a hopper drain through its opening into a sink (docs/physics.md 8:
emitters, sinks and ids).

An emitter above a square hopper (four plates at 55 degrees, an opening 6 cm across) pours
1,500 grains a second (r = 4 mm, 2,500 kg/m^3) for a second; they collide with each other and
the plates (impulses, Gauss-Seidel pairs), flow through the opening and fall into a sink 20 cm
below it, which removes them. Checked: the emitter placed rate x time grains (within 10 %;
it found room for all), the count is always emitted - removed, removed ids never come back and
the others stay in ascending order, no grain ever got inside a plate, and no grain reached
the sink sooner than free fall from the emitter allows.
Run it: `python scenes/hopper_drain.py`; `tai-coll run scenes/hopper_drain.py --export ply,usd`
writes every frame's grains for Blender or Houdini.
"""

import numpy as np

import tai_coll as tc

RADIUS = 0.004       # m
RATE = 1500.0        # grains per second
POUR = 1.0           # s of pouring
OPENING = 0.03       # m, half the hopper's opening
TOP = 0.2            # m, the height of the opening
SLOPE = np.radians(55.0)
PLATE = (0.09, 0.004, 0.13)  # half length along the slope, half thickness, half width (m)
EMITTER = tc.Cylinder(center=(0.0, 0.36, 0.0), radius=0.05, half_height=0.01)
EMIT_SPEED = 0.5     # m/s, downward
SINK_TOP = 0.0       # m: grains whose centre falls below this are removed
FRAMES = 80          # 1.33 s at 60 frames per second


def plates() -> list:
    """Four plates sloping up and out from the opening's edges."""
    up_slope = np.array([np.cos(SLOPE), np.sin(SLOPE), 0.0])
    inward = np.array([-np.sin(SLOPE), np.cos(SLOPE), 0.0])
    rotation = np.column_stack([up_slope, inward, [0.0, 0.0, 1.0]])
    center = np.array([OPENING, TOP, 0.0]) + PLATE[0] * up_slope - PLATE[1] * inward
    out = []
    for k in range(4):
        turn = tc.rotation_matrix((0.0, 1.0, 0.0), k * np.pi / 2)
        out.append(tc.Box(center=turn @ center, half_extents=PLATE, rotation=turn @ rotation))
    return out


def render_settings() -> dict:
    from tai_coll.render import Camera

    return {"camera": Camera(position=(0.42, 0.5, 0.55), look_at=(0.0, 0.17, 0.0), fov=45.0), "color_by": "speed"}


def scene() -> tc.Scene:
    s = tc.Scene()
    wall = tc.Material(restitution=0.2, friction=0.3)
    for plate in plates():
        s.add_collider(plate, material=wall)
    s.enable_particle_collisions(material=tc.Material(restitution=0.2, friction=0.3))
    s.add_emitter(EMITTER, rate=RATE, stop=POUR, radius=RADIUS, mass=2500.0 * 4.0 / 3.0 * np.pi * RADIUS ** 3,
                  velocity=(0.0, -EMIT_SPEED, 0.0), seed=1)
    s.add_sink(tc.Box(center=(0.0, SINK_TOP - 0.5, 0.0), half_extents=(2.0, 0.5, 2.0)))
    return s


def main():
    s = scene()
    emitter = s.emitters[0]
    walls = plates()
    removed, deepest, first_removal = set(), 0.0, None
    previous = np.zeros(0, dtype=np.int64)
    for _ in range(FRAMES):
        s.step()
        ids = s.ids()
        gone = set(np.setdiff1d(previous, ids).tolist())
        if gone and first_removal is None:
            first_removal = s.time
        assert not (removed & set(ids.tolist())), "a removed id came back"
        assert np.all(np.diff(ids) > 0), "ids must stay in ascending order"
        removed |= gone
        previous = ids
        stats = s.stats()
        assert s.num_particles == stats["emitted"] - stats["removed"]
        x = s.positions()
        if len(x):
            deepest = max(deepest, max(float(np.max(RADIUS - w.signed_distance(x))) for w in walls))
    stats = s.stats()
    # the lowest a grain starts is the emitter's bottom, at EMIT_SPEED downward
    drop = EMITTER.center[1] - EMITTER.half_height - SINK_TOP
    fall = (-EMIT_SPEED + np.sqrt(EMIT_SPEED ** 2 + 2 * 9.81 * drop)) / 9.81
    print(f"emitted {stats['emitted']} grains ({stats['emission_skipped']} found no room), {stats['removed']} drained "
          f"into the sink (the first at t = {first_removal:.3f} s; free fall allows {fall:.3f} s), "
          f"{s.num_particles} left in the hopper; deepest into a plate {deepest * 1e3:.2f} mm (overlap of its radius)")
    assert abs(stats["emitted"] - RATE * POUR) <= 0.1 * RATE * POUR, "the emitter should place rate x time grains"
    assert stats["removed"] > 0.5 * stats["emitted"], "most grains should have drained through the opening"
    assert first_removal >= fall - s.dt, "no grain can reach the sink sooner than free fall"
    assert len(removed) == stats["removed"]
    assert deepest <= 0.25 * RADIUS, "a grain got into a plate"
    print("the hopper drained into the sink")


if __name__ == "__main__":
    tc.init(arch="cpu")
    main()
