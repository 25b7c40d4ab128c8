"""Particles hitting particles: a pile settling in a box (the rows `tools/bench.py --pile` adds).

N particles of radius 5 mm start on a jittered lattice (spacing 2.3 r, about 54 layers) in
a box of five planes and fall into a pile, with particle-particle collisions on
(tai_coll.solvers.pairs), in these variants:
- impulse: the default ImpulseSolver, dt = 1/1000 s, 5 substeps per frame, pairs resolved
  by the default coloured Gauss-Seidel passes (1 contact + 2 projection);
- jacobi: the same with method="jacobi" (4 + 4 Jacobi passes): the baseline for the above;
- dem: the penalty variant (DEM spring-dashpots between particles, the model NVIDIA Warp's
  DEM example uses), PenaltySolver(hertz=200) critically damped (a 1 m/s impact sinks
  0.8 mm, 16 % of the radius; a particle rests 6 um deep per layer above it), at its
  recommended dt = 75 us: 13 times the steps of the impulse variant for the same time;
- dem-springs: the same with friction by tangential springs (tangential_springs=True:
  static friction that holds a contact without creeping);
- dem-rolling: dem-springs with particles that spin (PenaltySolver(spin=True)) and
  rolling resistance (rolling_friction=ROLLING_FRICTION, a rolling spring per contact):
  grains that roll and topple, and stop;
- any DEM variant with "-lists" (dem-lists, dem-springs-lists, dem-rolling-lists): the same
  with the force kernel reading Verlet lists (verlet_skin=DEM_SKIN radii: pairs within
  r_i + r_j + skin, rebuilt from the grid once some particle has moved half the skin) instead
  of querying the grid, sorted anew, every substep.
Every frame from the start is timed (kernels compiled beforehand on a small pile), so the
rates cover the fall, the impacts and, given enough frames, the dense pile:
- particle-steps per second over all timed frames (total), of the median frame, and of the
  median of the last quarter of the frames (the densest state reached);
- the hash grid's build on its own at the end state: the counting sort plus the neighbour
  lists (impulse), the counting sort alone (dem: its force kernel queries the grid itself);
- overlap between particles at the end (mean and max, relative to the radius);
- the bytes per particle of every array the scene and its pair solver hold.
The reordering of the store by cell (tai_coll.solvers.pairs, on by default) is measured on
its own by `reorder_cases`: the impulse pile with its particles added in random order,
without and then with it.
"""

import time

import numpy as np

RADIUS = 0.005
SUBSTEPS = 5
DT = {"impulse": 1.0 / 1000.0, "jacobi": 1.0 / 1000.0, "dem": 7.5e-5, "dem-springs": 7.5e-5, "dem-rolling": 7.5e-5}
DEM_HERTZ = 200.0
ROLLING_FRICTION = 0.1  # dem-rolling's mu_r (particles and walls): a lever arm of 0.1 r
DEM_SKIN = 0.5  # the "-lists" variants' skin, in radii (2.5 mm)
VARIANTS = ("impulse", "jacobi", "dem", "dem-springs", "dem-rolling", "dem-lists", "dem-springs-lists",
            "dem-rolling-lists")


def base_variant(variant: str) -> str:
    """The variant without its "-lists" (the model; the lists only change how pairs are found)."""
    return variant[: -len("-lists")] if variant.endswith("-lists") else variant


def pile_positions(n: int, half: float, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    spacing = 2.3 * RADIUS
    g = np.arange(-half + 1.5 * RADIUS, half - 1.5 * RADIUS, spacing)
    layers = int(np.ceil(n / (len(g) ** 2))) + 1
    X, Y, Z = np.meshgrid(g, 2 * RADIUS + spacing * np.arange(layers), g, indexing="ij")
    x = np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1)
    x = x[np.argsort(x[:, 1], kind="stable")][:n]
    return x + rng.uniform(-0.1 * RADIUS, 0.1 * RADIUS, x.shape)


def pile_half(n: int) -> float:
    """Half the box's width for n particles: the box grows with n, the depth stays ~54 layers."""
    return float(max(0.1, 0.5 * np.sqrt(n / 100_000) * 0.5))


def pile_scene(tc, n: int, half: float | None = None, variant: str = "impulse", *, shuffled: bool = False,
               reorder: bool = True):
    """The pile; shuffled: the particles added in random order (not layer by layer);
    reorder: the pair solver's reordering of the store by cell (on by default)."""
    if half is None:
        half = pile_half(n)
    lists = variant.endswith("-lists")
    variant = base_variant(variant)
    spin = variant == "dem-rolling"
    solver = tc.PenaltySolver(hertz=DEM_HERTZ, spin=spin) if variant.startswith("dem") else None
    scene = tc.Scene(dt=DT[variant], substeps=SUBSTEPS, solver=solver)
    walls = [((0, 0, 0), (0, 1, 0)), ((-half, 0, 0), (1, 0, 0)), ((half, 0, 0), (-1, 0, 0)),
             ((0, 0, -half), (0, 0, 1)), ((0, 0, half), (0, 0, -1))]
    material = tc.Material(restitution=0.2, friction=0.4, rolling_friction=ROLLING_FRICTION if spin else 0.0)
    for point, normal in walls:
        scene.add_collider(tc.Plane(point=point, normal=normal), material=material)
    method = {"dem": {}, "dem-springs": {"tangential_springs": True}, "dem-rolling": {"tangential_springs": True},
              "jacobi": {"method": "jacobi"}}.get(variant, {"method": "gauss-seidel"})
    if lists:
        method = dict(method, verlet_skin=DEM_SKIN * RADIUS)
    scene.enable_particle_collisions(material=material, reorder=reorder, **method)
    x = pile_positions(n, half)
    if shuffled:
        x = np.random.default_rng(1).permutation(x)
    scene.add_particles(positions=x, radius=RADIUS)
    return scene


def state_bytes(scene) -> int:
    """Bytes of every per-particle array: the store, the pair solver's work arrays, the grid."""
    return scene.state_nbytes()


def warmup_particles() -> int:
    """Particles in a warm-up scene: more than tai_coll launches serial kernels for at any
    thread count (tai_coll/serial_loops.py). A scene at or below that limit compiles the
    kernels' serial variants, which a large scene never launches: a 2,000-particle warm-up
    left twelve kernels to compile in the 100k pile's first timed frame (2.3 to 4 s of it)."""
    from tai_coll import serial_loops

    return serial_loops.SERIAL_WORK + 1


def compile_pile_kernels(tc, variant: str):
    """Run a pile of warmup_particles() until its particles touch, so that every kernel
    variant the pile uses is compiled (or loaded from the offline cache) before anything is
    timed."""
    scene = pile_scene(tc, warmup_particles(), variant=variant)
    scene.step(int(round(0.1 / (SUBSTEPS * DT[base_variant(variant)]))))
    scene.particle_overlap()


def grid_build_s(scene) -> float:
    """The grid on its own, on the current positions: what a substep that builds it builds (the
    DEM kernel querying the grid: the sort alone, every substep; the others: the sort and the
    neighbour lists, every substep or, with a skin, when the lists no longer hold)."""
    import taichi as ti

    pairs = scene.particle_collisions
    settings = pairs.settings
    x, radius, flags = scene_arrays(scene)
    n = scene.num_particles
    dem = scene.solver.pair_model == "dem"
    times = []
    for _ in range(5):
        t = time.perf_counter()
        if dem and settings.verlet_skin == 0.0:
            pairs.grid.sort(x, radius, flags, n, 2 * RADIUS)
        else:
            reach = (0.0 if dem else settings.margin_length(RADIUS)) + settings.skin_length(RADIUS)
            pairs.grid.build(x, radius, flags, n, 2 * RADIUS + reach, reach, forward=pairs.forward_lists and not dem)
        ti.sync()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def scene_arrays(scene):
    """The store's positions, radii and flags as kernels take them (for timing the grid alone)."""
    store = scene._particles
    return store.x, store.radius, store.flags


def pile_case(tc, n: int, simulated_s: float, variant: str = "impulse", *, shuffled: bool = False,
              reorder: bool = True) -> dict:
    import taichi as ti

    compile_pile_kernels(tc, variant)
    scene = pile_scene(tc, n, variant=variant, shuffled=shuffled, reorder=reorder)
    dt = DT[base_variant(variant)]
    frames = int(round(simulated_s / (SUBSTEPS * dt)))
    times = []
    for _ in range(frames):
        t = time.perf_counter()
        scene.step(1)
        ti.sync()
        times.append(time.perf_counter() - t)
    median = float(np.median(times))
    dense = float(np.median(times[-max(1, frames // 4):]))
    grid_s = grid_build_s(scene)
    builds = scene.particle_collisions.list_builds
    nbytes = state_bytes(scene)
    overlap = scene.particle_overlap()
    v = scene.velocities()
    label = variant + (f", random order, reorder {'on' if reorder else 'off'}" if shuffled else "")
    return {
        "case": f"taichi {label}, pile (particle collisions)",
        "variant": label,
        "shuffled": shuffled,
        "reorder": reorder,
        "layout": "pile",
        "particles": n,
        "dt": dt,
        "frames": frames,
        "substeps": SUBSTEPS,
        "simulated_s": scene.time,
        "frame_s": times,
        "median_frame_s": median,
        "particle_steps_per_s": n * SUBSTEPS * frames / float(np.sum(times)),
        "median_frame_particle_steps_per_s": n * SUBSTEPS / median,
        "last_quarter_particle_steps_per_s": n * SUBSTEPS / dense,
        "simulated_s_per_wall_s": scene.time / float(np.sum(times)),
        "grid_build_s": grid_s,
        "list_builds": builds,  # substeps that built neighbour lists (the DEM kernel on the grid: none)
        "state_bytes_per_particle": nbytes / n,
        "overlap_end": overlap,
        "kinetic_energy_per_particle_end_j": float(0.5 * np.mean(np.sum(v * v, axis=1))),
        "top_end_m": float(scene.positions()[:, 1].max()),
        "stats": scene.stats(),
    }


def reorder_cases(tc, n: int, simulated_s: float) -> list:
    """The impulse pile with particles added in random order: reordering off (the baseline),
    then on; the second row carries the speed-up."""
    rows = [pile_case(tc, n, simulated_s, "impulse", shuffled=True, reorder=reorder) for reorder in (False, True)]
    rows[1]["speedup_over_no_reorder"] = rows[1]["particle_steps_per_s"] / rows[0]["particle_steps_per_s"]
    return rows
