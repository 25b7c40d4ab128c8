"""A shorter path through Taichi's Python launch of a kernel (docs/design-notes.md, "Launches").

Each launch of a Taichi 1.7 kernel from Python does three things before the kernel runs:

- it matches the arguments given by name to the kernel's parameters (`_process_args`), one
  name at a time against the whole parameter list;
- it works out the key of the compiled instance to launch (`TaichiCallableTemplateMapper.
  extract`), walking every argument, and every member of every argument pack, through a chain
  of type tests;
- it sets the arguments on a fresh launch context (`Kernel.launch_kernel`), walking them the
  same way again.

tai_coll's kernels take argument packs of up to 25 arrays and a dozen named settings, and a
small scene launches a dozen kernels a substep. Profiled on the EPYC of docs/benchmarks.md, a
one-particle scene with particle collisions spent about 0.8 ms a launch, most of it in those
three walks, against tens of microseconds in the kernel.

`install()` (called by tc.init) keeps what those walks find that cannot change between calls:

- each kernel's parameter positions by name;
- each kernel's plan of how to set its arguments, made from its annotations once: which are
  scalars, matrices, arrays and packs, and which members of a pack are arrays;
- the key part of an argument pack, kept on the pack for each pack type it was read as, and
  dropped when a member of the pack is replaced (`ArgPack.__setitem__`). A pack's key part
  depends only on its arrays' element types and dimensions, which an array keeps for life.

What is set on the launch context, in which order and at which index, is what Taichi's own
walk sets, and the same errors are raised: any argument the plan does not cover (a texture,
a nested pack, a NumPy array that is not C-contiguous or sits in a pack, a value of an
unexpected type) sends that launch down Taichi's own path unchanged. Only Taichi 1.7, whose
launch code this was written against; TAI_COLL_FAST_LAUNCH=0 leaves it off.
"""

import inspect

import numpy as np

from .frontend_cache import patch_once

#: Taichi's own functions that install() replaced, by name (empty until installed): the
#: tests launch through them to compare.
TAICHIS = {}


@patch_once("TAI_COLL_FAST_LAUNCH")
def install() -> bool:
    """Install the shorter launch path (see the module's notes); returns whether it is on
    (False: another Taichi version, or TAI_COLL_FAST_LAUNCH=0). Safe to call again."""
    try:
        from taichi.lang import impl, kernel_impl, runtime_ops
        from taichi.lang._ndarray import Ndarray
        from taichi.lang.argpack import ArgPack, ArgPackType
        from taichi.lang.enums import Layout
        from taichi.lang.exception import handle_exception_from_cpp
        from taichi.lang.matrix import MatrixType
        from taichi.types import ndarray_type, primitive_types
        from taichi.types.annotations import template
        from taichi.lang.util import cook_dtype
        from taichi.types.utils import is_signed
        mapper = kernel_impl.TaichiCallableTemplateMapper
        kernel = kernel_impl.Kernel
        process_args = kernel_impl._process_args
        extract_arg = mapper.extract_arg
        launch = kernel.launch_kernel
        set_pack_item = ArgPack.__setitem__
    except (ImportError, AttributeError):
        return False

    # ------------------------------------------------------------------ arguments by name
    _EMPTY = inspect.Parameter.empty

    def fast_process_args(self, args, kwargs):
        # Taichi's _process_args with the names looked up in a table; any irregular call
        # (an unknown or repeated name, a missing argument) goes to Taichi's own, which raises
        positions = self.__dict__.get("_tc_positions")
        if positions is None:
            positions = self._tc_positions = {argument.name: k for k, argument in enumerate(self.arguments)}
        if len(args) > len(self.arguments):
            return process_args(self, args, kwargs)
        ret = [argument.default for argument in self.arguments]
        ret[:len(args)] = args
        for name, value in kwargs.items():
            k = positions.get(name)
            if k is None or k < len(args):
                return process_args(self, args, kwargs)
            ret[k] = value
        if any(value is _EMPTY for value in ret):
            return process_args(self, args, kwargs)
        return ret

    # ------------------------------------------------------------------ the instance key
    PRIMITIVE = {int, bool, float, str}
    real_ids = primitive_types.real_type_ids
    integer_ids = primitive_types.integer_type_ids

    class Part(tuple):
        """A pack's or an array's key part, its hash kept (a key is hashed on every launch)."""

        def __new__(cls, items):
            part = super().__new__(cls, items)
            part._hash = tuple.__hash__(part)
            return part

        def __hash__(self):
            return self._hash

    def kept_part(arg, slot, make):
        """The key part kept on `arg` (a pack or an array) for the annotation `slot`."""
        kept = arg.__dict__.get("_tc_keys")
        if kept is None:
            kept = arg.__dict__["_tc_keys"] = {}
        part = kept.get(slot)
        if part is None:
            part = kept[slot] = Part(make())
        return part

    def key_of(annotation, name):
        """A function giving the key part of an argument of this annotation."""
        def taichis(arg):
            return extract_arg(arg, annotation, name)

        if isinstance(annotation, template):
            def key(arg):
                kind = type(arg)
                if kind in PRIMITIVE or arg is None:
                    return arg  # (Taichi's own: a primitive template argument is its value)
                if kind is tuple and all(type(item) in PRIMITIVE for item in arg):
                    return arg  # (... and a tuple of them, item by item)
                return taichis(arg)
            return key
        if id(annotation) in real_ids or id(annotation) in integer_ids or isinstance(annotation, MatrixType):
            return lambda arg: "#"  # (Taichi's own for a scalar or a matrix: the same for every value)
        slot = id(annotation)
        if isinstance(annotation, ArgPackType):
            # (a pack's part depends on its arrays' element types and dimensions alone; a
            # member replaced drops the parts kept, pack_setitem)
            return lambda arg: kept_part(arg, slot, lambda: taichis(arg)) if isinstance(arg, ArgPack) else taichis(arg)
        if isinstance(annotation, ndarray_type.NdarrayType):
            # (an array's part: its element type, dimensions and gradient, fixed for its life)
            return lambda arg: (kept_part(arg, (slot, arg.grad is not None), lambda: taichis(arg))
                                if isinstance(arg, Ndarray) else taichis(arg))
        return taichis

    def extract(self, args):
        keys = self.__dict__.get("_tc_keys")
        if keys is None:
            keys = self._tc_keys = [key_of(argument.annotation, argument.name) for argument in self.arguments]
        return tuple([key(arg) for key, arg in zip(keys, args)])

    def pack_setitem(self, key, value):
        self.__dict__.pop("_tc_keys", None)  # (a member replaced: its array may differ in type)
        set_pack_item(self, key, value)

    # ------------------------------------------------------------------ setting arguments
    REALS = (float, int, np.floating, np.integer)  # what Taichi's walk takes for a real, then float()
    INTEGERS = (int, np.integer)  # ... and for an integer, then int()
    INT32_MAX = np.iinfo(np.int32).max
    MAX_SLOTS = 64  # Taichi's max_arg_num

    def member_plan(annotation):
        """For a pack: the names of its array members in Taichi's order, and its slot count;
        None if it holds something the plan does not cover."""
        arrays = []
        for name, member in annotation.members.items():
            if isinstance(member, ndarray_type.NdarrayType):
                arrays.append(name)
            elif id(member) in real_ids or id(member) in integer_ids or isinstance(member, MatrixType):
                pass  # (held by the pack itself)
            else:
                return None
        return arrays, 1 + len(annotation.members)

    def plan_of(self):
        """The kernel's steps, one per parameter that is not a template: (what, index,
        detail), and the positions of those parameters; None if not covered."""
        steps = []
        positions = []
        slots = 0
        index = 0
        for position, argument in enumerate(self.arguments):
            annotation = argument.annotation
            if isinstance(annotation, template):
                continue
            positions.append(position)
            if id(annotation) in real_ids:
                steps.append(("float", (index,), None))
                slots += 1
            elif id(annotation) in integer_ids:
                steps.append(("int" if is_signed(cook_dtype(annotation)) else "uint", (index,), None))
                slots += 1
            elif isinstance(annotation, ArgPackType):
                members = member_plan(annotation)
                if members is None:
                    return None
                steps.append(("pack", (index,), members[0]))
                slots += members[1]
            elif isinstance(annotation, ndarray_type.NdarrayType):
                # (for a NumPy array: how many trailing or leading axes are the element's)
                element_dims = 0
                if annotation.dtype is not None and id(annotation.dtype) not in primitive_types.type_ids:
                    element_dims = annotation.dtype.ndim
                steps.append(("array", (index,), (element_dims, annotation.layout == Layout.SOA)))
                slots += 1
            elif isinstance(annotation, MatrixType):
                # (the launch context's setter for its entries, what it takes and the cast)
                if annotation.dtype in primitive_types.real_types:
                    number = ("set_struct_arg_float", REALS, float)
                elif annotation.dtype in primitive_types.integer_types:
                    signed = is_signed(cook_dtype(annotation.dtype))
                    number = ("set_struct_arg_int" if signed else "set_struct_arg_uint", INTEGERS, int)
                else:
                    return None
                shape = (annotation.n,) if annotation.ndim == 1 else (annotation.n, annotation.m)
                steps.append(("matrix", (index,), (number, shape)))
                slots += 1
            else:
                return None
            index += 1
        if slots > MAX_SLOTS:
            return None  # (Taichi's own path raises its error)
        return steps, positions

    def set_ndarray(launch_ctx, index, array):
        """A Taichi array at `index`, with its gradient if it has one (Taichi's set_arg_ndarray)."""
        v_grad = array.grad.arr if array.grad else None
        if v_grad is None:
            launch_ctx.set_arg_ndarray(index, array.arr)
        else:
            launch_ctx.set_arg_ndarray_with_grad(index, array.arr, v_grad)

    def set_args(self, launch_ctx, plan, args):
        """Set the arguments on the launch context as Taichi's walk does; False (nothing
        usable set) when an argument is not what the plan covers."""
        steps, positions = plan
        late = []  # (the packs' arrays, set after every parameter, as Taichi's walk does)
        for (what, index, detail), position in zip(steps, positions):
            value = args[position]
            kind = type(value)  # (exact types first: the common case, cheaply)
            if what == "float":
                if not (kind is float or kind is int or isinstance(value, REALS)):
                    return False
                launch_ctx.set_arg_float(index, float(value))
            elif what == "int" or what == "uint":
                if not (kind is int or isinstance(value, INTEGERS)):
                    return False
                (launch_ctx.set_arg_int if what == "int" else launch_ctx.set_arg_uint)(index, int(value))
            elif what == "pack":
                if not isinstance(value, ArgPack):
                    return False
                for name in detail:
                    member = value[name]
                    if not isinstance(member, Ndarray):
                        return False
                    late.append(member)
                launch_ctx.set_arg_argpack(index, value._ArgPack__argpack)
            elif what == "array":
                if isinstance(value, Ndarray):
                    set_ndarray(launch_ctx, index, value)
                elif kind is np.ndarray and value.flags.c_contiguous:
                    # a NumPy array in place (Taichi's set_arg_ext_array): its shape without
                    # the element's axes
                    element_dims, soa = detail
                    shape = value.shape
                    if element_dims:
                        shape = shape[element_dims:] if soa else shape[:-element_dims]
                    if value.size > INT32_MAX:
                        return False  # (Taichi's own path warns)
                    launch_ctx.set_arg_external_array_with_shape(index, int(value.ctypes.data), value.nbytes,
                                                                 shape, 0)
                else:
                    return False
            else:  # matrix
                (setter, accepted, cast), shape = detail
                setter = getattr(launch_ctx, setter)
                try:
                    if len(shape) == 1:
                        entries = [value[k] for k in range(shape[0])]
                    else:
                        entries = [value[k, j] for k in range(shape[0]) for j in range(shape[1])]
                except Exception:
                    return False
                for k, entry in enumerate(entries):
                    if not isinstance(entry, accepted):
                        return False
                    setter(index + (k,), cast(entry))
        first_late = len(steps)
        for k, array in enumerate(late):
            set_ndarray(launch_ctx, (first_late + k,), array)
        return True

    def fast_launch(self, t_kernel, *args):
        plan = self.__dict__.get("_tc_plan", 0)
        if plan == 0:
            plan = self._tc_plan = plan_of(self)
        if plan is None or len(args) != len(self.arguments):
            return launch(self, t_kernel, *args)
        launch_ctx = t_kernel.make_launch_context()
        if not set_args(self, launch_ctx, plan, args):
            return launch(self, t_kernel, *args)
        try:
            prog = impl.get_runtime().prog
            compiled = prog.compile_kernel(prog.config(), prog.get_device_caps(), t_kernel)
            prog.launch_kernel(compiled, launch_ctx)
        except Exception as e:
            e = handle_exception_from_cpp(e)
            if impl.get_runtime().print_full_traceback:
                raise e
            raise e from None
        ret_dt = self.return_type
        if ret_dt is not None or self.has_print:
            runtime_ops.sync()
        if ret_dt is None:
            return None
        ret = [self.construct_kernel_ret(launch_ctx, ret_type, (k,)) for k, ret_type in enumerate(ret_dt)]
        return ret[0] if len(ret_dt) == 1 else ret

    TAICHIS.update(process_args=process_args, extract=mapper.extract, launch_kernel=launch)
    kernel_impl._process_args = fast_process_args
    mapper.extract = extract
    ArgPack.__setitem__ = pack_setitem
    kernel.launch_kernel = fast_launch
    return True
