"""A random pour: particles spawned at random, overlapping, in a box above a mesh ball.

3,000 particles of radius 6 mm are placed at uniform random in a 20 cm box whose bottom is
20 cm above a triangle-mesh ball (trimesh's icosphere) standing on a floor: nine in ten of
them overlap a neighbour, some by more than a radius. The overlap is removed by positions at
no more than `max_push_speed` (docs/physics.md 5.2.1), never turned into speed, so the cloud
falls as a cloud, pours over the ball and spreads on the floor, where the pile falls asleep
(docs/physics.md 5.3.1). The check after every frame: no particle climbs above the top of
the spawn box by more than a push out of its overlap can lift it (a radius and the height
max_push_speed reaches), none moves faster than a free fall from it allows.
Run it: `python scenes/random_pour.py` (impulses, the default solver) or
`python scenes/random_pour.py dem` (DEM pairs, with substeps="auto" picking the substep); for
`tai-coll run scenes/random_pour.py` set TAI_COLL_POUR_SOLVER=dem for the DEM version.
"""

import os
import sys

import numpy as np
import trimesh

import tai_coll as tc

RADIUS = 0.006   # m
COUNT = 3000
BALL = 0.1       # m, the mesh ball's radius
SPAWN = 0.2      # m, the spawn box's side
BOTTOM = 2 * BALL + 0.2  # m, the spawn box's bottom
FRAMES = 90      # 1.5 s at 60 frames per second
MATERIAL = tc.Material(restitution=0.3, friction=0.5)


def solver_name(solver=None) -> str:
    """The solver asked for: the argument, else TAI_COLL_POUR_SOLVER, else "impulse"."""
    return solver or os.environ.get("TAI_COLL_POUR_SOLVER", "impulse")


def scene(solver=None) -> tc.Scene:
    solver = solver_name(solver)
    if solver not in ("impulse", "dem"):
        raise ValueError(f"solver must be 'impulse' or 'dem'; got {solver!r}")
    if solver == "dem":
        s = tc.Scene(substeps="auto", frame_dt=1 / 60, solver=tc.PenaltySolver(hertz=200.0))
    else:
        s = tc.Scene()
    s.add_collider(tc.Plane(), material=MATERIAL)
    ball = trimesh.creation.icosphere(subdivisions=3, radius=BALL)
    ball.apply_translation((0.0, BALL, 0.0))
    s.add_collider(tc.TriangleMesh(ball), material=MATERIAL)
    s.enable_particle_collisions(material=MATERIAL)
    rng = np.random.default_rng(0)
    low = np.array([-0.5 * SPAWN, BOTTOM, -0.5 * SPAWN])
    s.add_particles(positions=low + rng.uniform(0.0, SPAWN, (COUNT, 3)), radius=RADIUS)
    return s


def main(solver=None):
    solver = solver_name(solver)
    s = scene(solver)
    top = BOTTOM + SPAWN
    g = float(np.linalg.norm(s.gravity))
    push = s.particle_collisions.settings.max_push_speed
    # a particle pushed out of an overlap by positions may end a radius above where it was
    # placed, and leave at up to the push speed
    ceiling = top + 2 * RADIUS + push ** 2 / (2 * g)
    highest, fastest = 0.0, 0.0
    for frame in range(FRAMES):
        s.step()
        x, v = s.positions(), np.linalg.norm(s.velocities(), axis=1)
        # free fall from the spawn top to a particle's height, plus the push speed and round-off
        allowed = np.sqrt(2.0 * g * np.maximum(top - x[:, 1], 0.0)) + push + 0.1
        assert x[:, 1].max() <= ceiling, f"frame {frame}: a particle climbed to {x[:, 1].max():.3f} m"
        assert np.all(v <= allowed), f"frame {frame}: {np.sum(v > allowed)} particle(s) faster than free fall"
        highest, fastest = max(highest, float(x[:, 1].max())), max(fastest, float(v.max()))
    print(f"{COUNT} particles poured from a random, overlapping spawn ({solver}): highest {highest:.3f} m "
          f"(spawn top {top:.3f} m), fastest {fastest:.2f} m/s, {int(s.sleeping().sum())} asleep after "
          f"{s.time:.2f} s")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
