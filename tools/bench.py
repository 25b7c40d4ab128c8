"""Benchmark: tai_coll's impulse and penalty solvers against the NumPy reference, in one process.

    python tools/bench.py                 # 1,000,000 particles, CPU, 2 threads, f32
    python tools/bench.py --quick         # 100,000 particles, a quick check
    python tools/bench.py --profile       # extra rows: f64, fewer colliders, 1 thread, ...

The scene: particles of radius 0.005 m, default material (e = 0.5, mu = 0.3), at rest at
random positions above and around a floor plane, a sphere and a rotated box, falling
under gravity ("falling"); dt = 1/600 s, 10 substeps per frame; the default ImpulseSolver
scheme (elastic_contact). A second pair of rows starts every particle within 2 mm above a
surface ("resting": contact-heavy). A particle-step is one particle advanced by one substep.
The penalty solver runs the same particles, colliders and dt: PenaltySolver(hertz=15),
critically damped (dt is 1.6x its recommended dt, inside the warning threshold; particles
rest 1.1 mm deep).

Reported:
- Taichi compile time of the step kernel (the first `step()`): cold, in a child process
  with an empty offline cache, then warm, in a second child reusing that cache; and as it
  came in this process (with the user's cache, usually warm);
- Taichi steady state: particle-steps per second from the median frame, the compile
  excluded (a small scene triggers it first; the kernels take arrays, so they serve any
  scene without compiling again);
- the NumPy reference (tools/numpy_reference.py) on the same initial state, in the same
  process, over the first frames only (it is slower), the speed-up over the same frames,
  and how far the two end states lie apart (f32 round-off makes a few particles diverge);
- bytes per particle: the state each side keeps between steps, and the NumPy reference's
  peak temporaries in one substep.

Every row of the table comes from a case: a function taking the prepared setup and
returning a dict of metrics. New solvers (penalty, particle-particle) add cases to CASES
(or PROFILE_CASES) and get their rows.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

TOOLS = Path(__file__).resolve().parent
ROOT = TOOLS.parent
sys.path.insert(0, str(TOOLS))
sys.path.insert(0, str(ROOT))

RADIUS = 0.005
DT = 1.0 / 600.0
SUBSTEPS = 10
PENALTY_HERTZ = 15.0  # contact frequency of the penalty rows (critically damped)


# ----------------------------------------------------------------------------- the scene
def collider_shapes(tc, which=("plane", "sphere", "box")):
    """The benchmark's colliders, none of them overlapping another."""
    shapes = {
        "plane": tc.Plane(point=(0.0, 0.0, 0.0), normal=(0.0, 1.0, 0.0)),
        "sphere": tc.Sphere(center=(-0.45, 0.35, 0.0), radius=0.3),
        "box": tc.Box(center=(0.45, 0.4, 0.0), half_extents=(0.2, 0.2, 0.2),
                      rotation=tc.rotation_matrix((0.3, 1.0, 0.2), 0.6)),
    }
    return [shapes[name] for name in which]


def initial_positions(tc, n: int, seed: int = 0) -> np.ndarray:
    """n points in [-1, 1] x [0.01, 1] x [-0.5, 0.5] m, clear of every collider by > r."""
    rng = np.random.default_rng(seed)
    shapes = collider_shapes(tc)
    out = np.empty((0, 3))
    while len(out) < n:
        m = int((n - len(out)) * 1.3) + 64
        x = np.column_stack([rng.uniform(-1.0, 1.0, m), rng.uniform(0.01, 1.0, m), rng.uniform(-0.5, 0.5, m)])
        clear = np.ones(m, bool)
        for s in shapes:
            clear &= s.signed_distance(x) > 1.2 * RADIUS
        out = np.concatenate([out, x[clear]])
    return out[:n]


def resting_positions(tc, n: int, seed: int = 0) -> np.ndarray:
    """A contact-heavy start: n points 0 to 2 mm above the surfaces, 60 % on the floor,
    20 % on the sphere's upper half and 20 % on the box's top face (particles may overlap
    each other: they do not collide with each other here)."""
    rng = np.random.default_rng(seed)
    _, sphere, box = collider_shapes(tc)
    n_sphere = n // 5
    n_box = n // 5
    lift = lambda m: RADIUS + rng.uniform(0.0, 2e-3, m)  # noqa: E731
    # sphere: directions in the upper half
    d = rng.normal(size=(n_sphere, 3))
    d[:, 1] = np.abs(d[:, 1])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    on_sphere = sphere.center + d * (sphere.radius + lift(n_sphere))[:, None]
    # box: its local top face (+y), then to the world
    h = box.half_extents
    local = np.column_stack([rng.uniform(-h[0], h[0], n_box), h[1] + lift(n_box), rng.uniform(-h[2], h[2], n_box)])
    on_box = box.center + local @ box.rotation.T
    # floor, clear of the sphere and the box
    floor = np.empty((0, 3))
    while len(floor) < n - n_sphere - n_box:
        m = int((n - n_sphere - n_box - len(floor)) * 1.3) + 64
        x = np.column_stack([rng.uniform(-1.0, 1.0, m), lift(m), rng.uniform(-0.5, 0.5, m)])
        clear = (sphere.signed_distance(x) > 1.2 * RADIUS) & (box.signed_distance(x) > 1.2 * RADIUS)
        floor = np.concatenate([floor, x[clear]])
    out = np.concatenate([floor[: n - n_sphere - n_box], on_sphere, on_box])
    return out[rng.permutation(n)]


def build_scene(tc, positions, colliders=("plane", "sphere", "box"), solver=None):
    scene = tc.Scene(dt=DT, substeps=SUBSTEPS, solver=solver)
    for shape in collider_shapes(tc, colliders):
        scene.add_collider(shape)  # default material
    scene.add_particles(positions=positions, radius=RADIUS)
    return scene


# ----------------------------------------------------------------------------- helpers
def rss_bytes() -> int:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def machine_info(args) -> dict:
    import taichi as ti

    from tai_coll import runtime

    started = runtime.info()

    cpu = platform.processor() or ""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    blas = None
    try:
        from threadpoolctl import threadpool_info

        blas = [{k: d.get(k) for k in ("internal_api", "num_threads", "version")} for d in threadpool_info()]
    except Exception:
        pass
    mem = None
    try:
        with open("/proc/meminfo") as f:
            mem = int(f.readline().split()[1]) * 1024
    except OSError:
        pass
    gpu = None
    if args.arch != "cpu" and shutil.which("nvidia-smi"):
        query = subprocess.run(["nvidia-smi", "--query-gpu=name,driver_version", "--format=csv,noheader"],
                               capture_output=True, text=True)
        gpu = query.stdout.strip() or None
    return {
        "cpu_model": cpu,
        "logical_cores": os.cpu_count(),
        "usable_cores": usable,
        "memory_bytes": mem,
        "os": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "taichi": ".".join(str(p) for p in ti.__version__),
        "blas_threadpools": blas,
        "arch_requested": args.arch,
        "gpu": gpu,
        "threads": args.threads if args.arch == "cpu" else None,
        # the CPU each of Taichi's workers was kept on (tai_coll.cpu_threads; [] when left free)
        "workers_pinned_to": [cpu for _, cpu in started.pinned_threads] if started else None,
    }


def frame_times(step, frames: int) -> list[float]:
    times = []
    for _ in range(frames):
        t0 = time.perf_counter()
        step()
        times.append(time.perf_counter() - t0)
    return times


def rate(n_particles: int, seconds: float) -> float:
    return n_particles * SUBSTEPS / seconds if seconds > 0 else float("nan")


# ----------------------------------------------------------------------------- Taichi side
def init_taichi(tc, args, precision="f32", threads=None):
    threads = args.threads if threads is None else threads
    info = tc.init(arch=args.arch, precision=precision, threads=threads if args.arch != "cuda" else None)
    return info


def compile_probe(args) -> dict:
    """Child-process mode: time the first and second step() of a small scene."""
    import tai_coll as tc
    import taichi as ti

    info = init_taichi(tc, args, precision=args.precision)
    scene = build_scene(tc, initial_positions(tc, 1000, seed=1))
    t0 = time.perf_counter()
    scene.step(1)
    ti.sync()
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    scene.step(1)
    ti.sync()
    second = time.perf_counter() - t0
    return {"first_step_s": first, "second_step_s": second, "arch": info.arch}


def measure_compile_cold_warm(args) -> dict:
    """Run compile_probe twice in child processes sharing one fresh offline-cache folder."""
    out = {}
    with tempfile.TemporaryDirectory(prefix="tai_coll_bench_cache_") as cache:
        env = dict(os.environ, TI_OFFLINE_CACHE="1", TI_OFFLINE_CACHE_FILE_PATH=cache)
        cmd = [sys.executable, str(Path(__file__).resolve()), "--compile-probe", "--arch", args.arch,
               "--threads", str(args.threads), "--precision", args.precision]
        for label in ("cold", "warm"):
            t0 = time.perf_counter()
            proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
            wall = time.perf_counter() - t0
            if proc.returncode != 0:
                out[label] = {"error": proc.stderr[-2000:]}
                continue
            line = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")][-1]
            result = json.loads(line)
            result["process_wall_s"] = wall
            out[label] = result
    return out


def taichi_case(setup, *, label="taichi impulse", layout="falling", precision=None, threads=None,
                colliders=None, frames=None, solver_factory=None, keep_state_after=None) -> dict:
    """Taichi: compile on a small scene, then time frames of the full scene."""
    import tai_coll as tc
    import taichi as ti

    args = setup["args"]
    precision = precision or args.precision
    colliders = colliders or setup["colliders"]
    frames = frames or args.frames
    threads = args.threads if threads is None else threads
    info = init_taichi(tc, args, precision=precision, threads=threads)
    solver = solver_factory(tc) if solver_factory else None
    positions = setup["layouts"][layout]
    small = build_scene(tc, positions[:1000], colliders, solver)
    t0 = time.perf_counter()
    small.step(1)
    ti.sync()
    compile_s = time.perf_counter() - t0
    del small

    rss0 = rss_bytes()
    scene = build_scene(tc, positions, colliders, solver_factory(tc) if solver_factory else None)
    rss1 = rss_bytes()
    # per slot: x, v (3 floats each), mass, radius, clearance (1 float each), the separating
    # plane (SEPARATION_SIZE floats: solvers/impulse.py), flags (i32)
    from tai_coll.scene.particles import SEPARATION_SIZE

    store = scene._particles
    state_bytes = store.capacity * ((9 + SEPARATION_SIZE) * np.dtype(info.float_dtype).itemsize + 4)

    def step():
        scene.step(1)
        ti.sync()

    times = []
    snapshot = None
    for f in range(frames):
        times += frame_times(step, 1)
        if keep_state_after is not None and f + 1 == keep_state_after:
            snapshot = scene.positions()
    n = scene.num_particles
    result = {
        "case": label,
        "layout": layout,
        "backend": f"taichi {info.arch}",
        "precision": precision,
        "threads": threads,
        "colliders": list(colliders),
        "particles": n,
        "frames": frames,
        "frame_s": times,
        "median_frame_s": float(np.median(times)),
        "particle_steps_per_s": rate(n, float(np.median(times))),
        "compile_first_step_s": compile_s,
        "state_bytes_per_particle": state_bytes / n,
        "rss_growth_bytes_per_particle": (rss1 - rss0) / n,
        "stats": scene.stats(),
        "in_contact_end": contact_fraction(tc, scene.positions(), colliders),
    }
    if snapshot is not None:
        result["_snapshot"] = snapshot
    del scene
    return result


def contact_fraction(tc, x, colliders, band=2e-3) -> float:
    """Fraction of particles within `band` m of touching a collider (phi < r + band)."""
    close = np.zeros(len(x), bool)
    for shape in collider_shapes(tc, colliders):
        close |= shape.signed_distance(x) < RADIUS + band
    return float(close.mean())


# ----------------------------------------------------------------------------- NumPy side
def numpy_reference(tc, positions, colliders, precision="f32", **options):
    """The NumPy reference for the benchmark scene, without building a Taichi scene."""
    from numpy_reference import NumpyImpulseReference, StaticCollider, solver_options

    dtype = np.float32 if precision == "f32" else np.float64
    shapes = [StaticCollider.from_shape(s, dtype=dtype) for s in collider_shapes(tc, colliders)]
    kwargs = dict(solver_options(tc.ImpulseSolver()), **options)
    return NumpyImpulseReference(colliders=shapes, positions=positions, radius=RADIUS, dt=DT,
                                 substeps=SUBSTEPS, dtype=dtype, **kwargs)


def numpy_case(setup, *, label="numpy reference", layout="falling", reuse_geometry=True, frames=None,
               compare_with=None) -> dict:
    """The NumPy reference on the same initial state as the Taichi scene, same precision."""
    import tai_coll as tc

    args = setup["args"]
    frames = frames or args.numpy_frames
    positions = setup["layouts"][layout]
    ref = numpy_reference(tc, positions, setup["colliders"], args.precision, reuse_geometry=reuse_geometry)
    n = ref.num_particles

    # peak temporaries of one substep, on a slice of the start (tracemalloc slows numpy a little)
    probe = numpy_reference(tc, positions[: min(n, 100_000)], setup["colliders"], args.precision,
                            reuse_geometry=reuse_geometry)
    probe.substep()
    tracemalloc.start()
    probe.substep()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    peak_per_particle = peak / probe.num_particles
    del probe

    times = frame_times(lambda: ref.step(1), frames)
    result = {
        "case": label,
        "layout": layout,
        "backend": "numpy",
        "precision": args.precision,
        "threads": 1,
        "colliders": list(setup["colliders"]),
        "particles": n,
        "frames": frames,
        "frame_s": times,
        "median_frame_s": float(np.median(times)),
        "particle_steps_per_s": rate(n, float(np.median(times))),
        "state_bytes_per_particle": ref.nbytes() / n,
        "peak_temp_bytes_per_particle": peak_per_particle,
        "stats": dict(ref.stats),
        "in_contact_end": contact_fraction(tc, ref.positions(), setup["colliders"]),
    }
    if compare_with is not None:
        d = np.linalg.norm(ref.positions() - compare_with, axis=1)
        result["agreement"] = {
            "after_frames": frames,
            "max_m": float(d.max()),
            "p99_m": float(np.percentile(d, 99)),
            "fraction_within_1e-5_m": float(np.mean(d <= 1e-5)),
            "fraction_within_1e-3_m": float(np.mean(d <= 1e-3)),
        }
    return result


# ----------------------------------------------------------------------------- cases
def penalty_solver(tc):
    return tc.PenaltySolver(hertz=PENALTY_HERTZ)


def falling_pair(setup):
    """The benchmark proper: Taichi, then NumPy from the same start over the first frames;
    the penalty solver on the same scene next to the impulse row."""
    k = setup["args"].numpy_frames
    taichi = taichi_case(setup, label="taichi impulse", keep_state_after=k)
    snapshot = taichi.pop("_snapshot", None)
    penalty = taichi_case(setup, label="taichi penalty", solver_factory=penalty_solver)
    numpy_row = numpy_case(setup, label="numpy reference", compare_with=snapshot)
    setup["speedups"]["falling"] = speedup(taichi, numpy_row)
    return [taichi, penalty, numpy_row]


def resting_pair(setup):
    """Contact-heavy: every particle starts within 2 mm of a surface."""
    k = setup["args"].numpy_frames
    taichi = taichi_case(setup, label="taichi impulse, resting", layout="resting", keep_state_after=k)
    snapshot = taichi.pop("_snapshot", None)
    penalty = taichi_case(setup, label="taichi penalty, resting", layout="resting", solver_factory=penalty_solver)
    numpy_row = numpy_case(setup, label="numpy reference, resting", layout="resting", compare_with=snapshot)
    setup["speedups"]["resting"] = speedup(taichi, numpy_row)
    return [taichi, penalty, numpy_row]


def speedup(taichi_row, numpy_row) -> dict:
    """Taichi over NumPy, both as medians over the same first frames from the same start."""
    k = numpy_row["frames"]
    taichi_rate = rate(taichi_row["particles"], float(np.median(taichi_row["frame_s"][:k])))
    return {"frames": k, "taichi_rate": taichi_rate, "numpy_rate": numpy_row["particle_steps_per_s"],
            "ratio": taichi_rate / numpy_row["particle_steps_per_s"],
            "ratio_taichi_all_frames": taichi_row["particle_steps_per_s"] / numpy_row["particle_steps_per_s"]}


# Each case takes the setup and returns a list of rows (dicts of metrics).
CASES = [falling_pair, resting_pair]


def profile_cases(args):
    """Where the Taichi kernel's time goes: rows that vary one thing at a time."""
    short = max(3, args.frames // 2)
    cases = [
        lambda s: taichi_case(s, label="taichi, 1 thread", threads=1, frames=short),
        lambda s: taichi_case(s, label="taichi, resting, 1 thread", layout="resting", threads=1, frames=short),
        lambda s: taichi_case(s, label="taichi, f64", precision="f64", frames=short),
        lambda s: taichi_case(s, label="taichi, plane only", colliders=("plane",), frames=short),
        lambda s: taichi_case(s, label="taichi, plane + sphere", colliders=("plane", "sphere"), frames=short),
        lambda s: taichi_case(s, label="taichi, scheme=simple", frames=short,
                              solver_factory=lambda tc: tc.ImpulseSolver(scheme="simple")),
        lambda s: taichi_case(s, label="taichi, resting, plane only", layout="resting", colliders=("plane",),
                              frames=short),
        lambda s: numpy_case(s, label="numpy, no geometry reuse", reuse_geometry=False),
        lambda s: numpy_case(s, label="numpy, resting, no reuse", layout="resting", reuse_geometry=False),
    ]
    return [lambda s, c=c: [c(s)] for c in cases]


# ----------------------------------------------------------------------------- report
def print_table(rows, compile_info, speedups, machine):
    print()
    print(f"machine: {machine['cpu_model']}, {machine['usable_cores']} usable cores, {machine['os']}")
    print(f"python {machine['python']}, numpy {machine['numpy']}, taichi {machine['taichi']}, "
          f"arch {machine['arch_requested']}, threads {machine['threads']}")
    if machine.get("gpu"):
        print(f"gpu: {machine['gpu']}")
    print()
    head = f"{'case':<30} {'prec':>4} {'thr':>3} {'particles':>10} {'frames':>6} {'median frame s':>14} " \
           f"{'Mparticle-steps/s':>18} {'state B/p':>9} {'in contact':>10}"
    print(head)
    print("-" * len(head))
    for r in rows:
        print(f"{r['case']:<30} {r['precision']:>4} {r['threads']:>3} {r['particles']:>10,} {r['frames']:>6} "
              f"{r['median_frame_s']:>14.4f} {r['particle_steps_per_s'] / 1e6:>18.2f} "
              f"{r['state_bytes_per_particle']:>9.1f} {100 * r['in_contact_end']:>9.1f}%")
    print()
    if compile_info:
        for label in ("cold", "warm"):
            c = compile_info.get(label, {})
            if "first_step_s" in c:
                print(f"taichi compile (first step, {label} offline cache, child process): "
                      f"{c['first_step_s']:.2f} s  (second step {c['second_step_s'] * 1e3:.1f} ms)")
            elif c:
                print(f"taichi compile ({label}): failed: {c.get('error', '')[-300:]}")
    if rows and "compile_first_step_s" in rows[0]:
        print(f"taichi compile (first step, this process, default cache): {rows[0]['compile_first_step_s']:.2f} s")
    print()
    for r in rows:
        if "peak_temp_bytes_per_particle" in r:
            print(f"{r['case']}: peak temporaries in one substep "
                  f"{r['peak_temp_bytes_per_particle']:.0f} B/particle")
        if "agreement" in r:
            a = r["agreement"]
            print(f"{r['case']} vs taichi after {a['after_frames']} frames: max {a['max_m']:.2e} m, "
                  f"p99 {a['p99_m']:.2e} m, within 1e-5 m: {100 * a['fraction_within_1e-5_m']:.2f}%")
    for layout, sp in speedups.items():
        # issue 2's target (20x) is set on the falling scene; the resting layout is an extra row
        target = f"target 20x: {'met' if sp['ratio'] >= 20 else 'NOT met'}" if layout == "falling" else "no target"
        print(f"speed-up ({layout}), taichi / numpy over the same first {sp['frames']} frames: "
              f"{sp['taichi_rate'] / 1e6:.2f} / {sp['numpy_rate'] / 1e6:.2f} M/s = {sp['ratio']:.2f}x ({target})")


def print_pile_table(rows):
    print()
    head = f"{'pile (particle collisions)':<48} {'particles':>10} {'dt ms':>5} {'sim s':>5} {'M p-steps/s':>11} " \
           f"{'median fr.':>10} {'last 1/4':>8} {'sim s/s':>7} {'grid ms':>7} {'B/part.':>7} {'overlap mean/max':>17}"
    print(head)
    print("-" * len(head))
    for r in rows:
        o = r["overlap_end"]
        print(f"{'taichi ' + r['variant'] + ', ' + r['precision']:<48} {r['particles']:>10,} {r['dt'] * 1e3:>5.2f} "
              f"{r['simulated_s']:>5.2f} {r['particle_steps_per_s'] / 1e6:>11.2f} "
              f"{r['median_frame_particle_steps_per_s'] / 1e6:>10.2f} "
              f"{r['last_quarter_particle_steps_per_s'] / 1e6:>8.2f} {r['simulated_s_per_wall_s']:>7.4f} "
              f"{r['grid_build_s'] * 1e3:>7.1f} {r['state_bytes_per_particle']:>7.0f} "
              f"{100 * o['mean']:>7.1f}% / {100 * o['max']:>5.1f}%")
    print("(M p-steps/s: over all timed frames; median fr.: of the median frame; last 1/4: of the median "
          "frame of the last quarter, the densest state reached; sim s/s: simulated seconds per second; "
          "grid: sort + neighbour lists (impulse, jacobi, -lists: built only when they no longer hold), "
          "sort alone (the other dem variants))")
    for r in rows:
        if r.get("list_builds") and r["variant"].endswith("-lists"):
            print(f"{r['variant']}, {r['particles']:,}: lists built in {r['list_builds']:,} of "
                  f"{r['frames'] * r['substeps']:,} substeps")
        twin = next((t for t in rows if t["variant"] + "-lists" == r["variant"] and t["particles"] == r["particles"]),
                    None)
        if twin is not None:
            print(f"{r['variant']}, {r['particles']:,}: "
                  f"{r['particle_steps_per_s'] / twin['particle_steps_per_s']:.2f}x the particle-steps/s of "
                  f"{twin['variant']} (the grid sorted and queried every substep; same process, same frames)")
    for r in rows:
        if "speedup_over_no_reorder" in r:
            print(f"pile of {r['particles']:,} added in random order: reordering the store by cell "
                  f"{r['speedup_over_no_reorder']:.2f}x faster than without (same process, same frames)")
        elif r["particles"] == 100_000 and not r.get("shuffled"):
            rate = r["particle_steps_per_s"]
            print(f"pile of 100,000, {r['variant']}, over {r['simulated_s']:.2f} s from the drop: "
                  f"{rate / 1e6:.2f} M particle-steps/s (target 5 M: {'met' if rate >= 5e6 else 'NOT met'})")


def count(low: int = 1):
    """An argparse type: a whole number of at least `low` (argparse then names the option in
    its error: "argument --frames: give 1 or more; got 0")."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number; got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"give {low} or more; got {value}")
        return value
    return parse


def seconds(text: str) -> float:
    """An argparse type: a finite time in seconds above zero."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds; got {text!r}") from None
    if not 0.0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"give a time above 0 s; got {text}")
    return value


def report_path(parser, option: str, path) -> Path:
    """The report file a tool was given with `option`, refused before anything runs (through
    parser.error: the usage, the message and exit status 2) where no file can be written: a
    directory, or a path under a file. A benchmark that ran for minutes then could not write
    its report would lose its figures."""
    path = Path(path)
    if path.is_dir():
        parser.error(f"{option}: {path} is a directory; give the report's file path (a .json file)")
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                parser.error(f"{option}: {parent} is a file, so no report can be written at {path}")
            break
    return path


def write_json(path, report) -> Path:
    """Write a benchmark report atomically (a temporary file moved into place; removed if the
    writing or the move fails, so that nothing half-written is left)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    try:
        tmp.write_text(json.dumps(report, indent=2, default=float))
        tmp.replace(path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--particles", type=count(), default=1_000_000)
    parser.add_argument("--frames", type=count(), default=10, help="Taichi frames timed (after compile)")
    parser.add_argument("--numpy-frames", type=count(), default=3, help="NumPy frames timed, from the same start")
    parser.add_argument("--arch", default="cpu", choices=("cpu", "cuda", "auto"))
    parser.add_argument("--threads", type=count(), default=2, help="Taichi CPU threads")
    parser.add_argument("--precision", default="f32", choices=("f32", "f64"),
                        help="precision of both sides (Taichi's default is f32)")
    parser.add_argument("--json", default=None,
                        help="report path (default bench_results/bench.json, bench_pile.json with --pile-only)")
    parser.add_argument("--quick", action="store_true", help="100,000 particles, fewer frames")
    parser.add_argument("--profile", action="store_true", help="extra rows to see where the time goes")
    parser.add_argument("--no-compile-probe", action="store_true", help="skip the cold/warm child processes")
    parser.add_argument("--compile-probe", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--pile", action="store_true",
                        help="also particle-particle collisions: piles of 100,000 and 1,000,000 particles "
                             "(100,000 only with --quick) settling in a box (tools/bench_pile.py)")
    parser.add_argument("--pile-only", action="store_true", help="only the pile rows")
    parser.add_argument("--pile-seconds", type=seconds, default=0.5,
                        help="simulated seconds timed from the drop, pile of 100,000 (0.5: fall to dense pile)")
    parser.add_argument("--pile-seconds-1m", type=seconds, default=0.06,
                        help="simulated seconds timed from the drop, pile of 1,000,000 (0.06: the fall and first "
                             "impacts)")
    parser.add_argument("--pile-variants", default="impulse,jacobi,dem,reorder",
                        help="comma-separated pile variants: impulse (default solver: Gauss-Seidel pair passes), "
                             "jacobi (the same, Jacobi passes), dem (penalty pairs), dem-springs (the same with "
                             "tangential springs), dem-rolling (springs, spinning particles, rolling resistance; "
                             "these two not in the default list), any dem variant with -lists (dem-lists, "
                             "dem-springs-lists, dem-rolling-lists: the DEM kernel on Verlet lists, skin 0.5 r, "
                             "instead of the grid sorted every substep), "
                             "reorder (100,000 only: the impulse pile added in random order, the store's "
                             "reordering by cell off, then on)")
    parser.add_argument("--pile-seconds-reorder", type=seconds, default=0.2,
                        help="simulated seconds timed from the drop for the reorder rows")
    args = parser.parse_args(argv)
    args.pile = args.pile or args.pile_only
    args.pile_variants = [v.strip() for v in args.pile_variants.split(",") if v.strip()]
    from bench_pile import VARIANTS

    unknown = sorted(set(args.pile_variants) - set(VARIANTS) - {"reorder"})
    if unknown or not args.pile_variants:
        parser.error(f"--pile-variants must list some of {', '.join(VARIANTS)}, reorder; got {unknown or 'nothing'}")
    if args.json is None:
        args.json = str(ROOT / "bench_results" / ("bench_pile.json" if args.pile_only else "bench.json"))
    report_path(parser, "--json", args.json)

    if args.compile_probe:
        print(json.dumps(compile_probe(args)))
        return 0
    if args.quick:
        args.particles = min(args.particles, 100_000)
        args.frames = min(args.frames, 5)
        args.numpy_frames = min(args.numpy_frames, 2)
        args.pile_seconds = min(args.pile_seconds, 0.1)
    if args.numpy_frames > args.frames:
        args.frames = args.numpy_frames

    compile_info = {} if args.no_compile_probe else measure_compile_cold_warm(args)

    import tai_coll as tc

    init_taichi(tc, args, precision=args.precision)
    setup = {"args": args, "colliders": ("plane", "sphere", "box"), "speedups": {},
             "layouts": {"falling": initial_positions(tc, args.particles),
                         "resting": resting_positions(tc, args.particles)}}
    machine = machine_info(args)

    rows = []
    for case in ([] if args.pile_only else CASES + (profile_cases(args) if args.profile else [])):
        for row in case(setup):
            rows.append(row)
            print(f"  done: {row['case']} ({row['particle_steps_per_s'] / 1e6:.2f} M particle-steps/s)",
                  flush=True)

    pile_rows = []
    if args.pile:
        from bench_pile import pile_case, reorder_cases

        for n in ((100_000,) if args.quick else (100_000, 1_000_000)):
            for variant in args.pile_variants:
                if variant == "reorder":
                    if n > 100_000:
                        continue
                    new_rows = reorder_cases(tc, n, min(args.pile_seconds_reorder, args.pile_seconds))
                else:
                    new_rows = [pile_case(tc, n, args.pile_seconds if n <= 100_000 else args.pile_seconds_1m, variant)]
                for row in new_rows:
                    row.update(precision=args.precision, threads=args.threads)
                    pile_rows.append(row)
                    print(f"  done: pile of {n:,}, {row['variant']} "
                          f"({row['particle_steps_per_s'] / 1e6:.2f} M particle-steps/s)", flush=True)

    print_table(rows, compile_info, setup["speedups"], machine)
    if pile_rows:
        print_pile_table(pile_rows)
    rows += pile_rows

    config = {"particles": args.particles, "dt": DT, "substeps": SUBSTEPS, "radius": RADIUS, "frames": args.frames,
              "numpy_frames": args.numpy_frames, "precision": args.precision}
    report = {"machine": machine, "config": config, "compile": compile_info, "rows": rows,
              "speedup": setup["speedups"], "time": time.strftime("%Y-%m-%dT%H:%M:%S")}
    path = write_json(args.json, report)
    print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
