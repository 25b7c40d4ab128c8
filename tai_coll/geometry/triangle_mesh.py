"""TriangleMesh: exact collisions with the triangles of a mesh, open (a sheet, a bowl) or
closed (docs/physics.md 1, triangle mesh row, exact path). The shape description; its device
queries and the cell grid its triangles are binned into are in mesh_grid.py.
"""

import os

import numpy as np

from .. import runtime, validate
from . import kinds
from .colliders import Collider
from .mesh_grid import bin_triangles
from .mesh_sdf import load_mesh
from .triangles import triangle_tree

MAX_CELLS_PER_AXIS = 128
MAX_CELLS = 1 << 21


def _load(mesh):
    """(vertices (V, 3) float64, faces (F, 3) int64) from a trimesh.Trimesh, a file path or
    a (vertices, faces) pair."""
    if isinstance(mesh, (str, os.PathLike)):
        mesh = load_mesh(mesh)[0]  # FileNotFoundError / ValueError, as for tc.MeshSDF
    if hasattr(mesh, "vertices") and hasattr(mesh, "faces"):
        vertices, faces = mesh.vertices, mesh.faces
    elif isinstance(mesh, (tuple, list)) and len(mesh) == 2:
        vertices, faces = mesh
    else:
        raise TypeError(f"mesh must be a trimesh.Trimesh, a file path or a (vertices, faces) pair; "
                        f"got {type(mesh).__name__}")
    try:
        vertices = np.asarray(vertices, dtype=np.float64)
        faces_arr = np.asarray(faces)
    except (TypeError, ValueError):
        raise TypeError("mesh vertices must be an (N, 3) array of numbers and faces an (M, 3) array of "
                        "integers") from None
    if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) < 3:
        raise ValueError(f"mesh vertices must have shape (N, 3) with N >= 3; got {vertices.shape}")
    if not np.all(np.isfinite(vertices)):
        raise ValueError("mesh vertices must be finite")
    validate.representable("mesh vertices", vertices, underflow=False)
    if faces_arr.ndim != 2 or faces_arr.shape[1] != 3 or len(faces_arr) == 0:
        raise ValueError(f"mesh faces must have shape (M, 3) with M >= 1; got {faces_arr.shape}")
    if not np.issubdtype(faces_arr.dtype, np.integer):
        raise TypeError(f"mesh faces must be integer vertex indices; got dtype {faces_arr.dtype}")
    if faces_arr.min() < 0 or faces_arr.max() >= len(vertices):
        raise ValueError(f"mesh faces must index the {len(vertices)} vertices; got indices from "
                         f"{faces_arr.min()} to {faces_arr.max()}")
    return vertices, faces_arr.astype(np.int64)


def is_closed(faces: np.ndarray) -> bool:
    """Whether every edge is shared by exactly two triangles (a watertight surface)."""
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return bool(np.all(counts == 2))


class TriangleMesh(Collider):
    """Exact collisions with the triangles of a mesh (docs/physics.md 1). A closed mesh (every
    edge shared by two triangles) is a solid, inside by ray parity; an open one (a sheet, a
    bowl) is a surface whose distance is unsigned, so particles stay on the side they came
    from. A fast particle cannot pass through the surface within a substep.

    mesh: a trimesh.Trimesh, a path to a file trimesh reads, or a (vertices, faces) pair.
    thickness (m, >= 0): > 0 makes the surface a shell of that total thickness,
        phi = |distance| - thickness / 2, unsigned (as tc.MeshSDF); 0 leaves a closed mesh
        solid and an open one a zero-thickness surface that the particle radius keeps
        particles off.
    closed: None detects it; False treats a closed mesh as a surface (particles may be
        inside it, as in a hollow ball); True insists (ValueError when not watertight).
    cell_size (m): edge of the acceleration grid's cubic cells; None picks about twice the
        mean triangle size, with at most 128 cells along the longest side.
    center, rotation: the pose of the local frame, whose origin is the center of the mesh's
        bounding box (the pivot of angular_velocity); None keeps the mesh where its own
        coordinates put it.
    """

    kind = kinds.TRIANGLE_MESH

    def __init__(self, mesh, *, thickness: float = 0.0, closed: bool | None = None, cell_size: float | None = None,
                 center=None, rotation=None):
        vertices, faces = _load(mesh)
        self.thickness = validate.real("thickness", thickness, low=0.0)
        watertight = is_closed(faces)
        if closed is not None and not isinstance(closed, bool):
            raise TypeError(f"closed must be True, False or None; got {closed!r}")
        if closed and not watertight:
            raise ValueError("closed=True needs a watertight mesh (every edge shared by exactly two triangles)")
        if closed and self.thickness > 0:
            raise ValueError("thickness > 0 makes a shell around the surface, whose distance is unsigned; "
                             "leave closed=None or False")
        self.closed = watertight and closed is not False and self.thickness == 0
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        self.mesh_center = (lo + hi) / 2.0
        self.vertices = vertices - self.mesh_center  # local frame
        self.faces = faces
        extent = float(np.max(hi - lo))
        if cell_size is None:
            e = np.cross(self.vertices[faces[:, 1]] - self.vertices[faces[:, 0]],
                         self.vertices[faces[:, 2]] - self.vertices[faces[:, 0]])
            mean_area = 0.5 * float(np.mean(np.linalg.norm(e, axis=1)))
            cell_size = max(2.0 * np.sqrt(2.0 * mean_area), extent / MAX_CELLS_PER_AXIS, 1e-9 * max(extent, 1.0))
        self.cell_size = validate.real("cell_size", cell_size, low=0.0, low_open=True)
        pad = 1e-6 * max(extent, self.cell_size)
        self.grid_origin = lo - self.mesh_center - pad
        self.grid_dims = np.maximum(np.ceil((hi - lo + 2 * pad) / self.cell_size), 1).astype(np.int64)
        if np.prod(self.grid_dims) > MAX_CELLS:
            raise ValueError(f"cell_size {self.cell_size:g} m makes a grid of {self.grid_dims.tolist()} cells "
                             f"(more than {MAX_CELLS}); use a larger cell_size")
        center = self.mesh_center if center is None else validate.vector3("center", center)
        bound = float(np.max(np.linalg.norm(self.vertices, axis=1))) + self.thickness / 2
        super().__init__(center=center, rotation=validate.rotation("rotation", rotation), params=(), bound=bound)
        self._packed = {}

    def shape_data(self):
        dtype = np.dtype(runtime.float_dtype())
        if dtype not in self._packed:
            verts = np.ascontiguousarray(self.vertices, dtype=dtype)
            tris = np.ascontiguousarray(self.faces, dtype=np.int32)
            origin = self.grid_origin.astype(dtype)
            h = dtype.type(self.cell_size)
            starts, ids = bin_triangles(verts, tris, origin, float(h), self.grid_dims)
            spheres, order, leaves, boxes = triangle_tree(verts, tris, dtype)
            ishape = np.array([0, 0, len(tris), *self.grid_dims, int(self.closed), len(verts)], dtype=np.int32)
            fshape = np.array([*origin, h, self.thickness / 2, leaves, 0.0, 0.0], dtype=dtype)
            self._packed[dtype] = (ishape, fshape,
                                   np.concatenate([verts.ravel(), spheres.ravel(), boxes.ravel()]),
                                   np.concatenate([tris.ravel(), starts, ids, order]))
        return self._packed[dtype]

    def crossing(self, starts, ends, radius: float = 0.0):
        hit, t, n = super().crossing(starts, ends, radius)
        # A start in contact is a hit at t = 0 whichever way it moves, and so is a start deep
        # inside a closed mesh (the kernels sweep only from clear starts and leave both out).
        phi, normal = self._query(starts)
        touching = phi < radius
        hit[touching], t[touching], n[touching] = True, 0.0, normal[touching]
        return hit, t, n

    @property
    def triangle_count(self) -> int:
        return len(self.faces)

    def _describe(self):
        return (f"{len(self.vertices)} vertices, {len(self.faces)} triangles, "
                f"{'closed' if self.closed else 'open'}, thickness={self.thickness}, "
                f"center={self.center.tolist()}")
