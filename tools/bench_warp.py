"""Benchmark: tai_coll against NVIDIA Warp on the same machine, in one invocation, where
particles are in contact (issue 23). Warp (`warp-lang`) is a benchmark-only extra:
`pip install 'tai_coll[bench]'`; tai_coll never imports it.

    python tools/bench_warp.py                         # both rows: a 1M layer, a 100k bed (CPU)
    python tools/bench_warp.py --rows layer --layer-particles 200000
    python tools/bench_warp.py --arch cuda --layer-particles 10000000

Rows (r = 5 mm, dt = 1/600 s, e = 0.5, mu = 0.3, f32, particle-steps per second):
- layer: N particles at rest in a layer 0 to 2 cm above a floor plane, 10 substeps a frame.
  tai_coll: a Scene with the plane and the default ImpulseSolver. Warp: one kernel a step:
  gravity (symplectic Euler), the particle put back on the plane, the restitution law on the
  normal velocity and Coulomb friction on the tangential one (the same 1-D impulse law).
- bed: 100,000 particles on a jittered lattice 2.2 r apart, 6 layers deep, in a box (floor
  and four walls); 300 steps to settle, then 100 timed. tai_coll: enable_particle_collisions()
  (Gauss-Seidel impulses, the default). Warp: position-based Jacobi on `wp.HashGrid`
  (predict, the grid on the predicted positions, 4 Jacobi passes each moving a particle by the
  mean of its contacts' half-overlaps and out of the walls, then the velocity from the move
  with the walls' restitution and friction), one launch per kernel. Both report the mean
  overlap of touching pairs at the end (relative to the radius).
Warp's CPU backend runs one thread; tai_coll runs --threads (default 2). Prints a table with
the ratio and writes bench_results/bench_warp.json.
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import tai_coll as tc  # noqa: E402
from tools.bench import machine_info, write_json  # noqa: E402

R = 0.005
DT = 1.0 / 600.0
E = 0.5
MU = 0.3
G = -9.81
SUBSTEPS = 10


# ---------------------------------------------------------------------- the scenes
def layer_positions(n: int, seed: int = 0) -> np.ndarray:
    """n particles at random in a layer from R to R + 2 cm above y = 0, over a square of side
    sqrt(n) diameters (the area grows with n; the layer stays as dense)."""
    rng = np.random.default_rng(seed)
    side = np.sqrt(n) * 2.0 * R
    return np.column_stack([rng.uniform(0, side, n), R + rng.uniform(0.0, 0.02, n), rng.uniform(0, side, n)])


def bed_positions(n: int, layers: int = 6, seed: int = 0) -> tuple:
    """A jittered lattice 2.2 r apart, `layers` deep; returns (positions, box width)."""
    rng = np.random.default_rng(seed)
    per_layer = int(np.ceil(n / layers))
    side = int(np.ceil(np.sqrt(per_layer)))
    spacing = 2.2 * R
    i, k, j = np.meshgrid(np.arange(side), np.arange(side), np.arange(layers), indexing="ij")
    x = np.column_stack([i.ravel(), j.ravel(), k.ravel()]).astype(np.float64)[:n] * spacing + spacing / 2
    x += rng.uniform(-0.1, 0.1, x.shape) * R
    return x, side * spacing


def tai_coll_layer(n: int, frames: int) -> dict:
    scene = tc.Scene(dt=DT, substeps=SUBSTEPS)
    scene.add_collider(tc.Plane(), material=tc.Material(restitution=E, friction=MU))
    scene.add_particles(positions=layer_positions(n), radius=R)
    scene.step(2)  # (compiles)
    t0 = time.perf_counter()
    scene.step(frames)
    seconds = time.perf_counter() - t0
    y = scene.positions()[:, 1]
    return {"rate": n * SUBSTEPS * frames / seconds, "seconds": seconds, "lowest": float(y.min())}


def tai_coll_bed(n: int, settle: int, timed: int) -> dict:
    x, width = bed_positions(n)
    scene = tc.Scene(dt=DT, substeps=SUBSTEPS)
    wall = tc.Material(restitution=E, friction=MU)
    for point, normal in (((0, 0, 0), (0, 1, 0)), ((0, 0, 0), (1, 0, 0)), ((width, 0, 0), (-1, 0, 0)),
                          ((0, 0, 0), (0, 0, 1)), ((0, 0, width), (0, 0, -1))):
        scene.add_collider(tc.Plane(point=point, normal=normal), material=wall)
    scene.add_particles(positions=x, radius=R)
    scene.enable_particle_collisions(material=tc.Material(restitution=E, friction=MU))
    scene.step(settle // SUBSTEPS)
    t0 = time.perf_counter()
    scene.step(timed // SUBSTEPS)
    seconds = time.perf_counter() - t0
    return {"rate": n * timed / seconds, "seconds": seconds, "mean_overlap": scene.particle_overlap()["mean"]}


# ---------------------------------------------------------------------- Warp
def warp_kernels(wp):
    @wp.kernel
    def layer_step(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), dt: float, r: float, e: float,
                   mu: float):
        i = wp.tid()
        vi = v[i] + wp.vec3(0.0, -9.81, 0.0) * dt
        xi = x[i] + vi * dt
        if xi[1] < r:
            xi = wp.vec3(xi[0], r, xi[2])
            vn = vi[1]
            if vn < 0.0:
                dvn = -(1.0 + e) * vn
                vt = wp.vec3(vi[0], 0.0, vi[2])
                speed = wp.length(vt)
                scale = 0.0
                if speed > 0.0:
                    scale = wp.max(0.0, 1.0 - mu * dvn / speed)
                vi = vt * scale + wp.vec3(0.0, -e * vn, 0.0)
        x[i] = xi
        v[i] = vi

    @wp.kernel
    def predict(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), xp: wp.array(dtype=wp.vec3), dt: float):
        i = wp.tid()
        xp[i] = x[i] + (v[i] + wp.vec3(0.0, -9.81, 0.0) * dt) * dt

    @wp.kernel
    def jacobi(grid: wp.uint64, xp: wp.array(dtype=wp.vec3), r: float, width: float,
               out: wp.array(dtype=wp.vec3)):
        tid = wp.tid()
        i = wp.hash_grid_point_id(grid, tid)
        xi = xp[i]
        delta = wp.vec3(0.0)
        count = int(0)
        query = wp.hash_grid_query(grid, xi, 2.0 * r)
        j = int(0)
        while wp.hash_grid_query_next(query, j):
            if j != i:
                d = xi - xp[j]
                dist = wp.length(d)
                if dist < 2.0 * r and dist > 1e-9:
                    delta += d / dist * (0.5 * (2.0 * r - dist))
                    count += 1
        if count > 0:
            xi = xi + delta / float(count)
        xi = wp.vec3(wp.clamp(xi[0], r, width - r), wp.max(xi[1], r), wp.clamp(xi[2], r, width - r))
        out[i] = xi

    @wp.kernel
    def finish(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), xp: wp.array(dtype=wp.vec3), dt: float,
               r: float, width: float, e: float, mu: float):
        i = wp.tid()
        vi = (xp[i] - x[i]) / dt
        # the walls' restitution and friction on the velocity the move implies (floor shown;
        # the side walls only stop the normal component)
        if xp[i][1] <= r + 1e-6 and vi[1] < 0.0:
            dvn = -(1.0 + e) * vi[1]
            vt = wp.vec3(vi[0], 0.0, vi[2])
            speed = wp.length(vt)
            scale = 0.0
            if speed > 0.0:
                scale = wp.max(0.0, 1.0 - mu * dvn / speed)
            vi = vt * scale + wp.vec3(0.0, -e * vi[1], 0.0)
        if (xp[i][0] <= r + 1e-6 and vi[0] < 0.0) or (xp[i][0] >= width - r - 1e-6 and vi[0] > 0.0):
            vi = wp.vec3(-e * vi[0], vi[1], vi[2])
        if (xp[i][2] <= r + 1e-6 and vi[2] < 0.0) or (xp[i][2] >= width - r - 1e-6 and vi[2] > 0.0):
            vi = wp.vec3(vi[0], vi[1], -e * vi[2])
        x[i] = xp[i]
        v[i] = vi

    return layer_step, predict, jacobi, finish


def warp_layer(wp, kernels, n: int, frames: int, device: str) -> dict:
    layer_step = kernels[0]
    x = wp.array(layer_positions(n).astype(np.float32), dtype=wp.vec3, device=device)
    v = wp.zeros(n, dtype=wp.vec3, device=device)
    for _ in range(2 * SUBSTEPS):
        wp.launch(layer_step, dim=n, inputs=[x, v, DT, R, E, MU], device=device)
    wp.synchronize_device(device)
    t0 = time.perf_counter()
    for _ in range(frames * SUBSTEPS):
        wp.launch(layer_step, dim=n, inputs=[x, v, DT, R, E, MU], device=device)
    wp.synchronize_device(device)
    seconds = time.perf_counter() - t0
    return {"rate": n * SUBSTEPS * frames / seconds, "seconds": seconds, "lowest": float(x.numpy()[:, 1].min())}


def warp_bed(wp, kernels, n: int, settle: int, timed: int, device: str, passes: int = 4) -> dict:
    _, predict, jacobi, finish = kernels
    positions, width = bed_positions(n)
    x = wp.array(positions.astype(np.float32), dtype=wp.vec3, device=device)
    v = wp.zeros(n, dtype=wp.vec3, device=device)
    xp = wp.zeros(n, dtype=wp.vec3, device=device)
    scratch = wp.zeros(n, dtype=wp.vec3, device=device)
    grid = wp.HashGrid(128, 128, 128, device=device)

    def step():
        nonlocal xp, scratch
        wp.launch(predict, dim=n, inputs=[x, v, xp, DT], device=device)
        grid.build(xp, 2.0 * R)
        for _ in range(passes):
            wp.launch(jacobi, dim=n, inputs=[grid.id, xp, R, width, scratch], device=device)
            xp, scratch = scratch, xp
        wp.launch(finish, dim=n, inputs=[x, v, xp, DT, R, width, E, MU], device=device)

    for _ in range(settle):
        step()
    wp.synchronize_device(device)
    t0 = time.perf_counter()
    for _ in range(timed):
        step()
    wp.synchronize_device(device)
    seconds = time.perf_counter() - t0
    return {"rate": n * timed / seconds, "seconds": seconds, "mean_overlap": mean_overlap(x.numpy().astype(np.float64))}


def mean_overlap(x: np.ndarray) -> float:
    """The mean overlap of touching pairs relative to the radius, by a tai_coll scene's own
    measure (the same for both sides)."""
    scene = tc.Scene()
    scene.add_particles(positions=x, radius=R)
    return scene.particle_overlap()["mean"]


# ---------------------------------------------------------------------- main
def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rows", default="layer,bed")
    parser.add_argument("--layer-particles", type=int, default=1_000_000)
    parser.add_argument("--layer-frames", type=int, default=10)
    parser.add_argument("--bed-particles", type=int, default=100_000)
    parser.add_argument("--settle", type=int, default=300, help="bed: steps to settle (default 300)")
    parser.add_argument("--timed", type=int, default=100, help="bed: steps timed (default 100)")
    parser.add_argument("--arch", default="cpu")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--out", default=str(ROOT / "bench_results" / "bench_warp.json"))
    args = parser.parse_args(argv)
    try:
        import warp as wp
    except ImportError:
        sys.exit("bench_warp: needs warp-lang (a benchmark-only extra): pip install 'tai_coll[bench]'")
    tc.init(arch=args.arch, threads=args.threads if args.arch == "cpu" else None)
    wp.config.quiet = True
    wp.init()
    device = "cpu" if args.arch == "cpu" else "cuda:0"
    kernels = warp_kernels(wp)
    rows = []
    wanted = args.rows.split(",")
    if "layer" in wanted:
        n = args.layer_particles
        ours, theirs = tai_coll_layer(n, args.layer_frames), warp_layer(wp, kernels, n, args.layer_frames, device)
        rows.append({"row": "layer", "particles": n, "tai_coll": ours, "warp": theirs,
                     "ratio": ours["rate"] / theirs["rate"]})
    if "bed" in wanted:
        n = args.bed_particles
        ours = tai_coll_bed(n, args.settle, args.timed)
        theirs = warp_bed(wp, kernels, n, args.settle, args.timed, device)
        rows.append({"row": "bed", "particles": n, "tai_coll": ours, "warp": theirs, "ratio": ours["rate"] / theirs["rate"]})
    print(f"tai_coll {tc.__version__} ({args.arch}, {args.threads if args.arch == 'cpu' else ''} threads) against "
          f"Warp {wp.__version__} ({device}), f32, dt {DT:.4g} s")
    print(f"{'row':<6} {'particles':>10} {'tai_coll steps/s':>17} {'Warp steps/s':>13} {'ratio':>6}  notes")
    for r in rows:
        if r["row"] == "layer":
            notes = f"lowest centre {r['tai_coll']['lowest'] * 1e3:.3f} / {r['warp']['lowest'] * 1e3:.3f} mm"
        else:
            notes = (f"mean overlap {r['tai_coll']['mean_overlap'] * 100:.2f} % / "
                     f"{r['warp']['mean_overlap'] * 100:.2f} % of r (Warp: PBD Jacobi, 4 passes)")
        print(f"{r['row']:<6} {r['particles']:>10,} {r['tai_coll']['rate']:>17.3e} {r['warp']['rate']:>13.3e} "
              f"{r['ratio']:>5.2f}x  {notes}")
    report = {"benchmark": "bench_warp", "machine": machine_info(args), "warp": wp.__version__, "rows": rows}
    print(f"wrote {write_json(args.out, report)}")


if __name__ == "__main__":
    main()
