"""Integer tags for collider kinds, as stored in the collider table and read by kernels.

Kinds come in groups. A kernel is compiled for the groups a scene uses (a bit mask passed
as a template argument and carried by the shape-data bundle as `g.groups`): every
geometry call site inlines the code of every compiled kind, so leaving out the groups a
scene does not use keeps compile times short. All analytic kinds form one group, so every
scene of analytic shapes shares one compiled kernel.
"""

import taichi as ti

PLANE = 0
SPHERE = 1
BOX = 2
CYLINDER = 3
CAPSULE = 4

TRIANGLE_MESH = 8  # exact triangles in a uniform grid (triangle_mesh.py)
HEIGHT_FIELD = 9   # terrain y = h(x, z), two triangles per cell (height_field.py)
SDF_GRID = 12      # signed-distance grid: MeshSDF, numpy Implicit (grid_sdf.py)

NAMES = {PLANE: "plane", SPHERE: "sphere", BOX: "box", CYLINDER: "cylinder", CAPSULE: "capsule",
         TRIANGLE_MESH: "triangle mesh", HEIGHT_FIELD: "height field", SDF_GRID: "sdf grid"}

GROUP_ANALYTIC = 1  # plane, sphere, box, cylinder, capsule: closed forms, all convex
GROUP_TRIANGLES = 8  # triangle meshes
GROUP_HEIGHT = 16    # height fields
GROUP_GRID = 64      # signed-distance grids
GROUPS = {PLANE: GROUP_ANALYTIC, SPHERE: GROUP_ANALYTIC, BOX: GROUP_ANALYTIC, CYLINDER: GROUP_ANALYTIC,
          CAPSULE: GROUP_ANALYTIC, TRIANGLE_MESH: GROUP_TRIANGLES, HEIGHT_FIELD: GROUP_HEIGHT,
          SDF_GRID: GROUP_GRID}

# Implicit colliders of a user's Taichi function: one kind and one group bit per function,
# registered at run time (implicit_eval.py), so a kernel inlines only the functions its scene uses.
IMPLICIT_FIRST = 64
IMPLICIT_MAX = 32
GROUP_IMPLICIT_FIRST_BIT = 12
GROUP_IMPLICIT = ((1 << IMPLICIT_MAX) - 1) << GROUP_IMPLICIT_FIRST_BIT  # every implicit bit


def register_implicit(index: int, name: str) -> int:
    """Kind id of the index-th registered implicit function, recorded in NAMES and GROUPS."""
    if index >= IMPLICIT_MAX:
        raise ValueError(f"at most {IMPLICIT_MAX} distinct implicit functions per process")
    kind = IMPLICIT_FIRST + index
    NAMES[kind] = f"implicit {name}"
    GROUPS[kind] = 1 << (GROUP_IMPLICIT_FIRST_BIT + index)
    return kind


@ti.func
def is_convex(kind) -> bool:
    """Whether the kind's shape is convex (all analytic kinds are): the solvers use it to
    skip work that convexity makes unnecessary."""
    return kind <= CAPSULE


def groups_of(kind_list) -> int:
    """The group mask for a set of kinds (the analytic group when empty)."""
    mask = 0
    for kind in kind_list:
        mask |= GROUPS[kind]
    return mask or GROUP_ANALYTIC
