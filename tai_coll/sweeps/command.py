"""`tai-coll sweep SCENE.py --param NAME=V1,V2 ...`: the command-line face of tai_coll.sweeps.
Arguments are checked before Ray or Taichi start (exit 2, one line); the sweep then writes
DIR/results.csv and results.json and prints the table; exit 1 when any run failed."""

import importlib.util
import time
from pathlib import Path

from . import RAY_HINT, ray_missing, sweep
from .grid import check_signature, parse_params

DEFAULT_RES = (480, 270)
MAX_PRINTED = 40  # rows printed; results.csv has them all


def check_arguments(args):
    """(script path, grid, out folder, frame size or None); a UsageError saying what is wrong."""
    from ..scripts import UsageError, check_script_path, check_threads, check_writable, parse_resolution

    path = check_script_path(args.scene)
    try:
        grid = parse_params(args.param)
    except ValueError as error:
        raise UsageError(str(error)) from None
    if args.frames is not None and args.frames < 1:
        raise UsageError(f"--frames must be >= 1; got {args.frames}")
    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers must be >= 1; got {args.workers}")
    check_threads(args.threads)
    if args.res is not None and not args.render:
        raise UsageError("--res sets the size of the frames --render writes: add --render")
    size = (parse_resolution(args.res) if args.res is not None else DEFAULT_RES) if args.render else None
    if size is not None and min(size) < 16:
        raise UsageError(f"--res must be at least 16x16 for a contact sheet; got {args.res}")
    out = Path(args.out) if args.out else Path("out") / f"{path.stem}_sweep"
    check_writable("--out", out)
    if ray_missing():
        raise UsageError(f"tai-coll sweep needs Ray, which is not installed: {RAY_HINT}")
    if args.render and importlib.util.find_spec("PIL") is None:
        raise UsageError(f"--render needs Pillow for the contact sheet's labels: {RAY_HINT}")
    return path, grid, out, size


def format_cell(value) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return "" if value is None else str(value)


def table(rows: list, names: list) -> str:
    """The rows as aligned text columns (status last, not padded)."""
    cells = [[format_cell(row.get(n)) for n in names] for row in rows]
    widths = [max([len(n)] + [len(c[k]) for c in cells]) for k, n in enumerate(names)]
    lines = ["  ".join(n.rjust(w) if n != "status" else n for n, w in zip(names, widths))]
    for c in cells:
        lines.append("  ".join(v.rjust(w) if n != "status" else v for v, n, w in zip(c, names, widths)))
    return "\n".join(lines)


def sweep_command(args) -> int:
    from ..scripts import ScriptError, UsageError, load_script, script_frames
    from .results import columns

    path, grid, out, size = check_arguments(args)
    module = load_script(path)
    make = getattr(module, "scene", None)
    if not callable(make):
        raise UsageError(f"{path} defines no scene() function (it must return a tc.Scene)")
    try:
        check_signature(make, list(grid), f"{path}: scene()")
    except ValueError as error:
        raise UsageError(str(error)) from None
    metrics = getattr(module, "metrics", None)
    if metrics is not None and not callable(metrics):
        raise UsageError(f"{path}: metrics must be a function metrics(scene) -> dict; got {type(metrics).__name__}")
    frames = args.frames if args.frames is not None else script_frames(module, path)
    settings = getattr(module, "render_settings", None) if size is not None else None
    start = time.perf_counter()
    try:
        rows = sweep(make, grid, frames, metrics=metrics, address=args.address, workers=args.workers,
                     arch=args.arch, threads=args.threads, out=out, render=size, render_settings=settings,
                     folder=path.resolve().parent)
    except (ValueError, TypeError) as error:
        raise UsageError(str(error)) from None
    except ConnectionError as error:
        raise UsageError(f"--address: {error}") from None
    except Exception as error:  # Ray could not start, or pickling the script's functions failed
        raise ScriptError(path, "to start the sweep", error) from error
    wall = time.perf_counter() - start
    names = [n for n in columns(rows) if n not in ("pid", "node", "frame_png")]
    shown = rows[:MAX_PRINTED]
    print(table(shown, names))
    if len(rows) > len(shown):
        print(f"... {len(rows) - len(shown)} more rows in {out / 'results.csv'}")
    failed = [row for row in rows if row["status"] != "ok"]
    workers = {(row["node"], row["pid"]) for row in rows if row.get("pid") is not None}
    print(f"{len(rows)} runs of {frames} frames, {len(rows) - len(failed)} ok, {len(failed)} failed, in "
          f"{wall:.1f} s on {len(workers)} worker process(es)")
    written = [out / "results.csv", out / "results.json"]
    if (out / "contact_sheet.png").exists() and size is not None:
        written.append(out / "contact_sheet.png")
    print("wrote " + ", ".join(str(p) for p in written))
    return 1 if failed else 0

