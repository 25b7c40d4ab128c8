"""Taichi's CPU worker threads, each kept on a CPU of its own.

Taichi 1.7 runs a parallel loop on a pool of `cpu_max_num_threads` workers that sleep between
loops. Left to the operating system's scheduler, a worker woken for the next loop is often
queued on a CPU where another thread runs, and the loop waits for it: on the 2-core machine
of docs/benchmarks.md the bed of `tools/bench_warp.py` ran 2 threads at 1.4 times the speed
of one, and at 1.9 times with each worker kept on its own CPU (docs/design-notes.md,
"Taichi's workers on CPUs of their own").

So `tc.init` on the CPU gives each worker one CPU, in order, when the pool has exactly one
worker for every CPU the process may run on (`os.sched_getaffinity`): the process then means to
use them all, and its workers never share one. With fewer workers (a sweep's runs with a thread
or two each on a large machine, say) the workers stay free to move, so that processes side by
side do not all crowd the same CPUs. Linux only (it reads the threads from /proc); elsewhere,
with another Taichi version, or with TAI_COLL_PIN_THREADS=0, nothing is pinned. Which thread a
loop's work lands on never changes a result: the kernels split their work so that any thread
may do any part (docs/design-notes.md, "Slabs").
"""

from __future__ import annotations

import os

from .frontend_cache import may_patch

TASKS = "/proc/self/task"


def thread_ids() -> frozenset:
    """The process's threads now (Linux; empty elsewhere)."""
    try:
        return frozenset(int(name) for name in os.listdir(TASKS))
    except OSError:
        return frozenset()


def pin_workers(before: frozenset, workers: int) -> tuple:
    """Keep each of Taichi's `workers` CPU workers on a CPU of its own; `before`: the thread
    ids from just before `ti.init` started them. Taichi 1.7 starts its compile threads and
    then the pool's workers, so the pool is the newest `workers` threads. Returns the
    (thread id, CPU) pairs pinned: none unless may_patch("TAI_COLL_PIN_THREADS") and the
    pool has one worker for every CPU the process may use."""
    if not (may_patch("TAI_COLL_PIN_THREADS") and hasattr(os, "sched_setaffinity")):
        return ()
    cpus = sorted(os.sched_getaffinity(0))
    started = sorted(thread_ids() - before - {os.getpid()})
    if workers != len(cpus) or len(started) < workers:
        return ()
    pinned = []
    for thread, cpu in zip(started[-workers:], cpus):
        try:
            os.sched_setaffinity(thread, {cpu})
        except OSError:  # (the thread has ended, or the system refuses: leave the rest free)
            continue
        pinned.append((thread, cpu))
    return tuple(pinned)
