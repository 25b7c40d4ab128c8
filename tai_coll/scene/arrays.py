"""Kernel-argument bundles for the particle store and the collider table.

State lives in Taichi ndarrays rather than fields: a kernel taking ndarrays compiles once per
dtype and serves every scene (and every capacity), where field arguments would compile the
step kernels again for each new scene. Inside a kernel the arrays are regrouped into these
bundles and handed to @ti.func helpers as template arguments, so the helpers read
`p.x[i]` and `c.center1[ci]` as if they were fields.
"""

import warnings

import taichi as ti

# Building a bundle inside a kernel is plain Python evaluated at compile time, which is what
# we want; Taichi warns about any such call, so silence exactly these.
warnings.filterwarnings("ignore", category=SyntaxWarning,
                        message=r'.*Calling non-taichi function "(ParticleArrays|ColliderArrays|ShapeData|_History|_DEM)"')


# Element types are left to the arrays passed in: annotations are evaluated at import time,
# before `init()` has chosen f32 or f64, and a fixed dtype here would pin the wrong one.
def vectors(dim: int = 3):
    return ti.types.ndarray(ndim=1)


def scalars(dtype=None):
    return ti.types.ndarray(ndim=1)


def matrices():
    return ti.types.ndarray(ndim=1)


class ParticleArrays:
    """x, v, mass, radius, flags, stats: see `ParticleStore`."""

    def __init__(self, x, v, mass, radius, flags, stats):
        self.x, self.v, self.mass, self.radius, self.flags, self.stats = x, v, mass, radius, flags, stats


class ShapeData:
    """Array-backed shape data (grids, triangles, heights) shared by a scene's colliders:
    per collider 8 integers (`ishape`) and 8 floats (`fshape`) describing its block, and
    the float and integer pools the blocks live in. Geometry functions take this bundle as
    `g` with the collider index; analytic shapes ignore it. `groups` is the compile-time
    mask of collider kind groups the kernel handles (geometry.kinds)."""

    def __init__(self, ishape, fshape, fpool, ipool, groups):
        self.ishape, self.fshape, self.fpool, self.ipool = ishape, fshape, fpool, ipool
        self.groups = groups


class ColliderArrays(ShapeData):
    """The collider table's columns: see `ColliderTable`. Also a `ShapeData`."""

    def __init__(self, kind, params, material, center0, rotation0, center1, rotation1, velocity,
                 angular_velocity, ishape, fshape, fpool, ipool, groups):
        super().__init__(ishape, fshape, fpool, ipool, groups)
        self.kind, self.params, self.material = kind, params, material
        self.center0, self.rotation0, self.center1, self.rotation1 = center0, rotation0, center1, rotation1
        self.velocity, self.angular_velocity = velocity, angular_velocity
