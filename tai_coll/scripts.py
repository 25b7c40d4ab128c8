"""Scene scripts for the command line: finding, loading and calling them, and the two kinds of
failure `tai-coll` reports (bad arguments: exit 2, one line; the script raised: exit 1, with
its traceback). Shared by `tai-coll run` (tai_coll.cli) and `tai-coll sweep`
(tai_coll.sweeps.command)."""

import importlib.util
import numbers
import sys
import tempfile
import traceback
from pathlib import Path

DEFAULT_FRAMES = 120


class UsageError(Exception):
    """Bad arguments: reported in one line, exit status 2."""


class ScriptError(Exception):
    """The scene script raised: its traceback is reported, exit status 1."""

    def __init__(self, path: Path, what: str, error: BaseException):
        super().__init__(f"{path} failed {what}: {type(error).__name__}: {error}")
        self.path, self.error = path, error


def check_threads(threads):
    """UsageError unless --threads is None (all cores) or from 1 to MAX_THREADS."""
    from .runtime import MAX_THREADS

    if threads is not None and not 1 <= threads <= MAX_THREADS:
        raise UsageError(f"--threads must be from 1 to {MAX_THREADS}; got {threads}")


def parse_resolution(text: str):
    from .render.renderer import MAX_SIZE

    parts = text.lower().split("x")
    try:
        width, height = (int(p) for p in parts)
    except ValueError:
        raise UsageError(f"--res must be WIDTHxHEIGHT, e.g. 1280x720; got {text!r}") from None
    if not (1 <= width <= MAX_SIZE and 1 <= height <= MAX_SIZE):
        raise UsageError(f"--res must have a width and height from 1 to {MAX_SIZE} pixels; got {text!r}")
    return width, height


def check_script_path(text: str) -> Path:
    """The scene script's path, or a UsageError saying why it is not one."""
    path = Path(text)
    if not path.exists():
        raise UsageError(f"scene file not found: {path}")
    if not path.is_file():
        raise UsageError(f"scene path is not a file: {path}")
    if path.suffix != ".py":
        raise UsageError(f"scene file must be a Python script (.py): {path}")
    return path


def check_writable(option: str, folder: Path):
    """UsageError unless `folder` exists or can be made, and a file can be written in it.
    Tried for real (permission bits do not tell, e.g. for root under /proc), and undone:
    folders made here are removed again, so a run that fails later leaves nothing behind."""
    made = []
    try:
        missing = []
        for part in (folder, *folder.parents):
            if part.exists():
                break
            missing.append(part)
        for part in reversed(missing):
            part.mkdir()
            made.append(part)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as error:
        raise UsageError(f"{option}: cannot write in {folder}: {error.strerror or error}") from None
    finally:
        for part in reversed(made):
            try:
                part.rmdir()
            except OSError:
                pass


def load_script(path: Path):
    """Import a scene script as a module (its folder on sys.path, as `python SCRIPT` has)."""
    name = f"tai_coll_scene_{path.stem}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    folder = str(path.resolve().parent)
    if folder not in sys.path:
        sys.path.insert(0, folder)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except Exception as error:
        raise ScriptError(path, "while loading", error) from error
    return module


def build_scene(module, path: Path):
    import tai_coll as tc

    make = getattr(module, "scene", None)
    if not callable(make):
        raise UsageError(f"{path} defines no scene() function (it must return a tc.Scene)")
    try:
        scene = make()
    except Exception as error:
        raise ScriptError(path, "in scene()", error) from error
    if not isinstance(scene, tc.Scene):
        raise UsageError(f"{path}: scene() must return a tc.Scene; got {type(scene).__name__}")
    return scene


def render_settings(module, path: Path) -> dict:
    make = getattr(module, "render_settings", None)
    if make is None:
        return {}
    try:
        settings = make()
    except Exception as error:
        raise ScriptError(path, "in render_settings()", error) from error
    if not isinstance(settings, dict):
        raise UsageError(f"{path}: render_settings() must return a dict of Renderer arguments; "
                         f"got {type(settings).__name__}")
    return dict(settings)


def script_traceback(error: ScriptError) -> str:
    """The traceback from the script's own frames on (tai-coll's loader frames left out)."""
    te = traceback.TracebackException.from_exception(error.error)
    script = str(error.path.resolve())
    frames = list(te.stack)
    for i, frame in enumerate(frames):
        if str(Path(frame.filename).resolve()) == script:
            te.stack = traceback.StackSummary.from_list(frames[i:])
            break
    return "".join(te.format())


def script_frames(module, path: Path) -> int:
    """The script's FRAMES (default DEFAULT_FRAMES): an integer >= 1, else a UsageError."""
    frames = getattr(module, "FRAMES", DEFAULT_FRAMES)
    if isinstance(frames, bool) or not isinstance(frames, numbers.Integral) or frames < 1:
        raise UsageError(f"{path}: FRAMES must be an integer >= 1 (or give --frames); got {frames!r}")
    return int(frames)
