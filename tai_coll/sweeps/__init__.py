"""Parameter sweeps on Ray (docs/api.md "Sweeps"): every combination of a scene function's
parameters runs as one Ray task, on a local cluster sized to the machine or on an existing
one by address; the rows come back with the parameters, the metrics, the wall time, the
worker's pid and node, and a status.

Ray is an optional extra (`pip install 'tai_coll[sweep]'`); nothing here imports it before a
sweep starts."""

import functools
import logging
import numbers
import os
import sys
import sysconfig
import time
from pathlib import Path

from ..runtime import ARCHS, MAX_THREADS
from .grid import check_grid, check_signature, combinations, parse_param, parse_params, parse_value
from .results import read_results, write_results
from .sheet import contact_sheet, layout

__all__ = ["sweep", "parse_param", "parse_params", "parse_value", "combinations", "write_results", "read_results",
           "contact_sheet", "layout", "ray_missing", "RAY_HINT"]

RAY_HINT = "pip install 'tai_coll[sweep]'"
GPU_ARCHS = tuple(arch for arch in ARCHS if arch != "cpu")  # the archs a run may take a GPU for
LOCAL_OBJECT_STORE = 256 * 1024 ** 2  # bytes: rows and their compressed frames are small
SAVE_EVERY = 5.0  # seconds between rewrites of the results while runs finish


def ray_missing() -> bool:
    import importlib.util

    return importlib.util.find_spec("ray") is None


def require_ray():
    try:
        import ray
    except ImportError:
        raise ImportError(f"sweeps need Ray, which is not installed: {RAY_HINT}") from None
    return ray


def _library_file(path) -> bool:
    """Whether a module file lies in the standard library or site-packages (importable by
    name on every worker), not in a user's folder."""
    if not path:
        return True
    path = os.path.realpath(path)
    roots = {os.path.realpath(p) for key in ("stdlib", "platstdlib", "purelib", "platlib")
             if (p := sysconfig.get_paths().get(key))}
    return any(path.startswith(root + os.sep) for root in roots)


def pack(callables: dict) -> bytes:
    """The callables pickled for the workers. A function from a user's module (a scene script
    loaded by path, a test file, a notebook) goes by value: a worker may not import it by name."""
    from ray import cloudpickle

    modules = set()
    for fn in callables.values():
        while isinstance(fn, functools.partial):
            fn = fn.func
        name = getattr(fn, "__module__", None)
        module = sys.modules.get(name) if name else None
        if module is not None and name != "__main__" and name.split(".")[0] != "tai_coll" \
                and not _library_file(getattr(module, "__file__", None)):
            modules.add(module)
    registered = []
    try:
        for module in modules:
            cloudpickle.register_pickle_by_value(module)
            registered.append(module)
        return cloudpickle.dumps(callables)
    finally:
        for module in registered:
            cloudpickle.unregister_pickle_by_value(module)


def check_arguments(scene_fn, grid, frames, metrics, address, workers, arch, threads, out, render):
    if not callable(scene_fn):
        raise TypeError(f"scene_fn must be callable (a function returning a tc.Scene); got {type(scene_fn).__name__}")
    grid = check_grid(grid)
    check_signature(scene_fn, list(grid), "scene_fn")
    if isinstance(frames, bool) or not isinstance(frames, numbers.Integral) or frames < 1:
        raise ValueError(f"frames must be an integer >= 1; got {frames!r}")
    if metrics is not None and not callable(metrics):
        raise TypeError(f"metrics must be callable as metrics(scene) -> dict, or None; got {type(metrics).__name__}")
    if address is not None and (not isinstance(address, str) or not address.strip()):
        raise ValueError(f"address must be a Ray cluster address such as '127.0.0.1:6379'; got {address!r}")
    for name, value, top in (("workers", workers, None), ("threads", threads, MAX_THREADS)):
        if value is None and name == "workers":
            continue
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1 or (top and value > top):
            raise ValueError(f"{name} must be an integer >= 1{f' and <= {top}' if top else ''}; got {value!r}")
    if arch not in ARCHS:
        raise ValueError(f"arch must be one of {', '.join(ARCHS)}; got {arch!r}")
    if render is not None:
        if out is None:
            raise ValueError("render needs out: the folder for the frames and the contact sheet")
        if (not isinstance(render, (tuple, list)) or len(render) != 2
                or not all(isinstance(v, numbers.Integral) and not isinstance(v, bool) and 16 <= v <= 8192
                           for v in render)):
            raise ValueError(f"render must be (width, height) in pixels, each 16 to 8192; got {render!r}")
    return grid


def connect(ray, address, workers, threads) -> bool:
    """Join the cluster at `address` (or RAY_ADDRESS), or start a local one of `workers` runs
    at a time (default: one per core). Returns whether this call started Ray (and so stops it)."""
    if ray.is_initialized():
        return False  # the caller's own session
    address = address or os.environ.get("RAY_ADDRESS") or None
    quiet = dict(log_to_driver=False, logging_level=logging.WARNING)
    if address:
        token_auth_if_available()
        ray.init(address=address, **quiet)
    else:
        cpus = (workers or max(1, (os.cpu_count() or 1) // threads)) * threads
        ray.init(num_cpus=cpus, include_dashboard=False, object_store_memory=LOCAL_OBJECT_STORE, **quiet)
    return True


def token_auth_if_available():
    """Ray 2.59 and 2.60 start local clusters (`ray start --head` too) with token
    authentication where the user set no RAY_AUTH_MODE, but a driver joining one by address
    sends the token only in token mode (Ray 2.61 turns it on everywhere). Where no mode is set
    and a token is at hand (~/.ray/auth_token, RAY_AUTH_TOKEN), switch this process to token
    mode the way Ray itself does for its local clusters; a cluster without authentication
    accepts such a driver as well. Rays without token authentication have nothing to do."""
    try:
        from ray._private.authentication.authentication_token_setup import (
            maybe_enable_token_auth_if_token_available)
    except ImportError:
        return
    maybe_enable_token_auth_if_token_available(warn_if_disabled=False)


def task_resources(ray, arch, threads) -> dict:
    """One GPU a run where the cluster has GPUs and the arch may use one; else `threads` CPUs."""
    resources = ray.cluster_resources()
    if arch in GPU_ARCHS and resources.get("GPU", 0) >= 1:
        return {"num_gpus": 1, "num_cpus": 1}
    if resources.get("CPU", 0) < threads:
        raise ValueError(f"threads = {threads}: the cluster has only {resources.get('CPU', 0):g} CPUs")
    return {"num_cpus": threads}


def sweep(scene_fn, grid: dict, frames: int, *, metrics=None, address: str | None = None,
          workers: int | None = None, arch: str = "auto", threads: int = 1, out=None,
          render: tuple | None = None, render_settings=None, progress: bool = True, folder=None) -> list:
    """Run scene_fn(**combination) for `frames` frames for every combination of `grid`'s
    values ({name: [values]}, the cartesian product), each as a Ray task, and return the rows
    in the grid's order: {"run", <parameters>, <metrics(scene) after the last frame>, "wall_time",
    "pid", "node", "status"} with status "ok" or the run's error ("ValueError: ..."). A run
    that fails does not stop the others.

    address: an existing Ray cluster ("HOST:PORT"; default RAY_ADDRESS, else a local cluster
        sized to the machine, stopped afterwards). A Ray session already started in this
        process is used as it is.
    workers: runs at a time (default: the local cluster's cores / threads; on a cluster, all
        it schedules).
    arch, threads: each run's tai_coll.init (threads: CPU threads a run, and the CPUs its
        task reserves). Where the cluster has GPUs and arch may use one, a run takes one GPU.
    out: a folder for results.csv and results.json (and, with render=(width, height), each
        run's last frame run_NNNN.png and contact_sheet.png; render_settings() returns the
        Renderer's keyword arguments, as a scene script's does).
    folder: a folder to put on the workers' sys.path (the scene script's).
    Raises TypeError/ValueError naming the argument before anything runs, ImportError naming
    the extra when Ray is missing.
    """
    grid = check_arguments(scene_fn, grid, frames, metrics, address, workers, arch, threads, out, render)
    if render_settings is not None and not callable(render_settings):
        raise TypeError(f"render_settings must be callable, returning a dict; got {type(render_settings).__name__}")
    ray = require_ray()
    runs = combinations(grid)
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
    job = {"payload": pack({"scene": scene_fn, "metrics": metrics, "render_settings": render_settings}),
           "folder": str(folder) if folder is not None else None}
    options = {"arch": arch, "threads": threads, "render": tuple(render) if render else None}
    started = connect(ray, address, workers, threads)
    save = (lambda done: write_results(out, done)) if out is not None else None
    frames_png = {}
    try:
        rows = run_tasks(ray, job, runs, frames, options, workers, progress, save,
                         keep_frame=(lambda row: write_frame(out, row, frames_png)) if render else None)
    finally:
        if started:
            ray.shutdown()
    if out is not None:
        write_results(out, rows)
        if render:
            write_sheet(out, [frames_png.get(row["run"]) for row in rows], runs, grid)
    return rows


def run_tasks(ray, job, runs, frames, options, workers, progress, save=None, keep_frame=None) -> list:
    """Submit the runs (at most `workers` in flight when given) and gather their rows.
    save(rows finished so far, in run order) is called every SAVE_EVERY seconds as runs
    finish, so an interrupted sweep leaves the rows it has; keep_frame(row) as each rendered
    run comes back."""
    from tqdm import tqdm

    from .worker import describe, run_one

    task = ray.remote(run_one).options(max_retries=0, **task_resources(ray, options["arch"], options["threads"]))
    job_ref = ray.put(job)
    pending, rows, waiting = {}, [None] * len(runs), list(enumerate(runs))
    bar = tqdm(total=len(runs), desc="sweep", unit="run", dynamic_ncols=True, file=sys.stderr,
               disable=None if progress else True)
    failed, saved = 0, time.monotonic()
    try:
        while waiting or pending:
            while waiting and (workers is None or len(pending) < workers):
                index, params = waiting.pop(0)
                pending[task.remote(job_ref, index, params, frames, options)] = (index, params)
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                index, params = pending.pop(ref)
                try:
                    rows[index] = ray.get(ref)
                except Exception as error:  # the worker process died (out of memory, a crash)
                    rows[index] = {"run": index, **params, "wall_time": None, "pid": None, "node": None,
                                   "status": describe(error)}
                if keep_frame is not None:
                    keep_frame(rows[index])
                failed += rows[index]["status"] != "ok"
                bar.set_postfix(failed=failed, refresh=False)
                bar.update(1)
            if save is not None and pending and time.monotonic() - saved > SAVE_EVERY:
                save([row for row in rows if row is not None])
                saved = time.monotonic()
    finally:
        bar.close()
    return rows


def write_frame(out: Path, row: dict, frames: dict):
    """A rendered run's PNG bytes (FRAME_KEY, taken out of the row) into DIR/run_NNNN.png;
    the row's frame_png names the file ("" when the run failed), frames[run] its bytes."""
    from ..export import atomic_write
    from .worker import FRAME_KEY, FRAME_PATTERN

    data = row.pop(FRAME_KEY, None)
    row["frame_png"] = ""
    if row["status"] != "ok" or not data:
        return
    name = FRAME_PATTERN.format(row["run"])

    def write(path):
        with open(path, "wb") as f:
            f.write(data)

    atomic_write(out / name, write)
    row["frame_png"] = name
    frames[row["run"]] = data  # compressed until the sheet is made


def write_sheet(out: Path, frames: list, runs: list, grid: dict):
    """DIR/contact_sheet.png from the runs' PNG bytes (None: a failed run, whose tile says so)."""
    import io

    import numpy as np
    from PIL import Image

    from ..render import write_png

    def pixels(data):
        with Image.open(io.BytesIO(data)) as image:
            return np.asarray(image.convert("RGB"))

    if any(f is not None for f in frames):
        write_png(out / "contact_sheet.png", contact_sheet([None if f is None else pixels(f) for f in frames],
                                                          runs, grid))
