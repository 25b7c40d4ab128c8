"""Implicit colliders: a user's function f(x) = 0 (docs/physics.md 1, last row).

f < 0 inside, f > 0 outside, in the collider's local frame. Two ways to give it:
- a Taichi function `@ti.func def f(p: ti.math.vec3) -> float`: evaluated in the kernels
  themselves. Each distinct function gets its own collider kind and group bit
  (kinds.register_implicit), so a kernel inlines only the functions its scene uses;
  the normal is the gradient of f, from the user's `gradient` function or by central
  differences;
- a vectorised numpy function `f(points (N, 3)) -> (N,)`: sampled on a grid over
  `bounds` and then handled exactly like a baked mesh (grid_sdf.py): trilinear phi,
  analytic gradient.
phi = f / lipschitz, where `lipschitz` bounds |grad f| (1 for a true signed distance), so
phi never exceeds the distance to the surface: culling, free-flight clearance and the
trajectory crossing by conservative advancement (marching.py) stay safe. Near the surface
(outside it, within the caller's reach) that bound can be a fraction of the distance, and
phi is f / |grad f| there, the distance to first order (implicit_eval.py; docs/physics.md 1.2).
"""

import numpy as np
import taichi as ti
from taichi.lang.expr import Expr

from .. import runtime, validate
from . import kinds
from .colliders import Collider
from .grid_sdf import node_counts
from .implicit_eval import GRADIENT_STEP, is_taichi_function, kind_for

# What each Taichi function given to Implicit returns ("float", "vec3" or what else it
# is), found once by compiling a call (_probe): kernels would otherwise fail deep inside
# the crossing code (marching.py) on a function that returns, say, a vector.
_RETURNS: dict = {}


def _returned(value) -> str:
    """What a Taichi function call returned, read at compile time."""
    if isinstance(value, tuple):
        return f"a tuple of {len(value)} values"
    if not isinstance(value, Expr):
        return f"a {type(value).__name__}"
    if value.is_tensor():
        shape = value.get_shape()
        return "vec3" if shape == (3,) else f"a {'x'.join(map(str, shape))} {'vector' if len(shape) == 1 else 'matrix'}"
    if value.is_struct():
        return "a struct"
    return "nothing" if str(value.ptr.get_rvalue_type()) == "unknown" else "float"


def _record(function, value):
    _RETURNS[function] = _returned(value)


@ti.kernel
def _probe(function: ti.template()):
    value = function(ti.math.vec3(0.0))
    ti.static(_record(function, value))


def _check_returns(role: str, function, expected: str):
    """TypeError naming `function` unless it compiles as f(p: vec3) returning `expected`."""
    name = getattr(function, "__name__", repr(function))
    signature = f"f(p: ti.math.vec3) -> {expected}"
    if function not in _RETURNS:
        runtime.ensure_init()
        try:
            _probe(function)
        except ti.TaichiCompilationError as error:
            raise TypeError(f"{role} {name} must be a Taichi function {signature}; calling it on a vec3 failed "
                            f"to compile: {error}") from error
    got = _RETURNS[function]
    if got != expected:
        what = "one float, the signed value" if expected == "float" else "a vec3, the gradient"
        raise TypeError(f"{role} {name} must return {what} ({signature}); it returns {got}")


class Implicit(Collider):
    """A solid bounded by the zero set of a user's function f (negative inside).

    function: a Taichi function `f(p: ti.math.vec3) -> float` of the local point, or a
        vectorised numpy function `f(points (N, 3)) -> (N,)`.
    bounds: ((x0, y0, z0), (x1, y1, z1)), local box (m) that contains the surface.
        Required for a numpy function (the grid covers it); for a Taichi function optional:
        it gives the bounding sphere used to skip far particles (without it, unbounded).
    lipschitz: bound on |grad f| (1 when f is a signed distance): phi = f / lipschitz, and
        f / |grad f| near the surface (docs/physics.md 1.2).
    gradient: Taichi functions only, optional `@ti.func (p) -> vec3`, the gradient of f;
        default central differences with step `gradient_step` (m; default 1e-6 x scale
        in f64, 1e-3 x scale in f32, scale the size of `bounds` or 1 m).
    resolution / voxel_size: numpy functions only: grid nodes along the longest side of
        `bounds` (default 64), or the spacing (m).
    center, rotation: pose of the local frame.
    """

    def __init__(self, function, *, bounds=None, lipschitz=1.0, gradient=None, gradient_step=None,
                 resolution=None, voxel_size=None, center=(0.0, 0.0, 0.0), rotation=None):
        if not callable(function):
            raise TypeError(f"function must be a Taichi function or a numpy function; got {type(function).__name__}")
        self.lipschitz = validate.real("lipschitz", lipschitz, low=0.0, low_open=True)
        self.bounds = None if bounds is None else validate.box("bounds", bounds)
        center = validate.vector3("center", center)
        rotation = validate.rotation("rotation", rotation)
        self.function = function
        self.taichi = is_taichi_function(function)
        if self.taichi:
            if resolution is not None or voxel_size is not None:
                raise ValueError("resolution and voxel_size apply to numpy functions only (they are sampled "
                                 "on a grid); a Taichi function is evaluated exactly")
            if gradient is not None and not is_taichi_function(gradient):
                raise TypeError("gradient must be a Taichi function (@ti.func) returning a vec3")
            _check_returns("function", function, "float")
            if gradient is not None:
                _check_returns("gradient", gradient, "vec3")
            self.gradient_step = validate.real("gradient_step", gradient_step, low=0.0, low_open=True,
                                               allow_none=True)
            self.kind = kind_for(function, gradient)
            bound = self.UNBOUNDED
            if self.bounds is not None:
                lo, hi = self.bounds
                bound = float(np.max(np.linalg.norm(np.array([[x, y, z] for x in (lo[0], hi[0])
                                                               for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]),
                                                    axis=1)))
            self.scale = 1.0 if self.bounds is None else float(np.max(self.bounds[1] - self.bounds[0]))
            super().__init__(center=center, rotation=rotation, params=(), bound=bound)
        else:
            self._sample_numpy(function, gradient, gradient_step, resolution, voxel_size, center, rotation)

    def _sample_numpy(self, function, gradient, gradient_step, resolution, voxel_size, center, rotation):
        if gradient is not None or gradient_step is not None:
            raise ValueError("gradient and gradient_step apply to Taichi functions only; a numpy function "
                             "is sampled on a grid whose interpolant has an exact gradient")
        if self.bounds is None:
            raise ValueError("bounds is required for a numpy function: the box over which it is sampled")
        if resolution is not None and voxel_size is not None:
            raise ValueError("give resolution or voxel_size, not both")
        lo, hi = self.bounds
        extent = hi - lo
        if voxel_size is None:
            resolution = validate.integer("resolution", 64 if resolution is None else resolution, low=4)
            h = float(np.max(extent)) / (resolution - 1)
        else:
            h = validate.real("voxel_size", voxel_size, low=0.0, low_open=True)
        dims = node_counts(extent, h, name="resolution" if voxel_size is None else "voxel_size")
        middle = 0.5 * (lo + hi)
        self.origin = middle - 0.5 * h * (dims - 1)
        self.voxel_size = h
        axes = [self.origin[a] + h * np.arange(dims[a]) for a in range(3)]
        points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        values = np.asarray(function(points), dtype=np.float64)
        if values.shape not in ((len(points),), (len(points), 1)):
            raise ValueError(f"function must return one value per point, shape ({len(points)},); "
                             f"got {values.shape}")
        if not np.all(np.isfinite(values)):
            raise ValueError("function returned NaN or infinite values inside bounds")
        self.values = validate.representable("function values / lipschitz",
                                             values.reshape(tuple(dims)) / self.lipschitz)
        self.kind = kinds.SDF_GRID
        half = 0.5 * h * (dims - 1)
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half + middle
        super().__init__(center=center, rotation=rotation, params=half,
                         bound=float(np.max(np.linalg.norm(corners, axis=1))))

    def shape_data(self):
        ishape = np.zeros(8, dtype=np.int32)
        fshape = np.zeros(8)
        if self.taichi:
            fshape[0] = 1.0 / self.lipschitz
            step = self.gradient_step
            if step is None:
                step = GRADIENT_STEP[np.dtype(runtime.float_dtype())] * self.scale
            fshape[1] = step
            return ishape, fshape, np.zeros(0), np.zeros(0, dtype=np.int32)
        ishape[2:5] = self.values.shape
        fshape[0:3] = self.origin
        fshape[3] = self.voxel_size
        return ishape, fshape, self.values.ravel(), np.zeros(0, dtype=np.int32)

    def _describe(self):
        name = getattr(self.function, "__name__", "function")
        how = "taichi" if self.taichi else f"grid {list(self.values.shape)}"
        return f"{name}, {how}, center={self.center.tolist()}"
