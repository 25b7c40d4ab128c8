"""Taichi start-up: which arch, which float precision, how many CPU threads.

`init()` is the only place that calls `ti.init`. Every other module asks `ensure_init()`
first, so using the API before `init()` starts the default arch ("auto"). Calling `init()`
again with the same arguments does nothing; different arguments restart Taichi, and
scenes built before then refuse every call (their fields belong to the old runtime:
`check_generation`, applied to a class by `bound_to_runtime`).
"""

from __future__ import annotations

import ctypes
import functools
import inspect
import numbers
import os
import platform
from dataclasses import dataclass

import numpy as np
import taichi as ti

from . import cpu_threads, fast_launch, frontend_cache, host_arrays, serial_loops

ARCHS = ("auto", "cpu", "gpu", "cuda", "vulkan", "metal")
PRECISIONS = ("f32", "f64")
# A fixed ceiling, the same on every machine: far above any core count in use, yet Taichi
# starts that many CPU workers in well under a second (10**6 hangs and exhausts the
# machine's threads).
MAX_THREADS = 1024
MAX_SEED = 2**31 - 1  # Taichi keeps its random seed in an int32 (2**31 and above: TypeError)
OFFLINE_CACHE_BYTES = 1 << 30  # 1 GiB of compiled kernels kept between runs (see _start; Taichi takes an int32)


@dataclass(frozen=True)
class RuntimeInfo:
    """What `init()` settled on. `arch` is the arch Taichi actually runs on."""

    requested_arch: str
    arch: str
    precision: str
    threads: int | None
    seed: int
    generation: int
    pinned_threads: tuple = ()  # (thread id, CPU) of each Taichi CPU worker kept on a CPU (cpu_threads)

    @property
    def float_dtype(self):
        return np.float64 if self.precision == "f64" else np.float32


_info: RuntimeInfo | None = None
_generation = 0


def _check_init_args(arch, precision, threads, seed):
    if not isinstance(arch, str):
        raise TypeError(f"arch must be a string, one of {ARCHS}; got {type(arch).__name__}")
    if arch not in ARCHS:
        raise ValueError(f"arch must be one of {ARCHS}; got {arch!r}")
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be 'f32' or 'f64'; got {precision!r}")
    if threads is not None:
        if isinstance(threads, bool) or not isinstance(threads, numbers.Integral):
            raise TypeError(f"threads must be an integer or None; got {threads!r}")
        if not 1 <= threads <= MAX_THREADS:
            raise ValueError(f"threads must be from 1 to {MAX_THREADS}; got {threads}")
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or not 0 <= seed <= MAX_SEED:
        raise ValueError(f"seed must be an integer from 0 to {MAX_SEED} (2**31 - 1); got {seed!r}")
    if precision == "f64" and arch in ("vulkan", "metal"):
        raise ValueError(f"precision='f64' is not supported on arch={arch!r}; use 'f32'")


def _cuda_driver_present() -> bool:
    """Whether the CUDA driver library loads, checked without Taichi's fallback warnings."""
    names = {"Linux": ["libcuda.so.1", "libcuda.so"], "Windows": ["nvcuda.dll"]}.get(platform.system(), [])
    for name in names:
        try:
            ctypes.CDLL(name)
            return True
        except OSError:
            continue
    return False


def _arch_name(arch) -> str:
    return {ti.x64: "cpu", ti.arm64: "cpu", ti.cuda: "cuda", ti.vulkan: "vulkan",
            ti.metal: "metal", ti.opengl: "opengl"}.get(arch, str(arch))


def _init(**config) -> tuple:
    """ti.init(**config); where it lands on the CPU, each worker of Taichi's pool is then kept
    on a CPU of its own if the pool has one for every CPU (cpu_threads). Returns the pinned
    (thread id, CPU) pairs."""
    before = cpu_threads.thread_ids()
    ti.init(**config)
    cfg = ti.lang.impl.current_cfg()
    return cpu_threads.pin_workers(before, cfg.cpu_max_num_threads) if _arch_name(cfg.arch) == "cpu" else ()


def _start(arch: str, precision: str, threads: int | None, seed: int) -> tuple:
    frontend_cache.install()  # Taichi's source reads and position messages, once each
    serial_loops.install()  # serial kernels for small scenes on the CPU
    fast_launch.install()  # Taichi's launch path, its walks over the arguments kept per kernel
    host_arrays.install()  # CPU arrays copied to and from NumPy through their memory, not kernels
    fp = ti.f64 if precision == "f64" else ti.f32
    # Taichi's offline cache of compiled kernels holds 100 MiB by default, fewer than a scene
    # with every kind of collider, pairs and bodies compiles: past it, it evicts and recompiles
    # on every run (the test suite's kernels alone are several hundred MiB).
    common = dict(default_fp=fp, default_ip=ti.i32, random_seed=seed, log_level=ti.WARN,
                  offline_cache_max_size_of_files=OFFLINE_CACHE_BYTES)
    # On the CPU, without Taichi's own control-flow optimisations of its IR (store forwarding,
    # dead stores), unless the user's TI_CFG_OPTIMIZATION says otherwise: LLVM's passes, which
    # run anyway, leave most kernels as fast, and the largest, the impulse substep, compiles in
    # 1.3 s instead of 8.6; the test suite takes half the time (docs/design-notes.md, "Compile
    # time"). GPUs keep them: not measured there.
    cpu = dict(arch=ti.cpu, **common)
    if not os.environ.get("TI_CFG_OPTIMIZATION"):
        cpu["cfg_optimization"] = False
    if threads is not None:
        cpu["cpu_max_num_threads"] = threads
    pinned = ()
    if arch == "cpu":
        pinned = _init(**cpu)
    elif arch == "auto":
        # A GPU when one is usable: CUDA, or Metal on a Mac. Vulkan is not tried here, since
        # on a machine without a GPU it would pick a software rasteriser (lavapipe), slower
        # than Taichi's own CPU backend and without f64.
        candidates = [ti.cuda] if _cuda_driver_present() else []
        if platform.system() == "Darwin" and precision == "f32":
            candidates.append(ti.metal)
        if candidates:
            pinned = _init(arch=candidates, **common)
        if not candidates or (_arch_name(ti.lang.impl.current_cfg().arch) == "cpu" and threads is not None):
            if candidates:
                ti.reset()
            pinned = _init(**cpu)
    else:
        target = {"gpu": ti.gpu, "cuda": ti.cuda, "vulkan": ti.vulkan, "metal": ti.metal}[arch]
        pinned = _init(arch=target, **common)  # (a GPU that is not there: Taichi's CPU fallback)
    return _arch_name(ti.lang.impl.current_cfg().arch), pinned


def init(arch: str = "auto", *, precision: str = "f32", threads: int | None = None,
         seed: int = 0) -> RuntimeInfo:
    """Start Taichi for tai_coll.

    arch: "cpu" | "gpu" | "cuda" | "vulkan" | "metal" | "auto" ("auto": CUDA or Metal when
        usable, else the CPU). A GPU arch that is not available falls back to the CPU, as
        Taichi does; `RuntimeInfo.arch` says where it landed.
    precision: "f32" (fast, the default) or "f64" (for tests and accuracy studies).
    threads: CPU worker threads, 1 to MAX_THREADS (None: all cores). Ignored on GPUs. With
        one for every CPU the process may use, each is kept on a CPU of its own
        (cpu_threads; `RuntimeInfo.pinned_threads`).
    seed: Taichi's random seed, 0 to MAX_SEED.
    Every argument is checked before the running Taichi is reset, so a bad call leaves it
    as it was.
    """
    global _info, _generation
    _check_init_args(arch, precision, threads, seed)
    if _info is not None and (_info.requested_arch, _info.precision, _info.threads, _info.seed) == (
            arch, precision, threads, seed):
        return _info
    if _info is not None:
        ti.reset()
        _info = None  # the old runtime is gone even if the new one fails to start
    actual, pinned = _start(arch, precision, threads, seed)
    _generation += 1
    _info = RuntimeInfo(arch, actual, precision, threads, seed, _generation, pinned)
    return _info


def ensure_init() -> RuntimeInfo:
    """The current runtime, starting the default one ("auto", f32) if none is running."""
    return _info if _info is not None else init()


def info() -> RuntimeInfo | None:
    """The running runtime, or None before the first `init()`."""
    return _info


def float_dtype():
    """The numpy dtype matching Taichi's default float."""
    return ensure_init().float_dtype


def read_small(array, count: int | None = None) -> np.ndarray:
    """A NumPy copy of the first `count` entries (None: all) of a Taichi array, flattened, for
    the host's small reads between kernels (a flag, a bound, a largest value).

    On the CPU it is copied straight from the array's memory (host_arrays.memory), about 11 us
    a read on the EPYC of docs/benchmarks.md, where Taichi's own `to_numpy` launches a copy
    kernel (0.1 to 0.25 ms) and its host accessor takes about 20 us for one entry
    (docs/design-notes.md, "Where the suite's time goes, small reads, empty lists"). Elsewhere
    it is `to_numpy`."""
    view = host_arrays.memory(array)
    found = (array.to_numpy() if view is None else view).reshape(-1)
    count = found.size if count is None else max(0, min(int(count), found.size))
    return found[:count].copy()


def check_generation(generation: int, what: str = "this object") -> None:
    """Raise if `generation` belongs to a Taichi runtime that `init()` has since replaced."""
    if _info is None or generation != _info.generation:
        raise RuntimeError(
            f"{what} was built before tai_coll.init() restarted Taichi with other arguments; "
            "its fields are gone. Build it again after the last init().")


def bound_to_runtime(cls):
    """Class decorator for objects whose Taichi arrays belong to the runtime that was current
    when they were built (`self._runtime`, a RuntimeInfo): every public method and every
    property setter first raises check_generation's RuntimeError once tc.init has
    restarted Taichi, instead of a Taichi internal error from a dead array. Property getters
    are left alone, so a stale object still prints and reports its host-side state; a getter
    that reads Taichi arrays should be a method."""
    what = f"this {cls.__name__}"

    def guarded(function):
        @functools.wraps(function)
        def call(self, *args, **kwargs):
            check_generation(self._runtime.generation, what)
            return function(self, *args, **kwargs)

        return call

    for name, member in list(vars(cls).items()):
        if name.startswith("_"):
            continue
        if isinstance(member, property) and member.fset is not None:
            setattr(cls, name, member.setter(guarded(member.fset)))
        elif inspect.isfunction(member):
            setattr(cls, name, guarded(member))
    return cls
