"""tc.init: idempotent with the same arguments, and the arch/precision it reports."""

import os

import numpy as np
import pytest
import taichi as ti

import tai_coll as tc
from tai_coll import runtime

from conftest import TEST_ARCH, add_box_of_planes


def test_init_twice_with_same_arguments_is_harmless():
    first = runtime.info()
    scene = tc.Scene()
    scene.add_particles(positions=[[0.0, 1.0, 0.0]])
    again = tc.init(arch=first.requested_arch, precision="f64", threads=first.threads, seed=0)
    assert again is first
    scene.step()  # the scene built before the second call still runs
    assert scene.time > 0


def test_session_runs_on_the_test_arch_in_f64():
    info = runtime.info()
    assert info.arch == TEST_ARCH and info.precision == "f64"
    assert info.threads == (2 if TEST_ARCH == "cpu" else None)
    assert runtime.float_dtype() is np.float64
    # f64 really reaches the kernels: a distance that f32 would round.
    x = 1.0 + 1e-12
    phi = tc.Plane(point=(0.0, 1.0, 0.0), normal=(0.0, 1.0, 0.0)).signed_distance([[0.0, x, 0.0]])
    assert abs(phi[0] - 1e-12) < 1e-15


def test_cpu_kernels_compile_without_taichis_cfg_optimisation():
    # runtime._start: on the CPU Taichi's CFG passes are off unless TI_CFG_OPTIMIZATION says
    # otherwise (they cost most of the largest kernels' compile time, and LLVM optimises
    # anyway); every test on the CPU compiles this way
    from taichi.lang import impl

    setting = os.environ.get("TI_CFG_OPTIMIZATION")
    expected = bool(int(setting)) if setting else TEST_ARCH != "cpu"
    assert impl.current_cfg().cfg_optimization is expected


def test_stale_generation_is_refused():
    import pytest

    with pytest.raises(RuntimeError, match="restarted Taichi"):
        runtime.check_generation(runtime.info().generation - 1, "this Scene")


FRONTEND_PROBE = '''
import taichi as ti
import tai_coll as tc

tc.init(arch="cpu", precision="f64", threads=1, seed=0)
defined_value = 1.0


@ti.func
def near(a):
    return a * 2.0 + defined_value


@ti.func
def far(a):
    return a * 2.0 + unknown_value


@ti.kernel
def sums(x: ti.types.ndarray()) -> float:
    total = 0.0
    for i in range(x.shape[0]):
        total += near(x[i]) + near(x[i] + 1.0)
    return total


@ti.kernel
def broken(x: ti.types.ndarray()) -> float:
    total = 0.0
    for i in range(x.shape[0]):
        total += near(x[i]) + far(x[i])
    return total


import numpy as np

print("sum", sums(np.arange(3.0)))
try:
    broken(np.arange(3.0))
except Exception as error:
    print(type(error).__name__)
    print(error)
from tai_coll import frontend_cache
print("memo", frontend_cache.install.installed)
'''


def test_taichis_frontend_memos_leave_its_error_messages_as_they_were(tmp_path):
    # frontend_cache: Taichi's source reads and position messages are made once per source
    # position. A kernel that compiles gives the same result, and a compile error in a
    # @ti.func the same message (file, line, the line with its caret) as without the memos,
    # here after a function of the same shape was compiled at two call sites.
    import subprocess
    import sys

    from taichi.lang import kernel_impl

    from tai_coll import frontend_cache

    # (in this process the memos are on unless the environment turned them off; the two probes
    # below set their own)
    installed = frontend_cache.install()
    assert installed == frontend_cache.may_patch("TAI_COLL_FRONTEND_CACHE")
    assert (kernel_impl.getsourcelines.__module__ == "tai_coll.frontend_cache") == installed
    import textwrap
    line = "\tif a:\t # a tab, then   spaces  "  # (the source lines' fill and dedent: the same text)
    assert kernel_impl.textwrap.fill(line, tabsize=4, width=9999) == textwrap.fill(line, tabsize=4, width=9999)
    assert kernel_impl.textwrap.dedent("  a\n   b") == "a\n b"
    probe = tmp_path / "probe.py"
    probe.write_text(FRONTEND_PROBE)
    outputs = {}
    for memo in ("1", "0"):
        env = dict(os.environ, TAI_COLL_FRONTEND_CACHE=memo, TI_OFFLINE_CACHE="0")
        run = subprocess.run([sys.executable, str(probe)], capture_output=True, text=True, env=env, timeout=300)
        assert run.returncode == 0, run.stderr
        outputs[memo] = [line for line in run.stdout.splitlines() if not line.startswith("[Taichi]")]
    with_memo, without = outputs["1"], outputs["0"]
    assert with_memo[-1] == "memo True" and without[-1] == "memo False"
    assert with_memo[:-1] == without[:-1]
    text = "\n".join(with_memo)
    assert "sum 24.0" in text and "TaichiNameError" in text
    assert f'File "{probe}"' in text and "in far:" in text
    # (the two functions' last lines differ only in the name, of the same length: a message
    # kept for `near` would quote its line)
    assert "return a * 2.0 + unknown_value" in text and "^^^^^^^^^^^^^" in text


def test_position_messages_wrap_every_line_as_textwrap_does():
    # frontend_cache.line_wrapper: a line that fits is returned as it is (less trailing
    # spaces) without TextWrapper's chunking, which took a quarter of the frontend's time; every
    # line must come out as TextWrapper(width=80) makes it: the source lines of tai_coll and of
    # Taichi's Python package (what Taichi quotes), their caret lines, and lines made to trip
    # the shortcut (tabs, other whitespace, hyphens, the width's edge, non-ASCII, spaces alone)
    import pathlib
    import textwrap

    import taichi

    from tai_coll import frontend_cache

    fast, slow = frontend_cache.line_wrapper(textwrap.TextWrapper)(width=80), textwrap.TextWrapper(width=80)
    lines = []
    for root in (pathlib.Path(tc.__file__).parent, pathlib.Path(taichi.__file__).parent / "lang"):
        for path in sorted(root.rglob("*.py")):
            for line in path.read_text(encoding="utf-8").splitlines():
                lines += [line, " " * (len(line) - len(line.lstrip())) + "^" * len(line.strip()) + "   "]
    assert len(lines) > 40_000
    edge = "x" * 79
    lines += ["", " ", " " * 100, "\t\tx = 1", "a\tb", "x = 1\x0c", "x = y\xa0", "x = y \xa0", "caf\u00e9 = 1",
              edge, edge + " ", edge + "  ", edge + "y", edge + "y ", edge + "yz", " " + edge, " " + edge + "y",
              "a-b-c " * 20, "- " * 45, "x" * 200, "   " + "-" * 77 + "   ", "\x1f", "a \x1f"]
    wrong = [line for line in lines if fast.wrap(line) != slow.wrap(line)]
    assert wrong == []
    again = frontend_cache.line_wrapper(textwrap.TextWrapper)  # (longer lines: wrapped once, then kept)
    assert [again(width=80).wrap(line) for line in lines * 2] == [slow.wrap(line) for line in lines * 2]
    for options in (dict(break_on_hyphens=False), dict(drop_whitespace=False), dict(subsequent_indent="  ")):
        odd, plain = again(width=30, **options), textwrap.TextWrapper(width=30, **options)
        assert [odd.wrap(line) for line in lines[-10:] * 2] == [plain.wrap(line) for line in lines[-10:] * 2]
    shortcut = [line for line in lines if line.isascii() and line.isprintable() and len(line.rstrip(" ")) <= 80]
    assert len(shortcut) > 0.75 * len(lines)  # (most lines take the shortcut: the comparison tests it)


def _piles_after(frames: int) -> list:
    """Positions and velocities of three small piles falling into a box for `frames` frames:
    Gauss-Seidel impulse pairs with sleeping (its default), Jacobi passes, and DEM pairs with
    tangential springs and spinning particles; each 300 particles, on a jittered lattice."""
    rng = np.random.default_rng(5)
    g = np.arange(-2, 3) * 0.012
    lattice = np.stack(np.meshgrid(g, np.arange(12) * 0.012 + 0.01, g, indexing="ij"), -1).reshape(-1, 3)
    x = lattice + rng.uniform(-0.001, 0.001, lattice.shape)
    cases = [(tc.ImpulseSolver(), dict(sleep_time=0.02)), (tc.ImpulseSolver(), dict(method="jacobi")),
             (tc.PenaltySolver(hertz=200.0, spin=True), dict(tangential_springs=True))]
    out = []
    for solver, options in cases:
        dt = 7.5e-5 if isinstance(solver, tc.PenaltySolver) else 1e-3
        scene = tc.Scene(dt=dt, substeps=5, solver=solver)
        add_box_of_planes(scene, 0.04, tc.Material(restitution=0.2, friction=0.4))
        scene.enable_particle_collisions(material=tc.Material(restitution=0.2, friction=0.4), **options)
        scene.add_particles(positions=x, radius=0.005)
        scene.step(frames)
        out += [scene.positions(), scene.velocities()]
    return out


def test_small_scenes_serial_kernels_give_the_parallel_kernels_numbers(monkeypatch):
    # A scene of few particles steps with serial variants of the kernels on the CPU
    # (tai_coll/serial_loops.py): the same numbers as the thread pool's kernels up to
    # round-off (LLVM may fuse multiplies and adds differently), and the same every run.
    from tai_coll import serial_loops

    if TEST_ARCH != "cpu" or os.environ.get("TAI_COLL_SERIAL_SMALL") == "0":
        pytest.skip("GPUs launch no serial variants; TAI_COLL_SERIAL_SMALL=0 turns them off")
    assert serial_loops.install() and 300 * runtime.info().threads <= serial_loops.SERIAL_WORK
    with serial_loops.small(300, True, runtime.info().threads) as serial_now:
        assert serial_now
    serial = _piles_after(12)
    assert all(np.array_equal(a, b) for a, b in zip(serial, _piles_after(12)))
    from tai_coll.solvers.pairs.gauss_seidel import _pass

    assert any(key[-1] == "serial" for key in _pass._primal.mapper.mapping)  # the serial variants ran
    monkeypatch.setattr(serial_loops, "SERIAL_WORK", 0)  # every scene now launches the thread pool's kernels
    parallel = _piles_after(12)
    for a, b in zip(serial, parallel):
        assert np.abs(a - b).max() <= 1e-12
    assert np.abs(serial[0][:, 1] - serial[0][:, 1].max()).max() > 0.01  # (the piles did fall)


PackForTest = ti.types.argpack(count=ti.i32, a=ti.types.ndarray(ndim=1), b=ti.types.ndarray(ndim=1))


def _probe_kernel():
    """A kernel with every kind of parameter the shorter launch path sets (tai_coll/fast_launch.py):
    a pack of arrays and an integer, an array, a float, an integer, a vector, a template."""

    @ti.kernel
    def probe(pack: PackForTest, out: ti.types.ndarray(ndim=1), scale: float, shift: ti.i32,
              offset: ti.math.vec3, twice: ti.template()):
        for i in range(pack.count):
            value = scale * (pack.a[i] + pack.b[i]) + shift + offset[0] + 10.0 * offset[1] + 100.0 * offset[2]
            if ti.static(twice):
                value *= 2.0
            out[i] = value

    return probe


def test_the_shorter_launch_path_sets_what_taichis_own_sets():
    # tai_coll/fast_launch.py keeps Taichi's walks over a kernel's arguments per kernel: the
    # same values reach the kernel, by position or by name, with a vector as a tuple or a
    # ti.Vector, NumPy values, a replaced pack member of another type, and a NumPy array
    # (which goes down Taichi's own path); Taichi's own errors for bad calls stay.
    from taichi.lang import kernel_impl
    from taichi.lang.exception import TaichiSyntaxError

    from tai_coll import fast_launch

    if os.environ.get("TAI_COLL_FAST_LAUNCH") == "0":
        pytest.skip("TAI_COLL_FAST_LAUNCH=0 leaves Taichi's launch path alone")
    assert fast_launch.install() and kernel_impl.Kernel.launch_kernel is not fast_launch.TAICHIS["launch_kernel"]
    probe = _probe_kernel()
    a = ti.ndarray(ti.f64, 4)
    b = ti.ndarray(ti.f64, 4)
    a.from_numpy(np.array([1.0, 2.0, 3.0, 4.0]))
    b.from_numpy(np.array([0.5, 0.25, 0.125, 0.0625]))
    pack = PackForTest(count=3, a=a, b=b)
    out = ti.ndarray(ti.f64, 4)

    def expected(scale, shift, offset, twice, a_values=(1.0, 2.0, 3.0, 4.0)):
        values = scale * (np.array(a_values) + [0.5, 0.25, 0.125, 0.0625]) + shift + offset[0] + 10 * offset[1] \
            + 100 * offset[2]
        values = values * (2.0 if twice else 1.0)
        values[3] = 0.0
        return values

    out.fill(0.0)
    probe(pack, out, 2.0, 3, (1.0, 2.0, 3.0), False)
    assert np.array_equal(out.to_numpy(), expected(2.0, 3, (1, 2, 3), False))
    assert probe._primal._tc_plan is not None  # (the shorter path set these)
    out.fill(0.0)
    probe(twice=True, offset=ti.math.vec3(0.5, 0.0, 0.25), shift=np.int64(-1), scale=np.float64(0.5), out=out,
          pack=pack)
    assert np.array_equal(out.to_numpy(), expected(0.5, -1, (0.5, 0.0, 0.25), True))
    # a member replaced by an array of another element type: another compiled instance
    a32 = ti.ndarray(ti.f32, 4)
    a32.from_numpy(np.array([8.0, 16.0, 32.0, 64.0], dtype=np.float32))
    pack["a"] = a32
    out.fill(0.0)
    probe(pack, out, 1.0, 0, (0.0, 0.0, 0.0), False)
    assert np.array_equal(out.to_numpy(), expected(1.0, 0, (0, 0, 0), False, (8.0, 16.0, 32.0, 64.0)))
    # a NumPy array for the array parameter (written in place), and a strided one (Taichi's
    # own path, which refuses it)
    host = np.zeros(4)
    probe(pack, host, 1.0, 0, (0.0, 0.0, 0.0), False)
    assert np.array_equal(host, expected(1.0, 0, (0, 0, 0), False, (8.0, 16.0, 32.0, 64.0)))
    host = np.zeros(8)[::2]
    assert not host.flags.c_contiguous
    with pytest.raises(ValueError, match="Non contiguous"):
        probe(pack, host, 1.0, 0, (0.0, 0.0, 0.0), False)
    # the same numbers through Taichi's own functions
    mine = out.to_numpy()
    kernel_impl.Kernel.launch_kernel, saved = fast_launch.TAICHIS["launch_kernel"], kernel_impl.Kernel.launch_kernel
    try:
        out.fill(0.0)
        probe(pack, out, 1.0, 0, (0.0, 0.0, 0.0), False)
    finally:
        kernel_impl.Kernel.launch_kernel = saved
    assert np.array_equal(out.to_numpy(), mine)
    # Taichi's own errors
    with pytest.raises(TaichiSyntaxError, match="Unexpected argument 'scael'"):
        probe(pack, out, 1.0, 0, (0.0, 0.0, 0.0), twice=False, scael=1.0)
    with pytest.raises(TaichiSyntaxError, match="Multiple values for argument 'pack'"):
        probe(pack, out, 1.0, 0, (0.0, 0.0, 0.0), False, pack=pack)
    with pytest.raises(TaichiSyntaxError, match="missing"):
        probe(pack, out, 1.0, 0, (0.0, 0.0, 0.0))
    # a value of the wrong type: whatever Taichi's own path raises (for a float parameter
    # annotated `float`, Taichi 1.7 fails while writing its message: AttributeError)
    raised = []
    for launch in (kernel_impl.Kernel.launch_kernel, fast_launch.TAICHIS["launch_kernel"]):
        kernel_impl.Kernel.launch_kernel, saved = launch, kernel_impl.Kernel.launch_kernel
        try:
            with pytest.raises(Exception) as error:
                probe(pack, out, "fast", 0, (0.0, 0.0, 0.0), False)
        finally:
            kernel_impl.Kernel.launch_kernel = saved
        raised.append((type(error.value), str(error.value)))
    assert raised[0] == raised[1]


def test_the_shorter_launch_path_gives_a_pile_the_same_bits():
    # Stepping a scene through Taichi's own launch functions and through the shorter path:
    # bit-identical piles (the same compiled kernels get the same arguments).
    from taichi.lang import kernel_impl

    from tai_coll import fast_launch

    if os.environ.get("TAI_COLL_FAST_LAUNCH") == "0":
        pytest.skip("TAI_COLL_FAST_LAUNCH=0 leaves Taichi's launch path alone")
    mine = _piles_after(6)
    mapper = kernel_impl.TaichiCallableTemplateMapper
    replaced = {"process_args": (kernel_impl, "_process_args"), "extract": (mapper, "extract"),
                "launch_kernel": (kernel_impl.Kernel, "launch_kernel")}
    saved = {name: getattr(owner, attribute) for name, (owner, attribute) in replaced.items()}
    try:
        for name, (owner, attribute) in replaced.items():
            setattr(owner, attribute, fast_launch.TAICHIS[name])
        theirs = _piles_after(6)
    finally:
        for name, (owner, attribute) in replaced.items():
            setattr(owner, attribute, saved[name])
    assert all(np.array_equal(a, b) for a, b in zip(mine, theirs))


def test_small_reads_give_what_to_numpy_gives():
    # runtime.read_small: the host's reads between kernels (a pass's flag, the particles'
    # cell bounds, the largest speed), on the CPU straight from the array's memory
    from tai_coll import runtime

    for dtype, values in ((ti.i32, [3, -7, 2**31 - 1, -2**31, 0, 5]), (ti.u8, [0, 255, 3, 4, 5, 6]),
                          (ti.f32, [1.5, -2.25, 3e38, 0.0, 1.0, 2.0]), (ti.f64, [1e-300, -2.5, 7.0, 8.0, 9.0, 1e300])):
        array = ti.ndarray(dtype, shape=6)
        array.from_numpy(np.array(values, dtype=array.to_numpy().dtype))
        for _ in range(2):  # (the second read uses the place kept on the array)
            expected = array.to_numpy()
            assert np.array_equal(runtime.read_small(array), expected) and runtime.read_small(array).dtype == expected.dtype
            assert np.array_equal(runtime.read_small(array, 1), expected[:1])
            assert runtime.read_small(array, 0).shape == (0,) and np.array_equal(runtime.read_small(array, 99), expected)
        array.from_numpy(np.zeros(6, dtype=array.to_numpy().dtype))  # a write between reads is seen
        assert not runtime.read_small(array).any()
    vectors = ti.Vector.ndarray(3, ti.f64, shape=2)  # (not scalars: read by to_numpy)
    vectors.from_numpy(np.arange(6.0).reshape(2, 3))
    assert np.array_equal(runtime.read_small(vectors), np.arange(6.0))


def _through_taichi(name, array, *args):
    """Ndarray method `name` as Taichi's own (host_arrays.TAICHIS) applied to `array`."""
    from tai_coll import host_arrays

    return host_arrays.TAICHIS[name](array, *args)


def test_host_copies_give_what_taichis_kernels_give():
    # tai_coll/host_arrays.py: on the CPU, to_numpy, from_numpy and fill go through the array's
    # memory, not Taichi's kernels; the same values, casts (rounding from f64 to f32, truncation
    # from float to integer, wrapping between integers), shapes and dtypes, and Taichi's errors
    from tai_coll import host_arrays

    if not host_arrays.install():
        pytest.skip("Taichi's own copies here (not Taichi 1.7, or TAI_COLL_HOST_ARRAYS=0)")
    if runtime.info().arch != "cpu":
        pytest.skip("host copies are the CPU's")
    rng = np.random.default_rng(7)
    cases = [(lambda: ti.ndarray(ti.f32, shape=(5, 4)), rng.normal(size=(5, 4)) * 1e3),
             (lambda: ti.ndarray(ti.i32, shape=7), np.array([1.9, -1.9, 2.5, 3e9, -3e9, 0.0, 7.0])),
             (lambda: ti.ndarray(ti.i8, shape=5), np.array([1, 127, 128, -129, 300], dtype=np.int64)),
             (lambda: ti.ndarray(ti.u8, shape=3), np.array([True, False, True])),
             (lambda: ti.Vector.ndarray(3, ti.f32, shape=6), rng.normal(size=(6, 3))),
             (lambda: ti.Vector.ndarray(3, ti.f64, shape=(2, 3)), rng.normal(size=(2, 3, 3))),
             (lambda: ti.Matrix.ndarray(2, 3, ti.f32, shape=4), rng.normal(size=(4, 2, 3)).astype(np.float32)),
             (lambda: ti.Vector.ndarray(3, ti.i32, shape=4), rng.integers(-9, 9, size=(4, 3))[:, ::-1])]
    for make, values in cases:
        if values.dtype.kind == "f" and make().dtype in (ti.i32, ti.i8, ti.u8):
            values = values[np.abs(values) < 2**31]  # (C leaves float-to-integer overflow undefined)
        ours, theirs = make(), make()
        if values.shape != tuple(ours.arr.total_shape()):
            ours, theirs = ti.ndarray(ours.dtype, shape=len(values)), ti.ndarray(theirs.dtype, shape=len(values))
        matrix = bool(ours.arr.element_shape())
        ours.from_numpy(values)
        if matrix:
            _through_taichi("_ndarray_matrix_from_numpy", theirs, values, len(ours.arr.element_shape()) == 1)
            expected = _through_taichi("_ndarray_matrix_to_numpy", theirs, len(ours.arr.element_shape()) == 1)
        else:
            _through_taichi("_ndarray_from_numpy", theirs, values)
            expected = _through_taichi("_ndarray_to_numpy", theirs)
        got = ours.to_numpy()
        assert got.dtype == expected.dtype and got.shape == expected.shape and np.array_equal(got, expected)
        got[...] = 0  # (a copy: the array keeps its values)
        assert np.array_equal(ours.to_numpy(), expected)
        for value in (3, 0.75, True, -2):
            try:
                _through_taichi("fill", theirs, value)
            except TypeError:  # (Taichi's f32/i32/u32 fill takes its own kind of value only)
                with pytest.raises(TypeError):
                    ours.fill(value)
                continue
            ours.fill(value)
            assert np.array_equal(ours.to_numpy(), theirs.to_numpy())
    array = ti.ndarray(ti.f32, shape=3)
    with pytest.raises(ValueError, match="Mismatch shape"):
        array.from_numpy(np.zeros(4))
    with pytest.raises(TypeError):
        array.from_numpy([1.0, 2.0, 3.0])


def test_kernels_see_host_writes_and_host_reads_see_kernels():
    @ti.kernel
    def bump(a: ti.types.ndarray(dtype=ti.types.vector(3, ti.f32), ndim=1), s: ti.types.ndarray(dtype=ti.i32, ndim=1)):
        for i in range(a.shape[0]):
            a[i] += 1.0
            s[i] *= 2

    vectors = ti.Vector.ndarray(3, ti.f32, shape=4)
    scalars = ti.ndarray(ti.i32, shape=4)
    vectors.from_numpy(np.arange(12.0).reshape(4, 3))
    scalars.fill(5)
    bump(vectors, scalars)
    assert np.array_equal(vectors.to_numpy(), np.arange(12.0).reshape(4, 3) + 1.0)
    assert np.array_equal(scalars.to_numpy(), np.full(4, 10))
