"""Serial kernels for small scenes on the CPU (docs/design-notes.md, "Small scenes").

On the CPU, Taichi runs each top-level loop of a kernel as a task of its thread pool: the
launching thread wakes the workers and waits for every one of them to report back, even when
the loop has two iterations. Measured on the AMD EPYC of docs/benchmarks.md (2 threads): a
kernel of one two-iteration loop costs 169 us a launch, one of eight such loops 367 us, and the
same eight loops run serially 58 us. A scene of a few particles makes a dozen launches a
substep, so a good part of its time went to waking threads that had nothing to do.

`install()` (called by tc.init) lets Taichi compile a second, serial variant of any kernel:
while `small(...)` is in force for a scene of at most SERIAL_WORK / threads particles on the
CPU, a launch looks up and compiles its kernel under a key that also holds the word "serial",
and each range loop of a kernel compiled then runs on the launching thread (Taichi's own
`ti.loop_config(serialize=True)`, given to every range loop). The kernels' code is the same,
and so are their results up to round-off (presumably LLVM, under Taichi's fast math, fuses
multiplies and adds differently once a loop is no longer a task of its own; the generated code
was not compared). Measured after 12 frames of a
300-particle pile (tests/test_runtime.py): Gauss-Seidel positions 7e-17 m and velocities
2e-14 m/s apart, Jacobi and DEM pairs bit-identical. A scene still gives the same numbers
every run, since the variant follows from its particle count; one that grows past the limit
(an emitter) changes variant there. Taichi's offline cache keys compiled kernels by their
IR, which records the serial loops, so the two variants are cached apart.

Only Taichi 1.7, whose frontend this was written against; TAI_COLL_SERIAL_SMALL=0 leaves it
off (every launch then uses Taichi's thread pool, as before).
"""

import contextlib
import os

from .frontend_cache import patch_once

#: A scene launches serial kernels while its particles times the runtime's threads are at most
#: this. Measured on the EPYC (2 threads, docs/design-notes.md, "Small scenes"): serial was
#: faster for a pair of particles (30 %) and for beds of 300 to 10,000 particles (10.6 against
#: 18.3 ms a substep at 3,000), and level at 30,000. A machine with more threads, or threads
#: that wake faster, gains more from its pool: so the limit falls with the thread count (4,096
#: particles with 2 threads, 512 with 16).
SERIAL_WORK = 8192

_serial = False  # whether the launches now use the serial variants (see small)


@patch_once("TAI_COLL_SERIAL_SMALL")
def install() -> bool:
    """Let kernels have serial variants (see the module's notes); returns whether it is on
    (False: another Taichi version, or TAI_COLL_SERIAL_SMALL=0). Safe to call again."""
    try:
        from taichi.lang import kernel_impl, misc
        from taichi.lang.ast import ast_transformer
        mapper = kernel_impl.TaichiCallableTemplateMapper
        transformer = ast_transformer.ASTTransformer
        builders = {name: getattr(transformer, name)
                    for name in ("build_range_for", "build_ndrange_for", "build_grouped_ndrange_for")}
        serialize = misc._parallelize
    except (ImportError, AttributeError):
        return False

    def lookup(self, args):
        # Taichi's own lookup (kernel_impl.TaichiCallableTemplateMapper.lookup), with the
        # serial choice in the key that picks the compiled instance; the arguments' features
        # it returns for compiling are Taichi's own key, unchanged
        if len(args) != self.num_args:
            raise TypeError(f"{self.num_args} argument(s) needed but {len(args)} provided.")
        key = self.extract(args)
        instance = (key, "serial") if _serial else key
        if instance not in self.mapping:
            self.mapping[instance] = len(self.mapping)
        return self.mapping[instance], key

    def serial_loop(build):
        def build_loop(ctx, node):
            if _serial:
                serialize(1)  # the loop config of the loop built next: one thread, strictly serial
            return build(ctx, node)
        return staticmethod(build_loop)

    mapper.lookup = lookup
    for name, build in builders.items():
        setattr(transformer, name, serial_loop(build))
    return True


@contextlib.contextmanager
def small(count: int, cpu: bool, threads: int | None):
    """Within the block, kernels launch their serial variants if the variants are installed,
    on the CPU, for count particles on `threads` threads (None: all cores) with count * threads
    at most SERIAL_WORK; the choice in force before is restored after."""
    global _serial
    before = _serial
    _serial = install.installed and cpu and count * (threads or os.cpu_count() or 1) <= SERIAL_WORK
    try:
        yield _serial
    finally:
        _serial = before
