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

NAMES = {PLANE: "plane", SPHERE: "sphere", BOX: "box", CYLINDER: "cylinder", CAPSULE: "capsule"}

GROUP_ANALYTIC = 1  # plane, sphere, box, cylinder, capsule: closed forms, all convex
GROUPS = {PLANE: GROUP_ANALYTIC, SPHERE: GROUP_ANALYTIC, BOX: GROUP_ANALYTIC, CYLINDER: GROUP_ANALYTIC,
          CAPSULE: GROUP_ANALYTIC}


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
