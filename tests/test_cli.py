"""The tai-coll command, run as `python -m tai_coll` in a child process (its own Taichi)."""

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# Rendering needs Vulkan (tools/setup.sh installs lavapipe); without it these fail showing the
# renderer's install hint, unless TAI_COLL_SKIP_RENDER_TESTS=1 asks to skip them.
renders = pytest.mark.skipif(os.environ.get("TAI_COLL_SKIP_RENDER_TESTS") == "1",
                             reason="TAI_COLL_SKIP_RENDER_TESTS=1")

TINY_SCENE = """
import numpy as np
import tai_coll as tc

FRAMES = 3

def scene():
    s = tc.Scene(dt=1 / 600, substeps=10)
    s.add_collider(tc.Plane(point=(0, 0, 0), normal=(0, 1, 0)))
    s.add_collider(tc.Box(center=(0.3, 0.1, 0), half_extents=(0.1, 0.1, 0.1)), velocity=(-0.5, 0, 0))
    rng = np.random.default_rng(0)
    s.add_particles(positions=rng.uniform([-0.3, 0.05, -0.2], [0.1, 0.4, 0.2], (50, 3)), radius=0.01)
    return s

def render_settings():
    return {"color_by": "height", "colormap": "plasma"}
"""


#: A line of Taichi's own log ("[W 11/27/26 06:08:54.275 5724] [file.cpp:function@66] ...").
TAICHI_LOG = re.compile(r"\[[DIWE] \d\d/\d\d/\d\d \d\d:\d\d:\d\d\.\d+ \d+\] ")


def tai_coll(*args, cwd=None, timeout=300):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    done = subprocess.run([sys.executable, "-m", "tai_coll", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=timeout)
    # Taichi's log lines are not the command's: when the suite's other process holds the lock of
    # Taichi's offline cache as this one ends, Taichi warns that it could not take it.
    done.stderr = "".join(line for line in done.stderr.splitlines(keepends=True) if not TAICHI_LOG.match(line))
    return done


def script(tmp_path, text, name="scene.py"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


@pytest.mark.slow  # two child processes, each starting Taichi and rendering
@renders
def test_run_writes_frames_and_a_video(tmp_path):
    imageio = pytest.importorskip("imageio")
    path = script(tmp_path, TINY_SCENE)
    out = tai_coll("run", path, "--frames", 5, "--res", "96x64", "--out", tmp_path / "frames", "--video",
                   tmp_path / "clip.mp4", "--fps", 25, "--arch", "cpu", "--threads", 1)
    assert out.returncode == 0, out.stderr
    pngs = sorted((tmp_path / "frames").glob("frame_*.png"))
    assert [p.name for p in pngs] == [f"frame_{k:05d}.png" for k in range(5)]
    first = imageio.v3.imread(pngs[0])
    assert first.shape == (64, 96, 3) and first.std() > 2
    with imageio.get_reader(str(tmp_path / "clip.mp4"), format="FFMPEG") as reader:
        decoded = [f for f in reader]
        assert reader.get_meta_data()["fps"] == 25
    assert len(decoded) == 5 and decoded[0].shape == (64, 96, 3)
    assert "particle-steps/s" in out.stdout and "frames/s at 96x64" in out.stdout
    assert "(5 frames x 10 substeps of 0.001667 s) of 50 particles" in out.stdout

    # the script's FRAMES and the default folders: out/SCENE/ with frames and SCENE.mp4
    again = tai_coll("run", path, "--res", "64x48", "--arch", "cpu", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert len(list((tmp_path / "out" / "scene").glob("frame_*.png"))) == 3
    assert (tmp_path / "out" / "scene" / "scene.mp4").is_file()


@renders
def test_run_without_rendering_and_as_gif(tmp_path):
    path = script(tmp_path, TINY_SCENE)
    out = tai_coll("run", path, "--frames", 2, "--no-render", "--out", tmp_path / "none", "--arch", "cpu")
    assert out.returncode == 0, out.stderr
    assert not (tmp_path / "none").exists() and "rendering" not in out.stdout
    gif = tai_coll("run", path, "--frames", 2, "--res", "80x60", "--no-frames", "--video", tmp_path / "c.gif",
                   "--arch", "cpu")
    assert gif.returncode == 0, gif.stderr
    assert (tmp_path / "c.gif").read_bytes()[:6] == b"GIF89a"


@renders
def test_a_scene_failing_mid_run_keeps_its_frames_and_leaves_no_video(tmp_path):
    # frames are written behind the simulation (render/behind.py): those rendered before the
    # failure are all written, and the video, unfinished, is not left behind
    path = script(tmp_path, """
        import tai_coll as tc

        FRAMES = 6

        class Failing(tc.Scene):
            def step(self, *args, **kwargs):
                if self.frame == 3:
                    raise RuntimeError("the scene failed at frame 3")
                return super().step(*args, **kwargs)

        def scene():
            s = Failing(dt=1 / 600, substeps=10)
            s.add_collider(tc.Plane(point=(0, 0, 0), normal=(0, 1, 0)))
            s.add_particles(positions=[[0, 0.1, 0]], radius=0.01)
            return s
        """)
    out = tai_coll("run", path, "--res", "64x48", "--out", tmp_path / "out", "--arch", "cpu", "--threads", 1)
    assert out.returncode == 1 and "the scene failed at frame 3" in out.stderr, out.stderr
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [f"frame_{k:05d}.png" for k in range(3)]


@pytest.mark.parametrize("args, reason", [
    (["--res", "0x0"], "--res must have a width and height from 1"),
    (["--res", "wide"], "--res must be WIDTHxHEIGHT"),
    (["--frames", "0"], "--frames must be >= 1"),
    (["--video", "clip.avi"], "--video must end in .mp4 or .gif"),
    (["--fps", "20000"], "--fps must be > 0 and < 10000; got 20000"),
    (["--fps", "0"], "--fps must be > 0 and < 10000; got 0"),
    (["--fps", "nan"], "--fps must be > 0 and < 10000; got nan"),
    (["--threads", "0"], "--threads must be from 1 to 1024; got 0"),
    (["--threads", "5000"], "--threads must be from 1 to 1024; got 5000"),
])
def test_bad_arguments_exit_2_with_one_line(tmp_path, args, reason):
    path = script(tmp_path, TINY_SCENE)
    out = tai_coll("run", path, *args)
    assert out.returncode == 2
    assert out.stderr.strip().splitlines() == [f"tai-coll: error: {out.stderr.split('error: ', 1)[1].strip()}"]
    assert reason in out.stderr
    assert "Starting on arch" not in out.stdout + out.stderr  # refused before Taichi started


def tree(folder: Path) -> list:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


@pytest.mark.parametrize("option, target", [
    ("--out", "a_file/frames"),          # under a regular file
    ("--out", "a_file"),                 # a regular file itself
    ("--out", "a_file/deeper/frames"),
    ("--video", "a_file/clip.mp4"),
    ("--video", "a_folder.mp4"),         # a folder where the file should go
    ("--out", "/proc/nope"),             # a folder no one can make
    ("--video", "/proc/nope/clip.gif"),
])
def test_outputs_that_cannot_be_written_exit_2_before_taichi_starts(tmp_path, option, target):
    if target.startswith("/proc") and not Path("/proc/self").exists():
        pytest.skip("no /proc here")
    path = script(tmp_path, TINY_SCENE)
    (tmp_path / "a_file").write_text("not a folder")
    (tmp_path / "a_folder.mp4").mkdir()
    before = tree(tmp_path)
    out = tai_coll("run", path, option, target if target.startswith("/") else tmp_path / target, "--arch", "cpu",
                   cwd=tmp_path)
    assert out.returncode == 2, out.stderr
    assert len(out.stderr.strip().splitlines()) == 1 and f"tai-coll: error: {option}" in out.stderr
    assert "Starting on arch" not in out.stdout + out.stderr
    assert tree(tmp_path) == before  # nothing made, nothing half-written


@pytest.mark.parametrize("frames", ["-5", "0", "2.5", "'ten'"])
def test_a_script_with_a_bad_FRAMES_exits_2_with_one_line(tmp_path, frames):
    path = script(tmp_path, TINY_SCENE.replace("FRAMES = 3", f"FRAMES = {frames}"))
    out = tai_coll("run", path, "--no-render", "--arch", "cpu")
    assert out.returncode == 2, out.stderr
    assert out.stderr.strip().splitlines() == [f"tai-coll: error: {path}: FRAMES must be an integer >= 1 (or give "
                                               f"--frames); got {frames}"]


def test_bad_scene_files(tmp_path):
    missing = tai_coll("run", tmp_path / "nowhere.py")
    assert missing.returncode == 2 and "scene file not found" in missing.stderr
    assert len(missing.stderr.strip().splitlines()) == 1

    no_function = script(tmp_path, "import tai_coll as tc\nSIZE = 3\n", "empty.py")
    out = tai_coll("run", no_function, "--arch", "cpu")
    assert out.returncode == 2 and "defines no scene() function" in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1

    raising = script(tmp_path, """
        import tai_coll as tc

        def helper():
            return tc.Sphere(radius=-1.0)

        def scene():
            s = tc.Scene()
            s.add_collider(helper())
            return s
    """, "raising.py")
    out = tai_coll("run", raising, "--arch", "cpu")
    assert out.returncode == 1
    assert "Traceback" in out.stderr and str(raising) in out.stderr and "helper()" in out.stderr
    assert "radius must be > 0" in out.stderr and "cli.py" not in out.stderr and "importlib" not in out.stderr

    broken = script(tmp_path, "def scene(:\n    pass\n", "broken.py")
    out = tai_coll("run", broken, "--arch", "cpu")
    assert out.returncode == 1 and "SyntaxError" in out.stderr and "broken.py failed while loading" in out.stderr


@renders
def test_info_is_a_preflight():
    out = tai_coll("info", "--arch", "cpu")
    assert out.returncode == 0, out.stdout + out.stderr
    assert "arch: cpu -> cpu" in out.stdout
    assert "vulkan (rendering): ok" in out.stdout and "ffmpeg (video): ok" in out.stdout
    import ray

    assert f"ray (tai-coll sweep, the 'sweep' extra): {ray.__version__}" in out.stdout
    assert out.stdout.strip().endswith("ready")


def test_console_script_entry_point_is_declared():
    text = (ROOT / "pyproject.toml").read_text()
    assert 'tai-coll = "tai_coll.cli:main"' in text
    from tai_coll import cli

    assert cli.build_parser().parse_args(["run", "x.py", "--res", "10x20"]).res == "10x20"


def test_render_size_limit_matches_the_renderer():
    from tai_coll import cli
    from tai_coll.render.renderer import MAX_SIZE

    with pytest.raises(cli.UsageError):
        cli.parse_resolution(f"{MAX_SIZE + 1}x10")
    assert cli.parse_resolution(f"{MAX_SIZE}x1") == (MAX_SIZE, 1)


def test_bake_is_the_mesh_baker_when_installed():
    import importlib.util

    out = tai_coll("bake", "--help")
    if importlib.util.find_spec("tai_coll.bake") is None:
        assert out.returncode == 2 and "bake needs tai_coll's mesh colliders" in out.stderr
    else:
        assert out.returncode == 0 and "MESH" in out.stdout, out.stderr


def test_bake_refuses_a_bad_thread_count_in_one_line():
    out = tai_coll("bake", "missing.stl", "--threads", "5000")
    assert out.returncode == 2
    assert "threads must be from 1 to" in out.stderr and "Traceback" not in out.stderr
