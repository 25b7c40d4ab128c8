"""Does the pile come to rest? The benchmark pile (tools/bench_pile.py: particles of radius
5 mm dropped on a jittered lattice into a box of five planes, about 54 layers deep) stepped
for a while, its state measured every `--every` simulated seconds:

- kinetic energy per unit mass (J/kg, the mean of v^2 / 2), speed percentiles (p50, p99, max);
- how far particles actually moved: the displacement over the last frame and over the whole
  interval since the previous measurement, each divided by its time (p50, p99, max; mm/s).
  The stored velocity can differ from the motion: the solver's last pass changes velocities
  of touching pairs without moving them (tai_coll.solvers.gauss_seidel, settle), so a particle
  jammed in the pile may carry tens of mm/s that the next substep's contacts take away again;
- overlap between particles (mean over touching pairs, and max, relative to the radius);
- the height of the top particle and of the centre of mass (a pile that creeps sinks);
- particles outside the box (should stay 0) and the wall time so far.

- how many particles sleep (docs/physics.md 5.3.1).

`--lattice N` instead builds the pile of issue [2 of 6]: N^3 particles of radius 6 mm on a
lattice at 2.2 r (jitter 0.1 r, no overlap) in a box of planes as wide as the lattice, e = 0.3,
mu = 0.5, the default Scene and solver (N = 22: 10,648 particles; the promise at 2 s: speeds
p99 <= 5 mm/s, max <= 20 mm/s, mean overlap < 2 % of the radius).

Prints one line per measurement and writes them all as JSON (default
bench_results/pile_settle.json), with the machine. Examples:

    python tools/pile_settle.py --particles 100000 --seconds 1.5
    python tools/pile_settle.py --particles 1000000 --seconds 1.5 --variant impulse
    python tools/pile_settle.py --lattice 22 --seconds 2 --every 0.5
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
sys.path.insert(0, str(ROOT))

import bench_pile  # noqa: E402
from bench import count, init_taichi, machine_info, report_path, seconds, write_json  # noqa: E402


STATS = ("p50", "p99", "max")


def percentiles(values: np.ndarray, name: str) -> dict:
    """p50, p99 and max of speeds in m/s as {name_p50_m_s: ..., ...}."""
    found = (np.median(values), np.percentile(values, 99), values.max())
    return {f"{name}_{stat}_m_s": float(value) for stat, value in zip(STATS, found)}


def measure(scene, half: float, wall_s: float, frame_start: np.ndarray, frame_s: float, interval_start: np.ndarray,
            interval_s: float) -> dict:
    """The state now; frame_start, interval_start: positions a frame and an interval ago."""
    x, v = scene.positions(), scene.velocities()
    speed = np.linalg.norm(v, axis=1)
    moved_frame = np.linalg.norm(x - frame_start, axis=1) / frame_s
    moved_interval = np.linalg.norm(x - interval_start, axis=1) / interval_s
    overlap = scene.particle_overlap()
    outside = (np.abs(x[:, [0, 2]]).max(axis=1) > half + 1e-6) | (x[:, 1] < -1e-6)
    return {
        "t_s": scene.time,
        "kinetic_energy_j_per_kg": float(0.5 * np.mean(speed.astype(np.float64) ** 2)),
        **percentiles(speed, "speed"),
        **percentiles(moved_frame, "moved_last_frame"),
        **percentiles(moved_interval, "moved_since_last_measurement"),
        "overlap_mean": overlap["mean"],
        "overlap_max": overlap["max"],
        "top_m": float(x[:, 1].max()),
        "centre_of_mass_height_m": float(x[:, 1].mean()),
        "outside": int(outside.sum()),
        "asleep": int(scene.sleeping().sum()),
        "wall_s": wall_s,
    }


def mm_s(row: dict, name: str) -> str:
    """A row's p50/p99/max of `name` in mm/s."""
    return "/".join(f"{row[f'{name}_{stat}_m_s'] * 1e3:.1f}" for stat in STATS)


def print_row(row: dict) -> None:
    print(f"t {row['t_s']:5.2f} s  KE {row['kinetic_energy_j_per_kg']:8.2e} J/kg  speed p50/p99/max "
          f"{mm_s(row, 'speed')}  moved (last frame | since the last row) {mm_s(row, 'moved_last_frame')} | "
          f"{mm_s(row, 'moved_since_last_measurement')} mm/s  overlap {100 * row['overlap_mean']:4.1f} % / "
          f"{100 * row['overlap_max']:5.1f} %  top {row['top_m']:.4f} m  centre {row['centre_of_mass_height_m']:.4f} m"
          f"  outside {row['outside']}  asleep {row['asleep']}  wall {row['wall_s']:6.0f} s", flush=True)


LATTICE_RADIUS = 0.006


def lattice_pile(tc, n_side: int, seed: int = 0, sleep: bool = True):
    """The pile of issue [2 of 6] (see the module's notes), its particles sleeping after
    sleeping.SLEEP_TIME if `sleep`: (scene, half width of the box)."""
    from tai_coll.solvers.pairs.sleeping import SLEEP_TIME

    rng = np.random.default_rng(seed)
    r = LATTICE_RADIUS
    spacing = 2.2 * r
    g = (np.arange(n_side) - (n_side - 1) / 2) * spacing
    X, Y, Z = np.meshgrid(g, 2 * r + spacing * np.arange(n_side), g, indexing="ij")
    x = np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1) + rng.uniform(-0.1 * r, 0.1 * r, (n_side ** 3, 3))
    half = n_side / 2 * spacing + r
    scene = tc.Scene()
    material = tc.Material(restitution=0.3, friction=0.5)
    for point, normal in [((0, 0, 0), (0, 1, 0)), ((-half, 0, 0), (1, 0, 0)), ((half, 0, 0), (-1, 0, 0)),
                          ((0, 0, -half), (0, 0, 1)), ((0, 0, half), (0, 0, -1))]:
        scene.add_collider(tc.Plane(point=point, normal=normal), material=material)
    scene.enable_particle_collisions(material=material, sleep_time=SLEEP_TIME if sleep else None)
    scene.add_particles(positions=x, radius=r)
    return scene, half


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--particles", type=count(), default=100_000)
    parser.add_argument("--seconds", type=seconds, default=1.5, help="simulated seconds from the drop")
    parser.add_argument("--every", type=seconds, default=0.25, help="simulated seconds between measurements")
    parser.add_argument("--variant", choices=bench_pile.VARIANTS, default="impulse")
    parser.add_argument("--lattice", type=count(), default=None, metavar="N",
                        help="the [2 of 6] lattice pile of N^3 particles instead of the benchmark pile")
    parser.add_argument("--arch", default="cpu", choices=("cpu", "cuda", "auto"))
    parser.add_argument("--threads", type=count(), default=2, help="Taichi CPU threads")
    parser.add_argument("--json", default=str(ROOT / "bench_results" / "pile_settle.json"))
    args = parser.parse_args(argv)
    report_path(parser, "--json", args.json)

    import tai_coll as tc

    init_taichi(tc, args)
    if args.lattice is not None:
        scene, half = lattice_pile(tc, args.lattice)
        args.particles, args.variant = scene.num_particles, f"lattice {args.lattice}^3, default Scene"
        frame = scene.substeps * scene.dt
    else:
        scene = bench_pile.pile_scene(tc, args.particles, variant=args.variant)
        half = bench_pile.pile_half(args.particles)
        frame = bench_pile.SUBSTEPS * bench_pile.DT[bench_pile.base_variant(args.variant)]
    per = max(1, int(round(args.every / frame)))
    total = max(1, int(round(args.seconds / frame)))
    print(f"pile of {args.particles:,}, {args.variant}, {scene.substeps} substeps of {scene.dt * 1e3:g} ms per "
          f"frame, measured every {per * frame:g} s", flush=True)
    rows = []
    start = time.perf_counter()
    done = 0
    interval_start = scene.positions()
    while done < total:
        step = min(per, total - done)
        if step > 1:
            scene.step(step - 1)
        frame_start = scene.positions()
        scene.step(1)
        done += step
        rows.append(measure(scene, half, time.perf_counter() - start, frame_start, frame, interval_start,
                            step * frame))
        interval_start = scene.positions()
        print_row(rows[-1])
    report = {"machine": machine_info(args), "particles": args.particles, "variant": args.variant,
              "dt": scene.dt, "substeps": scene.substeps, "rows": rows}
    print(f"wrote {write_json(Path(args.json), report)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
