"""Benchmark: particles streaming onto rigid bodies, two-way (issue 21), against the same scene
with the bodies kinematic (colliders that hold still and feel nothing).

    python tools/bench_bodies.py                     # 100,000 particles, 10 bodies
    python tools/bench_bodies.py --particles 20000 --frames 10

Ten boxes (16 cm, 20 kg each) stand on a floor in two rows; a block of particles (r = 3 mm,
2,500 kg/m^3) falls onto them at 2 m/s from just above, with the default ImpulseSolver (no
particle-particle contacts: a stream), dt = 1/600 s, 10 substeps a frame. Variants, in one
process, the same frames:
- bodies: the boxes are scene.add_body (the particles push them, and the floor holds them);
- kinematic: the boxes are add_collider(..., velocity=(0, 0, 0)): moving colliders that do
  not move, which is the code path bodies take for the particles without the coupling.
Kernels are compiled on a small scene first; then every frame is timed. Reports
particle-steps per second over the timed frames, the median frame, and the share of the
frame the bodies' host work takes (their contacts, the ledger's sum). Prints a table and
writes bench_results/bench_bodies.json.
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import tai_coll as tc  # noqa: E402
from tools.bench import count, machine_info, report_path, write_json  # noqa: E402
from tools.bench_pile import warmup_particles  # noqa: E402

RADIUS = 0.003
HALF = 0.08          # m, the boxes' half side
BOX_MASS = 20.0      # kg
DT = 1.0 / 600.0
SUBSTEPS = 10


def box_centres():
    xs = np.linspace(-0.4, 0.4, 5)
    return [(x, HALF, z) for z in (-0.12, 0.12) for x in xs]


def build(variant: str, particles: int, seed: int = 0) -> tc.Scene:
    rng = np.random.default_rng(seed)
    scene = tc.Scene(dt=DT, substeps=SUBSTEPS)
    scene.add_collider(tc.Plane(point=(0, 0, 0), normal=(0, 1, 0)), material=tc.Material(restitution=0.3))
    for centre in box_centres():
        shape = tc.Box(center=centre, half_extents=(HALF, HALF, HALF))
        if variant == "bodies":
            scene.add_body(shape, mass=BOX_MASS, material=tc.Material(restitution=0.3, friction=0.4))
        else:
            scene.add_collider(shape, material=tc.Material(restitution=0.3, friction=0.4), velocity=(0.0, 0.0, 0.0))
    # a block over the boxes, 2.4 r apart, jittered
    side = 2.4 * RADIUS
    nx, nz = int(1.0 / side), int(0.4 / side)
    layers = int(np.ceil(particles / (nx * nz)))
    gx, gy, gz = np.meshgrid(np.arange(nx), np.arange(layers), np.arange(nz), indexing="ij")
    points = np.column_stack([gx.ravel() * side - 0.5, 2 * HALF + 0.01 + gy.ravel() * side,
                              gz.ravel() * side - 0.2])[:particles]
    points += rng.uniform(-0.1, 0.1, points.shape) * RADIUS
    scene.add_particles(positions=points, velocities=np.tile([0.0, -2.0, 0.0], (len(points), 1)), radius=RADIUS,
                        mass=2500.0 * 4.0 / 3.0 * np.pi * RADIUS ** 3)
    return scene


def run(variant: str, particles: int, frames: int) -> dict:
    scene = build(variant, particles)
    times = []
    bodies = getattr(scene, "_bodies", None)
    host = 0.0
    if variant == "bodies":  # time the bodies' host phases (begin / end) apart
        system = bodies
        begin, end = system.begin, system.end

        def timed(fn):
            def wrapper(*a, **k):
                nonlocal host
                t0 = time.perf_counter()
                out = fn(*a, **k)
                host += time.perf_counter() - t0
                return out
            return wrapper
        system.begin, system.end = timed(begin), timed(end)
    for _ in range(frames):
        t0 = time.perf_counter()
        scene.step()
        times.append(time.perf_counter() - t0)
    total = sum(times)
    steps = particles * SUBSTEPS
    out = {"variant": variant, "particles": particles, "frames": frames, "seconds": total,
           "particle_steps_per_s": steps * frames / total, "median_frame_s": float(np.median(times)),
           "median_particle_steps_per_s": steps / float(np.median(times)),
           "hit_bodies": int(np.sum(scene.positions()[:, 1] < 2 * HALF + 2 * RADIUS))}
    if variant == "bodies":
        out["bodies_host_share"] = host / total
        out["body_speeds"] = [float(np.linalg.norm(b.velocity)) for b in scene.bodies]
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--particles", type=count(), default=100_000)
    parser.add_argument("--frames", type=count(), default=20)
    parser.add_argument("--arch", default="cpu", choices=("cpu", "cuda", "auto"))
    parser.add_argument("--threads", type=count(), default=2)
    parser.add_argument("--out", default=str(ROOT / "bench_results" / "bench_bodies.json"))
    args = parser.parse_args(argv)
    report_path(parser, "--out", args.out)
    tc.init(arch=args.arch, threads=args.threads if args.arch == "cpu" else None)
    for variant in ("bodies", "kinematic"):  # compile every kernel first, on a smaller scene
        build(variant, warmup_particles()).step(2)
    rows = [run(variant, args.particles, args.frames) for variant in ("bodies", "kinematic")]
    ratio = rows[0]["particle_steps_per_s"] / rows[1]["particle_steps_per_s"]
    print(f"{args.particles:,} particles onto 10 boxes, {args.frames} frames x {SUBSTEPS} substeps "
          f"(dt {DT:.4g} s), arch {args.arch}, {args.threads} threads")
    print(f"{'variant':<10} {'particle-steps/s':>17} {'median frame':>13} {'reached the boxes':>18}")
    for r in rows:
        print(f"{r['variant']:<10} {r['particle_steps_per_s']:>17.3e} {r['median_frame_s'] * 1e3:>10.1f} ms "
              f"{r['hit_bodies']:>18,}")
    print(f"bodies / kinematic: {ratio:.2f}x; the bodies' host work {rows[0]['bodies_host_share'] * 100:.1f} % "
          f"of the bodies' frames")
    report = {"benchmark": "bench_bodies", "machine": machine_info(args), "rows": rows,
              "bodies_over_kinematic": ratio}
    print(f"wrote {write_json(args.out, report)}")


if __name__ == "__main__":
    main()
