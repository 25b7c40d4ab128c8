"""MeshSDF: a triangle mesh as a baked signed-distance grid (the fast path of docs/physics.md 1).

The mesh is baked once (geometry.bake, in Taichi kernels on the initialised arch) into
a grid of signed distances in its local frame; kernels sample it trilinearly
(geometry.grid_sdf). Local frame: the mesh's coordinates shifted so that the centre of its
axis-aligned bounding box is the origin. By default the collider sits where the mesh's own
coordinates put it (`center` = that bounding-box centre, no rotation); kinematic motions
move and turn the grid rigidly about `center`.
"""

import os

import numpy as np

from .. import notices, runtime, validate
from . import bake, grid_sdf, kinds
from . import cache as sdf_cache
from .colliders import Collider

SIGNS = ("auto", "winding", "parity", "none")
DEFAULT_RESOLUTION = 128
DEFAULT_PADDING_CELLS = 4


def load_mesh(mesh_or_path, name: str = "mesh"):
    """A trimesh.Trimesh from a Trimesh, a trimesh Scene, or a path trimesh loads
    (OBJ, STL, PLY, GLB, ...). Raises FileNotFoundError for a missing file and ValueError,
    naming the argument `name` and the file, for a file trimesh cannot read or a mesh
    without triangles."""
    import trimesh

    source = mesh_or_path
    where = "the mesh"  # or the file it came from
    if isinstance(mesh_or_path, (str, os.PathLike)):
        path = os.fspath(mesh_or_path)
        if not os.path.exists(path):
            raise FileNotFoundError(f"mesh file not found: {path!r}")
        if not os.path.isfile(path):
            raise ValueError(f"{name}: {path!r} is not a file")
        where = f"the mesh read from {path!r}"
        try:
            source = trimesh.load(path, force="mesh")
        except ImportError as error:
            # trimesh reaches for optional modules when a file is not what it expects (to
            # guess the text encoding of bytes that are not UTF-8, say): not the user's
            # missing package, an unreadable file
            raise ValueError(f"{name}: could not read a mesh from {path!r}: not a "
                             f"{os.path.splitext(path)[1] or 'mesh'} file trimesh can parse (it stopped for lack of "
                             f"the optional module {error.name!r})") from None
        except Exception as error:  # trimesh raises many kinds for unreadable files
            raise ValueError(f"{name}: could not read a mesh from {path!r}: {error}") from None
    if isinstance(source, trimesh.Scene):
        geometry = [g for g in source.geometry.values() if isinstance(g, trimesh.Trimesh)]
        source = trimesh.util.concatenate(geometry) if geometry else None
    if not isinstance(source, trimesh.Trimesh):
        if source is not mesh_or_path:  # a file, or a trimesh Scene, without triangles
            raise ValueError(f"{name}: {where} is empty: it has no triangles")
        raise TypeError(f"{name} must be a trimesh.Trimesh or a path to a mesh file; got {type(mesh_or_path).__name__}")
    vertices = np.asarray(source.vertices, dtype=np.float64)
    faces = np.asarray(source.faces, dtype=np.int64)
    if len(faces) == 0 or len(vertices) == 0:
        raise ValueError(f"{name}: {where} is empty: it has no triangles")
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise ValueError(f"{name}: faces must be triangles, shape (F, 3); got {faces.shape}")
    if not np.all(np.isfinite(vertices)):
        raise ValueError(f"{name}: {where} has NaN or infinite vertex coordinates")
    validate.representable(f"{name} vertices", vertices, underflow=False)
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise ValueError(f"{name}: the faces of {where} index vertices that do not exist")
    extent = np.max(vertices[faces].reshape(-1, 3), axis=0) - np.min(vertices[faces].reshape(-1, 3), axis=0)
    if np.max(extent) <= 0:
        raise ValueError(f"{name}: {where} is degenerate: all its vertices coincide")
    return source, vertices, faces


def grid_layout(extent, *, resolution, voxel_size, padding):
    """(voxel size, nodes per axis, padding) for a box of `extent` centred on the origin:
    `resolution` nodes along the longest axis (padding included), or a given voxel size;
    padding defaults to DEFAULT_PADDING_CELLS voxels."""
    extent = np.asarray(extent, dtype=np.float64)
    longest = float(np.max(extent))
    if voxel_size is not None:
        h = voxel_size
    elif padding is None:
        h = longest / (resolution - 1 - 2 * DEFAULT_PADDING_CELLS)
    else:
        h = (longest + 2 * padding) / (resolution - 1)
    pad = DEFAULT_PADDING_CELLS * h if padding is None else padding
    # counted in floats first (grid_sdf.node_counts): a tiny voxel_size would overflow an integer
    # count, wrap around and bake a 2 x 2 x 2 grid; beyond MAX_NODES, a ValueError naming the argument
    dims = grid_sdf.node_counts(extent + 2 * pad, h, name="voxel_size" if voxel_size is not None else "resolution")
    return h, dims.astype(np.int64), pad


class MeshSDF(Collider):
    """A triangle mesh baked into a signed-distance grid.

    mesh: a trimesh.Trimesh, or a path to a file trimesh reads (OBJ, STL, PLY, GLB, ...).
    resolution: grid nodes along the longest side of the padded bounding box (>= 8);
        default 128. Or voxel_size (m): the grid spacing instead (give one of the two).
    padding (m): margin added around the mesh's bounding box on every side; default 4 voxels.
    sign: "auto" (the winding number: by ray crossings for a closed mesh, the generalized
        winding number for an open, non-watertight or self-intersecting one; ray parity for
        a closed mesh whose faces are not consistently oriented), "winding", "parity", or
        "none" (unsigned distance). The method used is in `sign_method`.
    thickness (m): > 0 treats the surface as a shell of that total thickness (for sheets,
        bowls, cups): phi = |distance to the triangles| - thickness / 2, unsigned.
    center, rotation: the pose of the local frame (see the module docstring).
    cache: look the grid up in the on-disk cache and store it there after a bake
        (geometry.cache; $TAI_COLL_CACHE_DIR moves it).

    Attributes after construction: `values` (nx, ny, nz), `origin` (local position of node
    0), `voxel_size`, `sign_method`, `bake_seconds` (0 on a cache hit), `cache_hit`,
    `cache_path`, `mesh_center` (bounding-box centre in mesh coordinates).
    """

    kind = kinds.SDF_GRID

    def __init__(self, mesh, *, resolution=None, voxel_size=None, padding=None, sign="auto", thickness=0.0,
                 center=None, rotation=None, cache=True):
        self.mesh, vertices, faces = load_mesh(mesh)
        if resolution is not None and voxel_size is not None:
            raise ValueError("give resolution or voxel_size, not both")
        if voxel_size is None:
            resolution = validate.integer("resolution", DEFAULT_RESOLUTION if resolution is None else resolution,
                                          low=8)
        else:
            voxel_size = validate.real("voxel_size", voxel_size, low=0.0, low_open=True)
        padding = validate.real("padding", padding, low=0.0, allow_none=True)
        if sign not in SIGNS:
            raise ValueError(f"sign must be one of {SIGNS}; got {sign!r}")
        self.thickness = validate.real("thickness", thickness, low=0.0)
        if self.thickness > 0 and sign not in ("auto", "none"):
            raise ValueError(f"thickness > 0 makes a shell around the surface, whose distance is unsigned; "
                             f"use sign='auto' or 'none', not {sign!r}")
        if not isinstance(cache, bool):
            raise TypeError(f"cache must be True or False; got {cache!r}")

        lo, hi = vertices[faces].reshape(-1, 3).min(axis=0), vertices[faces].reshape(-1, 3).max(axis=0)
        self.mesh_center = 0.5 * (lo + hi)
        local = vertices - self.mesh_center
        h, dims, pad = grid_layout(hi - lo, resolution=resolution, voxel_size=voxel_size, padding=padding)
        origin = -0.5 * h * (dims - 1)
        self.sign = sign
        mode = "none" if self.thickness > 0 else self._sign_mode(sign, faces)

        runtime.ensure_init()
        dtype = runtime.float_dtype()
        key = sdf_cache.content_key(local, faces, dims=dims, voxel_size=h, origin=origin, sign=mode,
                                dtype=np.dtype(dtype).name, band=bake.BAND_CELLS, refine=bake.REFINE_CELLS)
        self.cache_path = sdf_cache.path_for(key) if cache else None
        stored = sdf_cache.load(key) if self.cache_path is not None else None
        self.cache_hit = stored is not None
        if stored is not None:
            values, method, seconds = stored["values"], str(stored["sign_method"]), 0.0
        else:
            grid = bake.bake_grid(local, faces, origin, h, dims, mode, dtype=dtype)
            values, method, seconds = grid.values, grid.sign_method, grid.seconds
            if self.cache_path is not None:
                try:
                    sdf_cache.store(key, values=values, sign_method=np.str_(method))
                except OSError as error:
                    notices.warn(f"could not write the SDF cache in {sdf_cache.cache_dir()}: {error}", RuntimeWarning)
                    self.cache_path = None
        self.values = np.asarray(values, dtype=np.float64).reshape(tuple(dims))
        self.origin = origin
        self.voxel_size = h
        self.padding = pad
        self.sign_method = method
        self.bake_seconds = seconds
        self.num_faces = len(faces)

        center = self.mesh_center if center is None else validate.vector3("center", center)
        half = 0.5 * h * (dims - 1)
        super().__init__(center=center, rotation=validate.rotation("rotation", rotation), params=half,
                         bound=float(np.linalg.norm(half)))

    @staticmethod
    def _sign_mode(sign, faces):
        if sign in ("winding", "parity", "none"):
            return sign
        # auto: closed and consistently oriented, or with a boundary -> winding numbers; closed
        # (every edge shared by two faces) but inconsistently oriented -> parity.
        edges, net, _, _ = bake.boundary_loops(np.zeros((int(faces.max()) + 1, 3)), faces)
        if len(edges) == 0:
            return "winding"
        sorted_edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
        _, counts = np.unique(sorted_edges, axis=0, return_counts=True)
        return "parity" if np.all(counts == 2) else "winding"

    @property
    def shell(self) -> bool:
        return self.thickness > 0

    def shape_data(self):
        ishape = np.zeros(8, dtype=np.int32)
        ishape[2:5] = self.values.shape
        ishape[5] = grid_sdf.FACE_FLOORS
        fshape = np.zeros(8)
        fshape[0:3] = self.origin
        fshape[3] = self.voxel_size
        fshape[4] = 0.5 * self.thickness
        # The least value on each face of the box (x low, x high, y low, ...): outside the
        # box the kernels search a face's nodes only where they could give a nearer point.
        v = self.values
        floors = [face.min() for face in (v[0], v[-1], v[:, 0], v[:, -1], v[:, :, 0], v[:, :, -1])]
        return ishape, fshape, np.concatenate([v.ravel(), floors]), np.zeros(0, dtype=np.int32)

    def _describe(self):
        return (f"{self.num_faces} faces, grid {list(self.values.shape)} at {self.voxel_size:.4g} m, "
                f"sign={self.sign_method!r}, center={self.center.tolist()}")


def bake_mesh(mesh, **options) -> MeshSDF:
    """Bake a mesh ahead of time into the on-disk cache and return the collider; later
    `MeshSDF(mesh, **options)` with the same options loads it without baking. Options as
    for MeshSDF (cache is always on here)."""
    if options.get("cache") is False:
        raise ValueError("bake_mesh bakes into the cache; cache=False makes no sense here")
    options["cache"] = True
    return MeshSDF(mesh, **options)
