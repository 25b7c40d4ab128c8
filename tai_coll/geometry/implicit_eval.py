"""Kernel side of implicit colliders (implicit.py): the registry of users' Taichi functions,
one collider kind and group bit each, and the dispatch that geometry/dispatch.py calls
(docs/physics.md 1, implicit row). Kept apart from the Implicit class: the device queries
import no collider classes.
"""

import numpy as np
import taichi as ti

from . import kinds
from .marching import march_crossing

vec3 = ti.math.vec3

TINY = 1e-12
#: A crossing refines phi (see _make_evaluator) within this many particle radii of the surface.
CROSSING_REACH = 1.5
GRADIENT_STEP = {np.dtype(np.float64): 1e-6, np.dtype(np.float32): 1e-3}  # relative to `scale`

# (kind, evaluator, crossing evaluator) per registered Taichi function, in registration order.
_REGISTERED: list = []
_BY_FUNCTION: dict = {}


def _make_evaluator(function, gradient, reach_in_params: bool = False):
    """A @ti.func (g, ci, kind, params, p, reach) -> (phi, n) for one user function;
    fshape[0] = 1 / lipschitz, fshape[1] = the central-difference step (m).

    phi = f / lipschitz is a lower bound on the distance, and only that: where |grad f| is
    below the bound (f = |p|^2 - 1 with lipschitz = 4 near the unit sphere), it is a fraction of
    the distance, and a particle would rest where the bound, not the surface, comes within its
    radius (docs/physics.md 1.3). Outside the surface and within the caller's `reach`, phi is
    f / |grad f| instead, the distance to first order (exact for a true distance, and for a
    smooth f off by the square of the distance times the curvature); past the reach, and inside,
    the bound. reach_in_params: the evaluator form marching.march_crossing calls,
    (g, ci, kind, params, p), its reach in params[0] (kind unused)."""

    has_gradient = gradient is not None

    @ti.func
    def refined(g: ti.template(), ci, p: vec3, reach):
        f = g.fshape[ci]
        value = function(p)
        phi = value * f[0]
        grad = vec3(0.0, 0.0, 0.0)
        if ti.static(has_gradient):
            grad = gradient(p)
        else:
            step = f[1]
            for a in ti.static(range(3)):
                e = vec3(0.0, 0.0, 0.0)
                e[a] = step
                grad[a] = (function(p + e) - function(p - e)) / (2.0 * step)
        n = vec3(0.0, 1.0, 0.0)
        gnorm = grad.norm()
        if gnorm > TINY:
            n = grad / gnorm
            if phi > 0.0 and phi < reach:
                phi = ti.max(phi, value / gnorm)
        return phi, n

    if reach_in_params:
        @ti.func
        def evaluate(g: ti.template(), ci, kind, params, p: vec3):
            return refined(g, ci, p, params[0])
    else:
        @ti.func
        def evaluate(g: ti.template(), ci, kind, params, p: vec3, reach):
            return refined(g, ci, p, reach)

    return evaluate


def kind_for(function, gradient) -> int:
    key = (function, gradient)
    if key not in _BY_FUNCTION:
        name = getattr(function, "__name__", "function")
        kind = kinds.register_implicit(len(_REGISTERED), name)
        _REGISTERED.append((kind, _make_evaluator(function, gradient),
                            _make_evaluator(function, gradient, reach_in_params=True)))
        _BY_FUNCTION[key] = kind
    return _BY_FUNCTION[key]


def registered_in(groups: int):
    """The (kind, evaluator, crossing evaluator) of the kinds whose group bit is in the
    compile-time mask."""
    return [entry for entry in _REGISTERED if groups & kinds.GROUPS[entry[0]]]


@ti.func
def implicit_sdf(g: ti.template(), groups: ti.template(), ci, kind: ti.i32, params, p: vec3, reach=1e30):
    """(phi, n) of the implicit kind `kind` among those compiled in (`groups`); refined
    within `reach` (see _make_evaluator)."""
    phi = 0.0
    n = vec3(0.0, 1.0, 0.0)
    for k in ti.static(range(len(registered_in(groups)))):
        if kind == ti.static(registered_in(groups)[k][0]):
            phi, n = ti.static(registered_in(groups)[k][1])(g, ci, kind, params, p, reach)
    return phi, n


@ti.func
def implicit_crossing(g: ti.template(), groups: ti.template(), ci, kind: ti.i32, params, x0: vec3, x1: vec3, r):
    """Root finding along the segment: conservative advancement on phi = f / lipschitz,
    refined within CROSSING_REACH radii (so that the contact is where the sphere touches the
    surface, not where the bound says it might)."""
    hit = False
    t = 1.0
    n = vec3(0.0, 1.0, 0.0)
    near = ti.Vector([CROSSING_REACH * r, 0.0, 0.0, 0.0])
    for k in ti.static(range(len(registered_in(groups)))):
        if kind == ti.static(registered_in(groups)[k][0]):
            hit, t, n = march_crossing(ti.static(registered_in(groups)[k][2]), g, ci, kind, near, x0, x1, r, 1.0,
                                       False)
    return hit, t, n


def is_taichi_function(function) -> bool:
    return bool(getattr(function, "_is_taichi_function", False))
