"""The `tai-coll` command (also `python -m tai_coll`).

    tai-coll run SCENE.py [--frames N] [--fps F] [--res WxH] [--out DIR] [--video PATH]
                          [--arch cpu|cuda|vulkan|auto] [--threads N] [--no-render] [--no-frames] [--no-video]
                          [--export ply,npz,usd] [--checkpoint-every N] [--resume STATE]
    tai-coll sweep SCENE.py --param NAME=V1,V2,... [--param ...] [--frames N] [--out DIR]
                            [--address HOST:PORT] [--workers K] [--render --res WxH] [--arch ...] [--threads N]
    tai-coll info [--arch ARCH]
    tai-coll bake MESH [...]      (tai_coll.bake: mesh signed-distance grids, when installed)

`run` loads a scene script, simulates it, renders every frame offscreen, writes PNG frames
and a video, and prints a summary. --export writes the particles of every frame into the
output folder, numbered by the scene's frame count (0: the state before the first step):
particles_00000.ply ... and particles_00000.npz ..., and one USD layer of time samples,
particles.usd. --checkpoint-every N saves the state every N frames (state_00010.npz ...);
--resume STATE loads one into the scene the script builds and runs --frames more, numbering
frames and files on from it. A scene script is a Python file with:

- `scene()` returning a tc.Scene (required);
- `FRAMES` (optional): the default number of frames;
- `render_settings()` (optional): a dict of keyword arguments for tai_coll.render.Renderer
  (camera, color_by, colormap, color_range, ...; width and height are defaults that --res
  overrides).

`sweep` runs the script's scene(**values) for every combination of the --param values, each
as a Ray task (tai_coll.sweeps), and writes DIR/results.csv and results.json: one row per run
with the parameters, the script's metrics(scene) after the last frame, the wall time, the
worker's pid and node, and a status ("ok" or the error). --render adds each run's last frame
and DIR/contact_sheet.png. It exits 1 when any run failed (the others finish).

Exit status: 0 done, 1 the scene script, the simulation, rendering or ffmpeg failed (with
the script's traceback or ffmpeg's message), 2 bad arguments (one line saying why),
130 interrupted.
"""

from __future__ import annotations

import argparse
import importlib.util
import logging
import sys
import time
import traceback
from pathlib import Path

from .scripts import (DEFAULT_FRAMES, ScriptError, UsageError, build_scene, check_script_path, check_threads,
                      check_writable, load_script, parse_resolution, render_settings, script_frames,
                      script_traceback)

ARCHS = ("cpu", "cuda", "vulkan", "auto")
DEFAULT_RES = (1280, 720)
FRAME_PATTERN = "frame_{:05d}.png"
EXPORT_PATTERN = "particles_{:05d}.{}"  # frame number, format
USD_NAME = "particles.usd"
STATE_PATTERN = "state_{:05d}.npz"
MAX_FPS = 10000  # --fps must lie in (0, MAX_FPS)


# ----------------------------------------------------------------------------- arguments
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tai-coll", description="tai_coll: particle collisions on Taichi.")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    commands.required = True

    run = commands.add_parser("run", help="simulate a scene script, render frames and a video")
    run.add_argument("scene", metavar="SCENE.py", help="a Python file defining scene() -> tc.Scene")
    run.add_argument("--frames", type=int, help=f"frames to simulate (default: the script's FRAMES, else "
                                                f"{DEFAULT_FRAMES})")
    run.add_argument("--fps", type=float, help="video frames per second (default: real time, 1 / (substeps dt))")
    run.add_argument("--res", default=None, metavar="WxH", help="frame size in pixels (default 1280x720)")
    run.add_argument("--out", metavar="DIR", help="folder for the PNG frames (default out/SCENE)")
    run.add_argument("--video", metavar="PATH", help="video file, .mp4 or .gif (default DIR/SCENE.mp4)")
    run.add_argument("--no-frames", action="store_true", help="write no PNG frames")
    run.add_argument("--no-video", action="store_true", help="write no video")
    run.add_argument("--arch", default="auto", choices=ARCHS, help="where the physics runs (default auto)")
    run.add_argument("--threads", type=int, help="CPU threads for the physics (default: all cores)")
    run.add_argument("--no-render", action="store_true", help="simulate only: no frames, no video, no Vulkan")
    run.add_argument("--export", metavar="FORMATS", help="write every frame's particles into the output folder: "
                                                         "a comma-separated list of ply, npz, usd")
    run.add_argument("--checkpoint-every", type=int, metavar="N", help="save the scene's state every N frames "
                                                                        "(DIR/state_FRAME.npz)")
    run.add_argument("--resume", metavar="STATE", help="start from a state saved by --checkpoint-every (or "
                                                        "scene.save_state) of the same script")

    sweep = commands.add_parser("sweep", help="run a scene script for every combination of parameter values, "
                                               "on Ray (the 'sweep' extra)")
    sweep.add_argument("scene", metavar="SCENE.py", help="a Python file defining scene(NAME=default, ...) -> tc.Scene "
                                                        "and, optionally, metrics(scene) -> dict")
    sweep.add_argument("--param", action="append", required=True, metavar="NAME=V1,V2,...",
                       help="a parameter of scene() and its values (repeat for more: every combination runs)")
    sweep.add_argument("--frames", type=int, help=f"frames each run simulates (default: the script's FRAMES, else "
                                                  f"{DEFAULT_FRAMES})")
    sweep.add_argument("--out", metavar="DIR", help="folder for results.csv, results.json and the frames "
                                                    "(default out/SCENE_sweep)")
    sweep.add_argument("--address", metavar="HOST:PORT", help="an existing Ray cluster (default RAY_ADDRESS, else "
                                                              "a local cluster on this machine)")
    sweep.add_argument("--workers", type=int, metavar="K", help="runs at a time (default: one per core)")
    sweep.add_argument("--render", action="store_true", help="render each run's last frame and a contact sheet")
    sweep.add_argument("--res", default=None, metavar="WxH", help="frame size for --render (default 480x270)")
    sweep.add_argument("--arch", default="auto", choices=ARCHS, help="where each run's physics runs (default auto: "
                                                                     "a GPU a run where the workers have them)")
    sweep.add_argument("--threads", type=int, default=1, help="CPU threads a run (default 1)")

    info = commands.add_parser("info", help="versions, arch, Vulkan and ffmpeg: a preflight check")
    info.add_argument("--arch", default="auto", choices=ARCHS, help="arch to report (default auto)")

    bake = commands.add_parser("bake", add_help=False, help="bake mesh signed-distance grids into the cache "
                                                            "(`tai-coll bake --help` for its options)")
    bake.add_argument("args", nargs=argparse.REMAINDER)
    return parser


def check_run_args(args):
    """Validate `run` arguments before Taichi starts; returns the scene path."""
    path = check_script_path(args.scene)
    if args.frames is not None and args.frames < 1:
        raise UsageError(f"--frames must be >= 1; got {args.frames}")
    if args.fps is not None and not 0 < args.fps < MAX_FPS:
        raise UsageError(f"--fps must be > 0 and < {MAX_FPS}; got {args.fps:g}")
    check_threads(args.threads)
    args.resolution = parse_resolution(args.res) if args.res is not None else None
    args.formats = parse_formats(args.export) if args.export is not None else ()
    if args.checkpoint_every is not None and args.checkpoint_every < 1:
        raise UsageError(f"--checkpoint-every must be >= 1; got {args.checkpoint_every}")
    if args.resume is not None:
        state = Path(args.resume)
        if not state.is_file():
            raise UsageError(f"--resume: no state file at {state}")
        if state.suffix.lower() != ".npz":
            raise UsageError(f"--resume: a state is a .npz file; got {state}")
    if args.formats or args.checkpoint_every is not None:
        check_writable("--out", output_folder(args, path))
    if args.video is not None and Path(args.video).suffix.lower() not in (".mp4", ".gif"):
        raise UsageError(f"--video must end in .mp4 or .gif; got {args.video}")
    frame_dir, video_path = output_paths(args, path)
    if frame_dir is not None:
        check_writable("--out", frame_dir)
    if video_path is not None:
        if video_path.is_dir():
            raise UsageError(f"--video: {video_path} is a folder, not a file")
        check_writable("--video", video_path.parent)
    return path


def parse_formats(text: str) -> tuple:
    """--export's formats, in the order given, each once; an unknown one is refused by name."""
    from .export import FORMATS

    formats = []
    for name in (part.strip().lower() for part in text.split(",")):
        if name not in FORMATS:
            raise UsageError(f"--export: unknown format {name!r}; choose from {', '.join(FORMATS)}")
        if name not in formats:
            formats.append(name)
    if "usd" in formats and importlib.util.find_spec("pxr") is None:
        raise UsageError("--export usd needs usd-core: pip install 'tai_coll[usd]'")
    return tuple(formats)


def output_folder(args, path: Path) -> Path:
    """The folder `run` writes into (--out, default out/SCENE)."""
    return Path(args.out) if args.out else Path("out") / path.stem


def output_paths(args, path: Path):
    """(frame folder, video file) that `run` writes, each None when not written."""
    if args.no_render:
        return None, None
    out = output_folder(args, path)
    frame_dir = None if args.no_frames else out
    video_path = None if args.no_video else (Path(args.video) if args.video else out / f"{path.stem}.mp4")
    return frame_dir, video_path


# ----------------------------------------------------------------------------- scene scripts
# ----------------------------------------------------------------------------- run
def default_fps(scene) -> float:
    fps = 1.0 / scene.frame_time
    return round(fps, 3) if 1.0 <= fps <= 240.0 else 30.0


def run(args) -> int:
    path = check_run_args(args)
    import tai_coll as tc

    tc.init(arch=args.arch, threads=args.threads)
    module = load_script(path)
    frames = args.frames if args.frames is not None else script_frames(module, path)
    scene = build_scene(module, path)
    if args.resume is not None:
        try:
            scene.load_state(args.resume)
        except (ValueError, FileNotFoundError) as error:
            raise UsageError(f"--resume: {error}") from None
    first = scene.frame  # frames are numbered on from a resumed state
    fps = args.fps if args.fps is not None else default_fps(scene)
    out = output_folder(args, path)
    exports = Exports(scene, out, args.formats, args.checkpoint_every, resumed=args.resume is not None)
    render = not args.no_render
    renderer = writer = None
    frame_dir, video_path = output_paths(args, path)
    if render:
        from .render import FrameWriter, Renderer, VideoWriter

        settings = render_settings(module, path)
        width, height = settings.pop("width", DEFAULT_RES[0]), settings.pop("height", DEFAULT_RES[1])
        if args.resolution is not None:
            width, height = args.resolution
        try:
            renderer = Renderer(width=width, height=height, **settings)
        except (TypeError, ValueError) as error:
            raise UsageError(f"{path}: render_settings(): {error}") from None
        if frame_dir is not None:
            frame_dir.mkdir(parents=True, exist_ok=True)
        video = None
        if video_path is not None:
            video_path.parent.mkdir(parents=True, exist_ok=True)
            video = VideoWriter(video_path, fps=fps)
        # PNGs and video frames are written on a thread of their own while the next frame is
        # stepped and rendered (render/behind.py); "writing" counts the time spent waiting for it
        writer = FrameWriter(video) if frame_dir is not None or video is not None else None

    from tqdm import tqdm

    timing = {"simulate": [], "render": [], "write": 0.0}
    n = scene.num_particles
    start = time.perf_counter()
    # A bar on a terminal (tqdm leaves logs and pipes alone): frames per second, particles.
    bar = tqdm(total=frames, desc=path.stem, unit="frame", dynamic_ncols=True, file=sys.stderr, disable=None,
               postfix={"particles": f"{n:,}"})
    try:
        if first == 0:
            exports.frame()  # the state before the first step: frame 0
        for k in range(first, first + frames):
            t0 = time.perf_counter()
            scene.step()
            exports.frame()
            t1 = time.perf_counter()
            timing["simulate"].append(t1 - t0)
            if render:
                image = renderer.render(scene)
                t2 = time.perf_counter()
                timing["render"].append(t2 - t1)
                if writer is not None:  # (k: 0 for the first frame stepped)
                    writer.write(image, frame_dir / FRAME_PATTERN.format(k) if frame_dir is not None else None)
            bar.update(1)
        if writer is not None:
            writer.close()
            timing["write"] = writer.waited
    except BaseException:
        if writer is not None:
            writer.abort()
        raise
    finally:
        bar.close()
        exports.close()  # (the USD layer keeps the frames up to a failure)
    wall = time.perf_counter() - start
    if frame_dir is not None:
        remove_stale_frames(frame_dir, first + frames)
    print(summary(scene, frames, wall, timing, renderer, frame_dir, video_path, fps))
    if exports.written:
        print(exports.describe())
    return 0


class Exports:
    """What `run` writes besides pictures: every frame's particles in the --export formats
    and the states of --checkpoint-every, into the output folder."""

    def __init__(self, scene, out: Path, formats: tuple, every: int | None, resumed: bool = False):
        self.scene, self.out, self.formats, self.every = scene, out, formats, every
        self.usd = None
        self.written = {}  # what -> [first, last] frame numbers
        self.states = []
        if formats or every is not None:
            out.mkdir(parents=True, exist_ok=True)
        if "usd" in formats:
            from .export import UsdRecorder

            # a resumed run continues the layer there (its frames after the state's dropped)
            self.usd = UsdRecorder(out / USD_NAME, frame_rate=1.0 / scene.frame_time,
                                   keep_until=scene.frame if resumed else None)

    def frame(self):
        from .export import save_frame

        number = self.scene.frame
        if self.formats:
            data = self.scene.frame_data()
            for name in self.formats:
                if name == "usd":
                    self.usd.add(data)
                else:
                    save_frame(self.out / EXPORT_PATTERN.format(number, name), data)
                self.written.setdefault(name, [number, number])[1] = number
        if self.every is not None and number and number % self.every == 0:
            self.states.append(self.scene.save_state(self.out / STATE_PATTERN.format(number)))
            if self.usd is not None:
                self.usd.save()  # (a run resumed from this state has the frames up to it)

    def close(self):
        if self.usd is not None and self.usd.time_codes:
            self.usd.save()

    def describe(self) -> str:
        lines = []
        for name, (a, b) in self.written.items():
            where = self.out / USD_NAME if name == "usd" else self.out / EXPORT_PATTERN.format(a, name)
            lines.append(f"  {name}: {where}" + ("" if name == "usd" or a == b else f" .. {EXPORT_PATTERN.format(b, name)}")
                         + f" (frames {a} to {b})")
        if self.states:
            lines.append(f"  states: {self.states[0]}" + (f" .. {self.states[-1].name}" if len(self.states) > 1 else ""))
        return "\n".join(lines)


def remove_stale_frames(folder: Path, count: int):
    """Frames numbered past this run's last, left by a longer earlier run."""
    k = count
    while (folder / FRAME_PATTERN.format(k)).exists():
        (folder / FRAME_PATTERN.format(k)).unlink()
        k += 1


def _steady(times: list[float]):
    """(total s, per-frame s after the first, first s): the first frame compiles kernels or
    opens the window, so rates come from the others."""
    rest = times[1:] if len(times) > 1 else times
    return sum(times), sum(rest) / len(rest), times[0]


def summary(scene, frames, wall, timing, renderer, frame_dir, video_path, fps) -> str:
    n = scene.num_particles
    total, per_frame, first = _steady(timing["simulate"])
    rate = n * scene.substeps / per_frame if per_frame > 0 else float("nan")
    lines = [f"simulated {scene.time:.4g} s ({frames} frames x {scene.substeps} substeps of {scene.dt:.4g} s) "
             f"of {n:,} particles in {wall:.2f} s wall",
             f"  simulation {total:.2f} s (first frame {first:.2f} s, with kernel compiles), "
             f"then {per_frame * 1e3:.3g} ms/frame: {rate:.3g} particle-steps/s"]
    if renderer is not None:
        total, per_frame, first = _steady(timing["render"])
        lines.append(f"  rendering {total:.2f} s (first frame {first:.2f} s, opening the window), then "
                     f"{per_frame * 1e3:.3g} ms/frame: {1 / per_frame:.3g} frames/s at "
                     f"{renderer.width}x{renderer.height}; writing {timing['write']:.2f} s")
    if frame_dir is not None:
        lines.append(f"  frames: {frame_dir / FRAME_PATTERN.format(0)} .. {FRAME_PATTERN.format(frames - 1)}")
    if video_path is not None:
        lines.append(f"  video: {video_path} ({frames} frames at {fps:g} fps)")
    for body in scene.bodies:
        p, v, w = body.position, body.velocity, body.angular_velocity
        lines.append(f"  body {body.index} ({type(body.shape).__name__}, {body.mass:.4g} kg): at "
                     f"({p[0]:.4g}, {p[1]:.4g}, {p[2]:.4g}) m, velocity ({v[0]:.3g}, {v[1]:.3g}, {v[2]:.3g}) m/s, "
                     f"spin ({w[0]:.3g}, {w[1]:.3g}, {w[2]:.3g}) rad/s")
    from .types import STAT_NAMES

    stats = scene.stats()
    events = {name: stats[name] for name in STAT_NAMES}
    if any(events.values()):
        lines.append("  events: " + ", ".join(f"{k} {v}" for k, v in events.items()))
    return "\n".join(lines)


# ----------------------------------------------------------------------------- info
VULKAN_PROBE = """
import numpy as np, tai_coll as tc
from tai_coll.render import Renderer
tc.init(arch="cpu")
s = tc.Scene()
s.add_particles(positions=[[0.0, 0.0, 0.0]], radius=0.1)
image = Renderer(width=32, height=24, color_by="constant").render(s)
assert image.shape == (24, 32, 3) and image.std() > 0, image.shape
print("ok")
"""


def vulkan_status() -> tuple[bool, str]:
    """Render one small frame in a child process (a broken driver cannot take this one down)."""
    import glob
    import subprocess

    drivers = sorted({Path(p).name for d in ("/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d")
                      for p in glob.glob(f"{d}/*.json")})
    where = f"drivers: {', '.join(drivers) if drivers else 'none found in /usr/share/vulkan/icd.d'}"
    try:
        proc = subprocess.run([sys.executable, "-c", VULKAN_PROBE], capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        return False, f"a test frame did not finish in 120 s ({where})"
    if proc.returncode == 0 and proc.stdout.strip().endswith("ok"):
        return True, f"offscreen test frame rendered ({where})"
    lines = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()]
    reason = lines[-1] if lines else f"exit code {proc.returncode}"
    return False, f"{reason} ({where})"


def info(args) -> int:
    import platform

    import numpy
    import taichi as ti

    import tai_coll as tc

    from .render.errors import VULKAN_HINT

    def version(module_name):
        try:
            from importlib.metadata import version as v

            return v(module_name)
        except Exception:
            return "not installed"

    print(f"tai_coll {tc.__version__}")
    print(f"python {platform.python_version()}, numpy {numpy.__version__}, "
          f"taichi {'.'.join(map(str, ti.__version__))}, trimesh {version('trimesh')}, "
          f"imageio-ffmpeg {version('imageio-ffmpeg')}, tqdm {version('tqdm')}, plyfile {version('plyfile')}")
    usd = version("usd-core")
    print(f"usd-core (USD export, the 'usd' extra): "
          f"{usd if usd != 'not installed' else 'not installed: pip install tai_coll[usd]'}")
    ray = version("ray")
    print(f"ray (tai-coll sweep, the 'sweep' extra): "
          f"{ray if ray != 'not installed' else 'not installed: pip install tai_coll[sweep]'}")
    ok = True
    try:
        runtime = tc.init(arch=args.arch)
        print(f"arch: {args.arch} -> {runtime.arch}")
    except Exception as error:
        ok = False
        print(f"arch: {args.arch} -> failed: {error}")
    vulkan_ok, message = vulkan_status()
    print(f"vulkan (rendering): {'ok' if vulkan_ok else 'NOT AVAILABLE'}: {message}")
    if not vulkan_ok:
        print(f"  {VULKAN_HINT}")
    ok &= vulkan_ok
    try:
        from .render.video import ffmpeg_exe, ffmpeg_version

        print(f"ffmpeg (video): ok: {ffmpeg_version()} at {ffmpeg_exe()}")
    except Exception as error:
        ok = False
        print(f"ffmpeg (video): NOT AVAILABLE: {error}")
    print("ready" if ok else "not ready: see above")
    return 0 if ok else 1


# ----------------------------------------------------------------------------- entry point
def bake(argv) -> int:
    """`tai-coll bake ...` is `python -m tai_coll.bake ...` (the mesh colliders' baker)."""
    if importlib.util.find_spec("tai_coll.bake") is None:
        raise UsageError("bake needs tai_coll's mesh colliders (tai_coll.bake), which this installation lacks")
    from . import bake as baker

    return baker.main(argv)


def main(argv=None) -> int:
    logging.basicConfig(format="tai-coll: %(message)s", level=logging.WARNING)
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        if argv[:1] == ["bake"]:  # its options are the baker's own, --help included
            return bake(argv[1:])
        args = build_parser().parse_args(argv)
        if args.command == "run":
            return run(args)
        if args.command == "sweep":
            from .sweeps.command import sweep_command

            return sweep_command(args)
        return info(args)
    except UsageError as error:
        print(f"tai-coll: error: {error}", file=sys.stderr)
        return 2
    except ScriptError as error:
        print(script_traceback(error), file=sys.stderr, end="")
        print(f"tai-coll: error: {error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("tai-coll: interrupted", file=sys.stderr)
        return 130
    except Exception as error:
        from .errors import SimulationError
        from .render.errors import RenderError

        if isinstance(error, (RenderError, SimulationError)):
            print(f"tai-coll: error: {error}", file=sys.stderr)
            return 1
        traceback.print_exc()
        print(f"tai-coll: error: {type(error).__name__}: {error}", file=sys.stderr)
        return 1
