"""Taichi's CPU workers kept on CPUs of their own (tai_coll/cpu_threads.py): which threads are
pinned, when, and that pinning changes no result. Each case starts Taichi in a process of its
own (the session's Taichi stays as conftest started it)."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from tai_coll import cpu_threads

pytestmark = pytest.mark.skipif(not (sys.platform.startswith("linux") and hasattr(os, "sched_setaffinity")),
                                reason="threads are pinned on Linux only")

PROBE = r'''
import json, os, sys
import numpy as np
import taichi as ti
import tai_coll as tc
from tai_coll.cpu_threads import thread_ids

threads, frames, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
before = thread_ids()
info = tc.init(arch="cpu", precision="f64", threads=threads, seed=0)
started = sorted(thread_ids() - before)
field = ti.field(ti.f64, shape=1 << 20)


@ti.kernel
def busy():
    for i in range(1 << 20):
        x = ti.cast(i, ti.f64)
        for _ in range(200):
            x = ti.sqrt(x * 0.5 + 1.0)
        field[i] = x


def alive(read):  # read(t) for each started thread still running (one of ti.init's short-lived
    found = {}      # helper threads may end at any moment, before or during the read)
    for t in started:
        try:
            found[t] = read(t)
        except (ProcessLookupError, FileNotFoundError):
            pass
    return found


def ran():  # each started thread's time on a CPU so far, ns (None: the kernel keeps no such count)
    if not os.path.exists(f"/proc/self/task/{os.getpid()}/schedstat"):
        return None
    return alive(lambda t: int(open(f"/proc/self/task/{t}/schedstat").read().split()[0]))


busy()
ti.sync()
start = ran()
busy()
ti.sync()
end = ran()
report = dict(pinned=[list(p) for p in info.pinned_threads], started=started,
              ran=None if start is None else [t for t in end if t in start and end[t] > start[t]],
              affinity=alive(lambda t: sorted(os.sched_getaffinity(t))))
if frames:
    rng = np.random.default_rng(3)
    g = np.arange(-8, 8) * 0.0105
    lattice = np.stack(np.meshgrid(g, np.arange(20) * 0.0105 + 0.006, g, indexing="ij"), -1).reshape(-1, 3)
    scene = tc.Scene(dt=1e-3, substeps=5)
    for point, normal in (((0, 0, 0), (0, 1, 0)), ((-0.1, 0, 0), (1, 0, 0)), ((0.1, 0, 0), (-1, 0, 0)),
                          ((0, 0, -0.1), (0, 0, 1)), ((0, 0, 0.1), (0, 0, -1))):
        scene.add_collider(tc.Plane(point=point, normal=normal), material=tc.Material(restitution=0.3, friction=0.4))
    scene.enable_particle_collisions(material=tc.Material(restitution=0.3, friction=0.4))
    scene.add_particles(positions=lattice + rng.uniform(-0.001, 0.001, lattice.shape), radius=0.005)
    scene.step(frames)
    np.savez(out + ".npz", x=scene.positions(), v=scene.velocities())
with open(out + ".json", "w") as f:
    json.dump(report, f)
'''


def _probe(tmp_path, name, threads, frames=0, pin="1"):
    script = tmp_path / "probe.py"
    script.write_text(PROBE)
    out = tmp_path / name
    env = dict(os.environ, TAI_COLL_PIN_THREADS=pin)
    run = subprocess.run([sys.executable, str(script), str(threads), str(frames), str(out)], capture_output=True,
                         text=True, env=env, timeout=600)
    assert run.returncode == 0, run.stderr
    report = json.loads((tmp_path / f"{name}.json").read_text())
    report["affinity"] = {int(t): cpus for t, cpus in report["affinity"].items()}
    return report, (np.load(f"{out}.npz") if frames else None)


def test_each_worker_runs_on_a_cpu_of_its_own_when_there_is_one_for_every_cpu(tmp_path):
    cpus = sorted(os.sched_getaffinity(0))
    report, _ = _probe(tmp_path, "pinned", len(cpus))
    pinned = dict(map(tuple, report["pinned"]))
    assert sorted(pinned.values()) == cpus  # every CPU once
    for thread, cpu in pinned.items():
        assert report["affinity"][thread] == [cpu]
    # the pinned threads are Taichi's pool: only they, among the threads ti.init started, ran
    # the parallel loop (the others compile kernels); on a machine of few CPUs, each of them
    # (on many, a worker that wakes late may find the loop's share taken)
    if report["ran"] is not None:
        assert report["ran"] and set(report["ran"]) <= set(pinned)
        if len(cpus) <= 4:
            assert sorted(report["ran"]) == sorted(pinned)
    # the pool's workers live on; the threads still running besides them stay free
    for thread in set(report["affinity"]) - set(pinned):
        assert report["affinity"][thread] == cpus


def test_workers_stay_free_with_fewer_or_more_than_the_cpus_or_when_turned_off(tmp_path):
    cpus = sorted(os.sched_getaffinity(0))
    cases = [("off", len(cpus), "0"), ("more", len(cpus) + 1, "1")]
    if len(cpus) > 1:
        cases.append(("fewer", len(cpus) - 1, "1"))
    for name, threads, pin in cases:
        report, _ = _probe(tmp_path, name, threads, pin=pin)
        assert report["pinned"] == [], name
        assert len(report["affinity"]) >= threads, name  # the pool's workers, at least, still run
        assert all(cpus_of == cpus for cpus_of in report["affinity"].values()), name


def test_pinned_workers_give_the_same_bits(tmp_path):
    # 5,120 particles, enough for the thread pool's kernels (serial_loops leaves them to it),
    # Gauss-Seidel pairs with sleeping: 40 frames with the workers pinned and free
    threads = len(os.sched_getaffinity(0))
    pinned, state = _probe(tmp_path, "on", threads, frames=40, pin="1")
    free, state_free = _probe(tmp_path, "off", threads, frames=40, pin="0")
    assert len(pinned["pinned"]) == threads and free["pinned"] == []
    assert np.isfinite(state["x"]).all() and state["x"][:, 1].mean() < 0.08  # falling into a pile (from 0.106)
    assert np.array_equal(state["x"], state_free["x"]) and np.array_equal(state["v"], state_free["v"])


def test_pin_workers_refuses_when_turned_off_or_on_a_mismatch(monkeypatch):
    # the function itself, in this process: nothing is touched unless the counts match
    monkeypatch.setenv("TAI_COLL_PIN_THREADS", "0")
    assert cpu_threads.pin_workers(frozenset(), 1) == ()
    monkeypatch.setenv("TAI_COLL_PIN_THREADS", "1")
    now = cpu_threads.thread_ids()
    assert os.getpid() in now
    assert cpu_threads.pin_workers(now, len(os.sched_getaffinity(0))) == ()  # no thread started since
    assert cpu_threads.pin_workers(frozenset(), len(os.sched_getaffinity(0)) + 1) == ()
