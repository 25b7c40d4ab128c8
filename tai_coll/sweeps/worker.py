"""One run of a sweep, as a Ray worker process executes it: build the scene from its
parameters, step it, check its state, read its metrics, render its last frame.

A worker process keeps its Taichi runtime between runs (tai_coll.init returns the running
one when the settings are the same), so a kernel compiles once per worker; Taichi's offline
cache keeps it on disk for the workers after. Nothing here raises: a failure becomes the
row's status, so the other runs of the sweep go on."""

import os
import pickle
import sys
import time

import numpy as np

from .grid import is_number

RESERVED = ("run", "wall_time", "pid", "node", "status", "frame_png")
FRAME_PATTERN = "run_{:04d}.png"
FRAME_KEY = "_frame"  # a rendered run's PNG bytes, on their way to the driver

_jobs = {}        # the unpickled callables of a job, by its bytes (one sweep's runs share them)
_renderers = {}   # one Renderer per size and settings: GGUI keeps one offscreen window per process


def load_job(job: dict) -> dict:
    """The job's callables. Its folder (a scene script's) goes on sys.path first, as `python
    SCRIPT` has it, so a script importing a module beside it unpickles here too."""
    payload = job["payload"]
    if payload not in _jobs:
        folder = job.get("folder")
        if folder and os.path.isdir(folder) and folder not in sys.path:
            sys.path.insert(0, folder)
        _jobs.clear()
        _jobs[payload] = pickle.loads(payload)
    return _jobs[payload]


def node_address() -> str:
    try:
        import ray

        return ray.util.get_node_ip_address()
    except Exception:  # outside Ray (a direct call), or a Ray without it
        import socket

        return socket.gethostname()


def describe(error: BaseException) -> str:
    """The row's status for a failure: the exception's type and message, on one line."""
    message = " ".join(str(error).split())
    return f"{type(error).__name__}: {message}" if message else type(error).__name__


def check_state(scene):
    """RuntimeError unless every particle's position and velocity is finite."""
    if scene.num_particles == 0:
        return
    bad = ~(np.isfinite(scene.positions()).all(axis=1) & np.isfinite(scene.velocities()).all(axis=1))
    if bad.any():
        raise RuntimeError(f"non-finite state after the last frame: {int(bad.sum())} particle(s) "
                           f"(first {np.flatnonzero(bad)[:5].tolist()})")


def check_metrics(values, params) -> dict:
    """The metrics dict as plain Python numbers; TypeError/ValueError saying what is wrong."""
    if not isinstance(values, dict):
        raise TypeError(f"metrics() must return a dict of numbers; got {type(values).__name__}")
    checked = {}
    for name, value in values.items():
        if not isinstance(name, str) or not name:
            raise TypeError(f"metrics() keys must be non-empty strings; got {name!r}")
        if name in RESERVED or name in params:
            raise ValueError(f"metrics() key {name!r} clashes with a column of the results "
                             f"(the parameters and {', '.join(RESERVED)})")
        if isinstance(value, np.generic):
            value = value.item()
        if not is_number(value):
            raise TypeError(f"metrics()[{name!r}] must be a number; got {type(value).__name__}")
        checked[name] = value
    return checked


def renderer_for(size, settings: dict):
    from ..render import Renderer

    key = (tuple(size), repr(sorted(settings.items())))
    if key not in _renderers:
        _renderers[key] = Renderer(width=size[0], height=size[1], **settings)
    return _renderers[key]


def render_last(scene, size, make_settings) -> bytes:
    """The scene's frame as PNG bytes: they travel back with the row, so the driver writes the
    files where it runs (a cluster's nodes need not share a file system)."""
    from ..render import encode_png

    settings = dict(make_settings()) if make_settings is not None else {}
    settings.pop("width", None), settings.pop("height", None)
    return encode_png(renderer_for(size, settings).render(scene))


def run_one(job: dict, index: int, params: dict, frames: int, options: dict) -> dict:
    """Run one combination; returns its row: run, the parameters, the metrics, wall_time, pid,
    node, status ("ok" or the error) and, when rendering, FRAME_KEY: the last frame's PNG
    bytes (None when the run failed), which the driver writes and removes from the row."""
    import tai_coll as tc

    start = time.perf_counter()
    row = {"run": index, **params}
    metrics, status, frame = {}, "ok", None
    try:
        callables = load_job(job)
        tc.init(arch=options["arch"], threads=options["threads"])
        scene = callables["scene"](**params)
        if not isinstance(scene, tc.Scene):
            raise TypeError(f"scene() must return a tc.Scene; got {type(scene).__name__}")
        for _ in range(frames):
            scene.step()
        check_state(scene)
        if callables.get("metrics") is not None:
            metrics = check_metrics(callables["metrics"](scene), params)
        if options.get("render"):
            frame = render_last(scene, options["render"], callables.get("render_settings"))
    except Exception as error:
        status = describe(error)
    row.update(metrics)
    row.update(wall_time=round(time.perf_counter() - start, 4), pid=os.getpid(), node=node_address(), status=status)
    if options.get("render"):
        row[FRAME_KEY] = frame
    return row

