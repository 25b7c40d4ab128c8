"""Integer tags for collider kinds, as stored in the collider table and read by kernels."""

PLANE = 0
SPHERE = 1
BOX = 2
CYLINDER = 3
CAPSULE = 4

NAMES = {PLANE: "plane", SPHERE: "sphere", BOX: "box", CYLINDER: "cylinder", CAPSULE: "capsule"}
