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
GRADIENT_STEP = {np.dtype(np.float64): 1e-6, np.dtype(np.float32): 1e-3}  # relative to `scale`

# (kind, evaluator) per registered Taichi function, in registration order.
_REGISTERED: list = []
_BY_FUNCTION: dict = {}


def _make_evaluator(function, gradient):
    """A @ti.func (g, ci, kind, params, p) -> (phi, n) for one user function (the evaluator
    form marching.march_crossing calls; kind and params unused); fshape[0] = 1 / lipschitz,
    fshape[1] = the central-difference step (m)."""

    has_gradient = gradient is not None

    @ti.func
    def evaluate(g: ti.template(), ci, kind, params, p: vec3):
        f = g.fshape[ci]
        phi = function(p) * f[0]
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
        return phi, n

    return evaluate


def kind_for(function, gradient) -> int:
    key = (function, gradient)
    if key not in _BY_FUNCTION:
        name = getattr(function, "__name__", "function")
        kind = kinds.register_implicit(len(_REGISTERED), name)
        _REGISTERED.append((kind, _make_evaluator(function, gradient)))
        _BY_FUNCTION[key] = kind
    return _BY_FUNCTION[key]


def registered_in(groups: int):
    """The (kind, evaluator) pairs whose group bit is in the compile-time mask."""
    return [(kind, evaluate) for kind, evaluate in _REGISTERED if groups & kinds.GROUPS[kind]]


@ti.func
def implicit_sdf(g: ti.template(), groups: ti.template(), ci, kind: ti.i32, params, p: vec3):
    """(phi, n) of the implicit kind `kind` among those compiled in (`groups`)."""
    phi = 0.0
    n = vec3(0.0, 1.0, 0.0)
    for k in ti.static(range(len(registered_in(groups)))):
        if kind == ti.static(registered_in(groups)[k][0]):
            phi, n = ti.static(registered_in(groups)[k][1])(g, ci, kind, params, p)
    return phi, n


@ti.func
def implicit_crossing(g: ti.template(), groups: ti.template(), ci, kind: ti.i32, params, x0: vec3, x1: vec3, r):
    """Root finding along the segment: conservative advancement on phi = f / lipschitz."""
    hit = False
    t = 1.0
    n = vec3(0.0, 1.0, 0.0)
    for k in ti.static(range(len(registered_in(groups)))):
        if kind == ti.static(registered_in(groups)[k][0]):
            hit, t, n = march_crossing(ti.static(registered_in(groups)[k][1]), g, ci, kind, params, x0, x1, r, 1.0,
                                       False)
    return hit, t, n


def is_taichi_function(function) -> bool:
    return bool(getattr(function, "_is_taichi_function", False))
