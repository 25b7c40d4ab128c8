"""Taichi arrays on the CPU read, written and filled through their memory
(docs/design-notes.md, "Host copies without kernels").

Taichi 1.7 copies an ndarray to or from NumPy (`to_numpy`, `from_numpy`) with a kernel, one
for each element type and number of dimensions, compiled the first time a process needs it
and launched for every copy; it fills an array of vectors, or of a type other than f32, i32
and u32, with a kernel too. A scene's set-up makes dozens of such copies (its colliders'
tables, its particles, the solvers' arrays), and a rendered frame reads the particles back.
On the CPU an ndarray's elements lie in the process's memory, in C order with each element's
components last, at an address fixed for the array's life: `install()` (called by tc.init)
has those three methods copy through a NumPy view of that memory there instead (`memory`,
through which runtime.read_small also reads the host's flags), with NumPy's casts (those of C,
as the kernels cast: round to nearest between floats, truncation from float to integer,
wrapping between integers). Anything else (a GPU, a type NumPy lacks) takes Taichi's own path,
as does every array where TAI_COLL_HOST_ARRAYS=0. Only Taichi 1.7, whose ndarray code this was
written against.
"""

import ctypes
import functools
import math

import numpy as np

from .frontend_cache import patch_once

#: Taichi's own methods that install() replaced, by name (empty until installed): the tests
#: copy through them to compare.
TAICHIS = {}


@functools.cache
def _internals():
    """What memory() uses of Taichi 1.7's internals, or None where this Taichi lacks them."""
    try:
        from taichi._lib import core as ti_core
        from taichi.lang import impl
        from taichi.lang.util import to_numpy_type
    except ImportError:
        return None
    return impl, to_numpy_type, {ti_core.Arch.x64, ti_core.Arch.arm64}


def _view_of(array):
    """A NumPy view of the array's memory, or False (see memory)."""
    found = _internals()
    if found is None:
        return False
    impl, to_numpy_type, cpus = found
    if impl.current_cfg().arch not in cpus:  # (an array lives on its runtime's arch for life)
        return False
    try:
        dtype = np.dtype(to_numpy_type(array.dtype))
    except (TypeError, KeyError):
        return False
    shape = tuple(array.arr.total_shape())
    if math.prod(shape) == 0:
        return False
    address = impl.get_runtime().prog.get_ndarray_data_ptr_as_int(array.arr)
    buffer = (ctypes.c_char * (math.prod(shape) * dtype.itemsize)).from_address(address)
    return np.frombuffer(buffer, dtype=dtype).reshape(shape)


def memory(array):
    """A NumPy view of a Taichi ndarray's memory on the CPU (shape: the array's, then its
    components'), every kernel launched so far having run; None where there is none to give (a
    GPU, a type NumPy lacks, another Taichi's internals). It aliases the array: copy what is kept.
    The view is made once and kept on the array (its address is fixed for the array's life)."""
    view = array.__dict__.get("_tc_memory")
    if view is None:
        view = array._tc_memory = _view_of(array)
    if view is False:
        return None
    _internals()[0].get_runtime().sync()  # (as Taichi's copies do: every kernel launched so far has run)
    return view


@patch_once("TAI_COLL_HOST_ARRAYS")
def install() -> bool:
    """Copy CPU arrays through their memory (see the module's notes); returns whether it is on
    (False: another Taichi version, or TAI_COLL_HOST_ARRAYS=0). Safe to call again."""
    try:
        from taichi.lang._ndarray import Ndarray
    except ImportError:
        return False
    methods = ("_ndarray_to_numpy", "_ndarray_matrix_to_numpy", "_ndarray_from_numpy",
               "_ndarray_matrix_from_numpy", "fill")
    if _internals() is None or not all(callable(getattr(Ndarray, name, None)) for name in methods):
        return False

    def reading(original):
        def to_numpy(self, *args, **kwargs):
            view = memory(self)
            return original(self, *args, **kwargs) if view is None else view.copy()
        return to_numpy

    def writing(original):
        def from_numpy(self, arr, *args, **kwargs):
            view = memory(self) if isinstance(arr, np.ndarray) and tuple(arr.shape) == tuple(
                self.arr.total_shape()) else None  # (anything else: Taichi's checks and errors)
            if view is None:
                return original(self, arr, *args, **kwargs)
            np.copyto(view, arr, casting="unsafe")
            return None
        return from_numpy

    def filling(original):
        def fill(self, val):
            view = memory(self)
            value = np.asarray(val)
            # (a value of another kind, a float into integers say: Taichi's path and its errors)
            if view is None or value.ndim or not np.can_cast(value.dtype, view.dtype, "same_kind"):
                return original(self, val)
            view[...] = value
            return None
        return fill

    for name, wrap in zip(methods, (reading, reading, writing, writing, filling)):
        TAICHIS[name] = getattr(Ndarray, name)
        setattr(Ndarray, name, wrap(TAICHIS[name]))
    return True
