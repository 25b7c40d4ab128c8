"""Benchmark: what the production workflow (issue 22) costs a running scene: an emitter
pouring into it, a checkpoint (save_state / load_state), and writing a frame (PLY, NPZ, USD).

    python tools/bench_workflow.py                   # 100,000 particles
    python tools/bench_workflow.py --particles 20000 --frames 5

A cube of particles (r = 5 mm, on a lattice 1.01 diameters apart) rests on a floor with
Gauss-Seidel pairs (the default ImpulseSolver, dt = 1/600 s, 10 substeps a frame). Variants,
in one process, the same frames:
- baseline: the pile alone;
- emitter: the pile and an emitter pouring 6,000 particles a second above it.
Kernels are compiled first; then every frame is timed (median reported). Then, on the
emitter's scene: save_state and load_state into a scene built the same way (seconds, bytes per
particle), and save_frame in each format. Prints a table and writes
bench_results/bench_workflow.json.
"""

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import tai_coll as tc  # noqa: E402
from tools.bench import count, frame_times, machine_info, report_path, write_json  # noqa: E402
from tools.bench_pile import warmup_particles  # noqa: E402

RADIUS = 0.005
RATE = 6000.0


def build(particles: int, emitter: bool) -> tc.Scene:
    side = int(np.ceil(particles ** (1.0 / 3.0)))
    g = np.stack(np.meshgrid(*(np.arange(side),) * 3, indexing="ij"), -1).reshape(-1, 3)[:particles]
    scene = tc.Scene()
    scene.add_collider(tc.Plane(point=(0, 0, 0), normal=(0, 1, 0)))
    scene.add_particles(positions=g * 2.02 * RADIUS + (0.0, RADIUS, 0.0), radius=RADIUS)
    scene.enable_particle_collisions()
    if emitter:
        top = side * 2.02 * RADIUS
        scene.add_emitter(tc.Box(center=(top / 2, top + 0.2, top / 2), half_extents=(0.1, 0.02, 0.1)), rate=RATE,
                          radius=RADIUS)
    return scene


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--particles", type=count(), default=100_000)
    parser.add_argument("--frames", type=count(), default=10)
    parser.add_argument("--arch", default="cpu", choices=("cpu", "cuda", "auto"))
    parser.add_argument("--threads", type=count(), default=2)
    parser.add_argument("--out", default=str(ROOT / "bench_results" / "bench_workflow.json"))
    args = parser.parse_args(argv)
    report_path(parser, "--out", args.out)
    tc.init(arch=args.arch, threads=args.threads if args.arch == "cpu" else None)
    build(warmup_particles(), True).step(3)  # compile every kernel first, on a smaller scene
    rows = []
    scenes = {}
    for variant in ("baseline", "emitter"):
        scene = build(args.particles, variant == "emitter")
        scene.step(2)
        median = float(np.median(frame_times(scene.step, args.frames)))
        scenes[variant] = scene
        rows.append({"variant": variant, "particles_at_end": scene.num_particles, "median_frame_s": median})
    scene = scenes["emitter"]
    files = {}
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "state.npz"
        t0 = time.perf_counter()
        scene.save_state(path)
        files["save_state_s"] = time.perf_counter() - t0
        files["state_bytes_per_particle"] = os.path.getsize(path) / scene.num_particles
        other = build(args.particles, True)
        t0 = time.perf_counter()
        other.load_state(path)
        files["load_state_s"] = time.perf_counter() - t0
        for ext in ("ply", "npz", "usd"):
            t0 = time.perf_counter()
            try:
                scene.save_frame(Path(folder) / f"frame.{ext}")
            except ImportError:  # (usd-core is an extra)
                continue
            files[f"save_frame_{ext}_s"] = time.perf_counter() - t0
    extra = rows[1]["median_frame_s"] - rows[0]["median_frame_s"]
    print(f"{args.particles:,} particles resting in a pile (Gauss-Seidel pairs), {args.frames} frames x 10 substeps, "
          f"arch {args.arch}, {args.threads} threads")
    print(f"{'variant':<10} {'median frame':>13} {'particles at end':>17}")
    for r in rows:
        print(f"{r['variant']:<10} {r['median_frame_s'] * 1e3:>10.1f} ms {r['particles_at_end']:>17,}")
    print(f"emitting {RATE:,.0f} particles/s: +{extra * 1e3:.1f} ms a frame "
          f"({extra / rows[0]['median_frame_s'] * 100:.0f} % of the baseline)")
    print(f"state: {files['state_bytes_per_particle']:.0f} B/particle, save {files['save_state_s']:.2f} s, "
          f"load {files['load_state_s']:.2f} s; frame: "
          + ", ".join(f"{k[11:-2]} {v * 1e3:.0f} ms" for k, v in files.items() if k.startswith("save_frame_")))
    report = {"benchmark": "bench_workflow", "machine": machine_info(args), "rows": rows, "files": files,
              "emitter_extra_frame_s": extra}
    print(f"wrote {write_json(args.out, report)}")


if __name__ == "__main__":
    main()
