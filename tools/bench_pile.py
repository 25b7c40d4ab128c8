"""Particles hitting particles: a pile settling in a box (the rows `tools/bench.py --pile` adds).

N particles of radius 5 mm start on a jittered lattice (spacing 2.3 r, about 54 layers) in
a box of five planes and fall into a pile, with particle-particle collisions on
(tai_coll.solvers.pairs) and the default ImpulseSolver; dt = 1/1000 s, 5 substeps per frame.
Every frame from the start is timed (kernels compiled beforehand on a small pile), so the
rates cover the fall, the impacts and, given enough frames, the dense pile:
- particle-steps per second over all timed frames (total), of the median frame, and of the
  median of the last quarter of the frames (the densest state reached);
- the hash grid's build on its own (counting sort plus neighbour lists, at the end state);
- overlap between particles at the end (mean and max, relative to the radius);
- the bytes per particle of every array the scene and its pair solver hold.
"""

import time

import numpy as np

RADIUS = 0.005
PILE_DT = 1.0 / 1000.0
PILE_SUBSTEPS = 5


def pile_positions(n: int, half: float, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    spacing = 2.3 * RADIUS
    g = np.arange(-half + 1.5 * RADIUS, half - 1.5 * RADIUS, spacing)
    layers = int(np.ceil(n / (len(g) ** 2))) + 1
    X, Y, Z = np.meshgrid(g, 2 * RADIUS + spacing * np.arange(layers), g, indexing="ij")
    x = np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1)
    x = x[np.argsort(x[:, 1], kind="stable")][:n]
    return x + rng.uniform(-0.1 * RADIUS, 0.1 * RADIUS, x.shape)


def pile_scene(tc, n: int, half: float | None = None):
    if half is None:
        half = max(0.1, 0.5 * np.sqrt(n / 100_000) * 0.5)
    scene = tc.Scene(dt=PILE_DT, substeps=PILE_SUBSTEPS)
    walls = [((0, 0, 0), (0, 1, 0)), ((-half, 0, 0), (1, 0, 0)), ((half, 0, 0), (-1, 0, 0)),
             ((0, 0, -half), (0, 0, 1)), ((0, 0, half), (0, 0, -1))]
    material = tc.Material(restitution=0.2, friction=0.4)
    for point, normal in walls:
        scene.add_collider(tc.Plane(point=point, normal=normal), material=material)
    scene.enable_particle_collisions(material=material)
    scene.add_particles(positions=pile_positions(n, half), radius=RADIUS)
    return scene


def state_bytes(scene) -> int:
    """Bytes of every per-particle array: the store, the pair solver's work arrays, the grid."""
    total = 0
    pairs = scene._pairs
    grid = pairs.grid
    particles = scene._particles
    arrays = [particles.x, particles.v, particles.mass, particles.radius, particles.flags, particles.clearance,
              pairs.x1, pairs.v1, pairs.v_start, pairs.delta, pairs.contacts] + grid.arrays()
    for a in arrays:
        total += a.to_numpy().nbytes
    return total


def compile_pile_kernels(tc):
    """Run a small pile until its particles touch, so that every kernel variant the pile
    uses is compiled (or loaded from the offline cache) before anything is timed."""
    scene = pile_scene(tc, 2000, half=0.03)
    scene.step(40)
    scene.particle_overlap()


def pile_case(tc, n: int, frames: int) -> dict:
    compile_pile_kernels(tc)
    scene = pile_scene(tc, n)
    times = []
    for _ in range(frames):
        t = time.perf_counter()
        scene.step(1)
        scene._particles.x.to_numpy()[:1]  # wait for the device
        times.append(time.perf_counter() - t)
    median = float(np.median(times))
    dense = float(np.median(times[-max(1, frames // 4):]))
    # the grid alone, on the current positions
    pairs = scene._pairs
    particles = scene._particles
    grid_times = []
    for _ in range(5):
        t = time.perf_counter()
        pairs.grid.build(particles.x, particles.radius, particles.flags, particles.count, 2.5 * RADIUS,
                         0.5 * RADIUS)
        pairs.grid.neighbour_count.to_numpy()[:1]
        grid_times.append(time.perf_counter() - t)
    overlap = scene.particle_overlap()
    v = scene.velocities()
    return {
        "case": "taichi impulse, pile (particle collisions)",
        "layout": "pile",
        "particles": n,
        "frames": frames,
        "simulated_s": scene.time,
        "frame_s": times,
        "median_frame_s": median,
        "particle_steps_per_s": n * PILE_SUBSTEPS * frames / float(np.sum(times)),
        "median_frame_particle_steps_per_s": n * PILE_SUBSTEPS / median,
        "last_quarter_particle_steps_per_s": n * PILE_SUBSTEPS / dense,
        "grid_build_s": float(np.median(grid_times)),
        "state_bytes_per_particle": state_bytes(scene) / n,
        "overlap_end": overlap,
        "kinetic_energy_per_particle_end_j": float(0.5 * np.mean(np.sum(v * v, axis=1))),
        "top_end_m": float(scene.positions()[:, 1].max()),
        "stats": scene.stats(),
    }
