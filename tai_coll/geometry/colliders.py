"""The analytic collider shapes users build: Plane, Sphere, Box, Cylinder, Capsule.

A collider is a pure description: kind, a parameter vector and a rest pose (center and
rotation). Motion and material are attached when it is added to a scene. Host-side queries
(`signed_distance`, `normal`, `crossing`) run the same @ti.func the step kernels use
(geometry/queries.py). The shapes' device code is in analytic.py, the dispatch on kind in
dispatch.py.
"""

from __future__ import annotations

import numpy as np

from .. import validate
from . import kinds, queries
from .frames import align_y


class Collider:
    """Base class: a shape in its local frame, placed by `center` and `rotation`."""

    kind: int = -1

    #: params[3] holds the radius of a sphere about `center` that encloses the shape (m), so
    #: kernels can rule a collider out with one distance before evaluating its SDF.
    BOUND_SLOT = 3
    UNBOUNDED = 1e30

    def __init__(self, *, center, rotation, params, bound):
        self.center = center
        self.rotation = rotation
        self.params = np.zeros(4)
        self.params[: len(params)] = params
        self.params[self.BOUND_SLOT] = bound

    @property
    def kind_name(self) -> str:
        return kinds.NAMES[self.kind]

    def signed_distance(self, points) -> np.ndarray:
        """phi(x) at each point of an (N, 3) array: negative inside, positive outside."""
        return self._query(points)[0]

    def normal(self, points) -> np.ndarray:
        """Unit outward normal (the gradient of phi) at each point, shape (N, 3)."""
        return self._query(points)[1]

    def crossing(self, starts, ends, radius: float = 0.0):
        """First contact of a sphere of `radius` moving along each segment starts[i] -> ends[i].

        Returns (hit (N,) bool, t (N,) fraction in [0, 1], normal (N, 3)). A segment that
        starts in contact reports hit at t = 0; t is 1 where nothing is hit.
        """
        x0 = validate.points("starts", starts)
        x1 = validate.points("ends", ends)
        if x0.shape != x1.shape:
            raise ValueError(f"starts and ends must have the same shape; got {x0.shape} and {x1.shape}")
        radius = validate.real("radius", radius, low=0.0)
        return queries.segment_crossing(self, x0, x1, radius)

    def shape_data(self):
        """Array data for kinds backed by arrays: (ishape (8,) int, fshape (8,) float,
        float block, int block). ishape[0] and ishape[1] are reserved: whoever packs the
        blocks into pools (the collider table, a host query) writes the blocks' offsets
        there. Analytic shapes have none."""
        return np.zeros(8, dtype=np.int32), np.zeros(8), np.zeros(0), np.zeros(0, dtype=np.int32)

    def _query(self, points):
        pts = validate.points("points", points)
        return queries.signed_distance_and_normal(self, pts)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self._describe()})"

    def _describe(self) -> str:
        return f"center={self.center.tolist()}"


class Plane(Collider):
    """The half-space below a plane through `point` with outward unit `normal` (any length given)."""

    kind = kinds.PLANE

    def __init__(self, *, point=(0.0, 0.0, 0.0), normal=(0.0, 1.0, 0.0)):
        point = validate.vector3("point", point)
        normal = validate.vector3("normal", normal, nonzero=True)
        self.normal_vector = normal / np.linalg.norm(normal)
        super().__init__(center=point, rotation=align_y(self.normal_vector), params=(), bound=self.UNBOUNDED)

    def _describe(self):
        return f"point={self.center.tolist()}, normal={self.normal_vector.tolist()}"


class Sphere(Collider):
    """A solid ball. center in m, radius in m (> 0)."""

    kind = kinds.SPHERE

    def __init__(self, *, center=(0.0, 0.0, 0.0), radius=1.0):
        center = validate.vector3("center", center)
        self.radius = validate.real("radius", radius, low=0.0, low_open=True)
        super().__init__(center=center, rotation=np.eye(3), params=(self.radius,), bound=self.radius)

    def _describe(self):
        return f"center={self.center.tolist()}, radius={self.radius}"


class Box(Collider):
    """A solid oriented box: center (m), half_extents (m, each > 0), rotation (3x3, local to world)."""

    kind = kinds.BOX

    def __init__(self, *, center=(0.0, 0.0, 0.0), half_extents=(0.5, 0.5, 0.5), rotation=None):
        center = validate.vector3("center", center)
        half = validate.vector3("half_extents", half_extents)
        if np.min(half) <= 0:
            raise ValueError(f"half_extents must all be > 0; got {half.tolist()}")
        self.half_extents = half
        super().__init__(center=center, rotation=validate.rotation("rotation", rotation), params=half,
                         bound=float(np.linalg.norm(half)))

    def _describe(self):
        return f"center={self.center.tolist()}, half_extents={self.half_extents.tolist()}"


class _Axial(Collider):
    """Shared set-up of shapes built around an axis through their center."""

    def __init__(self, *, center, radius, half_height, axis):
        center = validate.vector3("center", center)
        self.radius = validate.real("radius", radius, low=0.0, low_open=True)
        self.half_height = validate.real("half_height", half_height, low=0.0, low_open=True)
        axis = validate.vector3("axis", axis, nonzero=True)
        self.axis = axis / np.linalg.norm(axis)
        super().__init__(center=center, rotation=align_y(self.axis), params=(self.radius, self.half_height),
                         bound=self._bound())

    def _bound(self) -> float:
        raise NotImplementedError

    def _describe(self):
        return (f"center={self.center.tolist()}, radius={self.radius}, "
                f"half_height={self.half_height}, axis={self.axis.tolist()}")


class Cylinder(_Axial):
    """A solid capped cylinder: the axis runs from center - half_height*axis to center + half_height*axis."""

    kind = kinds.CYLINDER

    def __init__(self, *, center=(0.0, 0.0, 0.0), radius=0.5, half_height=0.5, axis=(0.0, 1.0, 0.0)):
        super().__init__(center=center, radius=radius, half_height=half_height, axis=axis)

    def _bound(self):
        return float(np.hypot(self.radius, self.half_height))


class Capsule(_Axial):
    """A segment of length 2*half_height along `axis`, swept by a sphere of `radius`."""

    kind = kinds.CAPSULE

    def __init__(self, *, center=(0.0, 0.0, 0.0), radius=0.25, half_height=0.5, axis=(0.0, 1.0, 0.0)):
        super().__init__(center=center, radius=radius, half_height=half_height, axis=axis)

    def _bound(self):
        return self.radius + self.half_height

    @classmethod
    def from_endpoints(cls, a, b, *, radius) -> "Capsule":
        """A capsule around the segment a -> b."""
        a = validate.vector3("a", a)
        b = validate.vector3("b", b)
        if np.linalg.norm(b - a) < 1e-12:
            raise ValueError("a and b must be distinct points; use a Sphere for a point")
        return cls(center=(a + b) / 2, radius=radius, half_height=np.linalg.norm(b - a) / 2, axis=b - a)
