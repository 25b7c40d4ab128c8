"""Benchmark: offscreen rendering next to the simulation it shows.

    python tools/bench_render.py                   # 100,000 particles at 1280x720, CPU, 2 threads
    python tools/bench_render.py --particles 1000000 --res 1920x1080

The scene is tools/bench.py's ("falling": particles of radius 5 mm above a floor, a sphere
and a box; dt = 1/600 s, 10 substeps per frame), coloured by speed. Timed per frame, each
as the median over --frames frames after a warm-up frame (kernel compiles, the window):

- simulate: `scene.step()` alone;
- render: `Renderer.render()` alone (read the state, colours, GGUI draw and read-back,
  conversion to uint8), split into its parts;
- encode: streaming the frame to ffmpeg (H.264);
- loop: step, render and encode in turn, with the step's time inside that loop, to see
  whether rendering slows the simulation down beyond its own cost;
- loop writing PNGs and the video: step, render, then a PNG and the video frame, written in
  turn (as `tai-coll run` did before render/behind.py) and behind the loop by a FrameWriter
  (as it does now), alternately twice, each the mean over its frames with the video's close
  included.

Prints a table and writes bench_results/render.json.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

TOOLS = Path(__file__).resolve().parent
ROOT = TOOLS.parent
sys.path.insert(0, str(TOOLS))
sys.path.insert(0, str(ROOT))


def median_ms(times):
    return 1e3 * float(np.median(times))


def main(argv=None):
    from bench import count, report_path, write_json

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--particles", type=count(), default=100_000)
    parser.add_argument("--res", default="1280x720")
    parser.add_argument("--frames", type=count(), default=10)
    parser.add_argument("--arch", default="cpu", choices=("cpu", "cuda", "vulkan", "auto"))
    parser.add_argument("--threads", type=count(), default=2)
    parser.add_argument("--json", default=str(ROOT / "bench_results" / "render.json"))
    args = parser.parse_args(argv)
    try:
        width, height = (int(v) for v in args.res.lower().split("x"))
        if width < 1 or height < 1:
            raise ValueError
    except ValueError:
        parser.error(f"--res: give WIDTHxHEIGHT in pixels (1280x720); got {args.res!r}")
    report_path(parser, "--json", args.json)

    import taichi as ti

    import tai_coll as tc
    from bench import build_scene, initial_positions, machine_info
    from tai_coll.render import FrameWriter, Renderer, VideoWriter, write_png
    from tai_coll.render.renderer import to_uint8
    from tai_coll.render import draw
    from tai_coll.render import window as ggui

    info = tc.init(arch=args.arch, threads=args.threads if args.arch != "cuda" else None)
    scene = build_scene(tc, initial_positions(tc, args.particles))
    renderer = Renderer(width=width, height=height)

    def step():
        scene.step()
        ti.sync()

    step()  # compile
    renderer.render(scene)  # open the window, compile GGUI's copy kernels
    simulate, render = [], []
    for _ in range(args.frames):
        t0 = time.perf_counter()
        step()
        t1 = time.perf_counter()
        renderer.render(scene)
        render.append(time.perf_counter() - t1)
        simulate.append(t1 - t0)

    # where a frame's rendering goes
    parts = {"read state + colours": [], "ggui draw + read-back": [], "to uint8": []}
    win = ggui.open_window(width, height)
    held = None  # the particles' vertex array (draw.particles)
    for _ in range(max(3, args.frames // 2)):
        t0 = time.perf_counter()
        x = np.ascontiguousarray(scene.positions(), dtype=np.float32)
        r = np.ascontiguousarray(scene.radii() * (height / width), dtype=np.float32)
        c = renderer._particle_colors(scene)
        t1 = time.perf_counter()
        canvas, view = renderer._set_up_view(win)
        buffers = ggui.mesh_buffers()
        if buffers.count:
            draw.mesh(view, buffers)
        held = draw.particles(view, x, r, c, held)
        canvas.scene(view)
        image = win.get_image_buffer_as_numpy()
        t2 = time.perf_counter()
        to_uint8(image)
        t3 = time.perf_counter()
        for name, dt in zip(parts, (t1 - t0, t2 - t1, t3 - t2)):
            parts[name].append(dt)

    # encoding alone, then the whole loop
    frame = renderer.render(scene)
    with tempfile.TemporaryDirectory() as folder:
        encode = []
        with VideoWriter(Path(folder) / "encode.mp4", fps=60) as video:
            for _ in range(args.frames):
                t0 = time.perf_counter()
                video.write(frame)
                encode.append(time.perf_counter() - t0)
        loop, loop_simulate = [], []
        with VideoWriter(Path(folder) / "loop.mp4", fps=60) as video:
            for _ in range(args.frames):
                t0 = time.perf_counter()
                step()
                t1 = time.perf_counter()
                video.write(renderer.render(scene))
                loop.append(time.perf_counter() - t0)
                loop_simulate.append(t1 - t0)
        # the loop writing PNGs and the video, in turn and behind, alternately twice (ms/frame, mean)
        written = {"in turn": [], "behind": []}
        for way in ("in turn", "behind") * 2:
            t0 = time.perf_counter()
            writer = FrameWriter(VideoWriter(Path(folder) / f"{way}.mp4", fps=60))
            for k in range(args.frames):
                step()
                image, png = renderer.render(scene), Path(folder) / f"{k}.png"
                if way == "behind":
                    writer.write(image, png)
                else:
                    write_png(png, image)
                    writer.video.write(image)
            writer.close()
            written[way].append(1e3 * (time.perf_counter() - t0) / args.frames)

    n = scene.num_particles
    rows = {
        "simulate": median_ms(simulate),
        "render": median_ms(render),
        **{f"  {name}": median_ms(times) for name, times in parts.items()},
        "encode (H.264)": median_ms(encode),
        "loop: simulate + render + encode": median_ms(loop),
        "  of which simulate": median_ms(loop_simulate),
        "loop + PNG + H.264, written in turn": float(np.mean(written["in turn"])),
        "loop + PNG + H.264, written behind": float(np.mean(written["behind"])),
    }
    machine = machine_info(argparse.Namespace(arch=args.arch, threads=args.threads))
    print(f"\nmachine: {machine['cpu_model']}, {machine['usable_cores']} usable cores; taichi {machine['taichi']} "
          f"on {info.arch}, {args.threads} threads; Vulkan driver: {vulkan_driver()}")
    print(f"{n:,} particles, {width}x{height}, median over {args.frames} frames\n")
    print(f"{'per frame':<38} {'ms':>9} {'frames/s':>9}")
    for name, ms in rows.items():
        print(f"{name:<38} {ms:9.1f} {1e3 / ms:9.2f}")
    overhead = rows["loop: simulate + render + encode"] - rows["simulate"] - rows["render"] - rows["encode (H.264)"]
    print(f"\nsimulation: {n * scene.substeps / (rows['simulate'] / 1e3) / 1e6:.2f} M particle-steps/s alone, "
          f"{n * scene.substeps / (rows['  of which simulate'] / 1e3) / 1e6:.2f} M between renders; "
          f"loop minus its parts timed alone: {overhead:+.1f} ms/frame")

    report = {"machine": machine, "arch": info.arch, "particles": n, "resolution": [width, height],
              "frames": args.frames, "vulkan_driver": vulkan_driver(), "median_ms": rows,
              "render_fps": 1e3 / rows["render"], "loop_overhead_ms": overhead,
              "time": time.strftime("%Y-%m-%dT%H:%M:%S")}
    path = write_json(args.json, report)
    print(f"wrote {path}")
    return 0


def vulkan_driver() -> str:
    """The Vulkan ICD files present (lavapipe is lvp_icd)."""
    import glob

    names = sorted(os.path.basename(p) for p in glob.glob("/usr/share/vulkan/icd.d/*.json"))
    return ", ".join(names) or "unknown"


if __name__ == "__main__":
    sys.exit(main())
