"""Height fields: terrain y = h(x, z) from a 2-D array of heights, or from an image
(docs/physics.md 1, height field row; seed 002). The shape description; its device queries
are in terrain.py.
"""

import os

import numpy as np

from .. import runtime, validate
from . import kinds
from .colliders import Collider
from .terrain import BLOCK
from .triangles import EMPTY, box_tree


def _read_netpbm(path: str) -> np.ndarray:
    """A PGM or PPM image (P2, P3, P5, P6) as an (H, W) float array in [0, 1]; colour is
    averaged to grey."""
    with open(path, "rb") as f:
        data = f.read()
    magic = data[:2]
    if magic not in (b"P2", b"P3", b"P5", b"P6"):
        raise ValueError(f"path: {path!r} is not a PGM/PPM image (magic {magic!r})")
    channels = 3 if magic in (b"P3", b"P6") else 1
    # Header: magic, width, height, maxval, separated by whitespace, '#' comments allowed.
    fields = []
    pos = 2
    while len(fields) < 3:
        while pos < len(data) and data[pos:pos + 1].isspace():
            pos += 1
        if data[pos:pos + 1] == b"#":
            while pos < len(data) and data[pos:pos + 1] not in (b"\n", b"\r"):
                pos += 1
            continue
        start = pos
        while pos < len(data) and not data[pos:pos + 1].isspace():
            pos += 1
        if start == pos:
            raise ValueError(f"path: {path!r} has a truncated PGM/PPM header")
        fields.append(int(data[start:pos]))
    width, height, maxval = fields
    count = width * height * channels
    if magic in (b"P2", b"P3"):
        values = np.array(data[pos:].split()[:count], dtype=np.float64)
    else:
        dtype = np.dtype(">u2") if maxval > 255 else np.dtype("u1")
        values = np.frombuffer(data, dtype=dtype, count=count, offset=pos + 1).astype(np.float64)
    if values.size != count:
        raise ValueError(f"path: {path!r} holds {values.size} samples, expected {count}")
    image = values.reshape(height, width, channels).mean(axis=2)
    return image / maxval


class HeightField(Collider):
    """Terrain y = h(x, z) (docs/physics.md 1): heights[i, j] (m) at x = origin_x + i dx,
    z = origin_z + j dz, y = origin_y + heights[i, j]; each cell is two triangles. Beyond
    the footprint the border heights continue flat.

    heights: 2-D array, at least 2 x 2 vertices, finite.
    cell_size: dx = dz (m, > 0), or a pair (dx, dz).
    origin: position of vertex (0, 0) at height 0 (m).
    The collider's center (pivot of angular_velocity) is the footprint's center at origin_y.
    """

    kind = kinds.HEIGHT_FIELD

    def __init__(self, *, heights, cell_size, origin=(0.0, 0.0, 0.0)):
        try:
            h = np.asarray(heights, dtype=np.float64)
        except (TypeError, ValueError):
            raise TypeError("heights must be a 2-D array of numbers") from None
        if h.ndim != 2 or h.shape[0] < 2 or h.shape[1] < 2:
            raise ValueError(f"heights must be a 2-D array of at least 2 x 2 vertices; got shape {h.shape}")
        if not np.all(np.isfinite(h)):
            raise ValueError("heights must be finite")
        validate.representable("heights", h, underflow=False)
        if np.ndim(cell_size) == 0:
            dx = dz = validate.real("cell_size", cell_size, low=0.0, low_open=True)
        else:
            pair = np.asarray(cell_size)
            if pair.shape != (2,):
                raise ValueError(f"cell_size must be a number or a pair (dx, dz); got shape {pair.shape}")
            dx = validate.real("cell_size[0]", float(pair[0]), low=0.0, low_open=True)
            dz = validate.real("cell_size[1]", float(pair[1]), low=0.0, low_open=True)
        origin = validate.vector3("origin", origin)
        self.heights = h
        self.cell_size = (dx, dz)
        self.origin = origin
        half = np.array([(h.shape[0] - 1) * dx / 2.0, 0.0, (h.shape[1] - 1) * dz / 2.0])
        self._local_origin = -half
        # Steepest slope over the triangles: |grad h| of each triangle's plane.
        sx0 = np.diff(h, axis=0)[:, :-1] / dx   # h10 - h00: lower triangle's x slope
        sz0 = (h[1:, 1:] - h[1:, :-1]) / dz      # h11 - h10: its z slope
        sz1 = np.diff(h, axis=1)[:-1, :] / dz   # h01 - h00: upper triangle's z slope
        sx1 = (h[1:, 1:] - h[:-1, 1:]) / dx      # h11 - h01: its x slope
        self.max_slope = float(max(np.max(np.hypot(sx0, sz0)), np.max(np.hypot(sx1, sz1))))
        super().__init__(center=origin + half, rotation=np.eye(3), params=(), bound=self.UNBOUNDED)
        self._packed = {}  # shape_data per float dtype

    @classmethod
    def from_image(cls, path, *, cell_size, height_scale: float = 1.0, origin=(0.0, 0.0, 0.0)) -> "HeightField":
        """A terrain from an image file: a .npy 2-D array (heights = values * height_scale)
        or a PGM/PPM image (heights = grey level in [0, 1] * height_scale). Pixel (row, col)
        becomes vertex (i = col, j = row): x runs along the image's width, z down its height."""
        path = os.fspath(path)
        height_scale = validate.real("height_scale", height_scale)
        if not os.path.exists(path):
            raise FileNotFoundError(f"height image not found: {path!r}")
        if path.lower().endswith(".npy"):
            image = np.load(path, allow_pickle=False)
            if image.ndim != 2:
                raise ValueError(f"path: {path!r} must hold a 2-D array; got shape {image.shape}")
        else:
            image = _read_netpbm(path)
        return cls(heights=np.asarray(image, dtype=np.float64).T * height_scale, cell_size=cell_size,
                   origin=origin)

    def height(self, x, z) -> np.ndarray:
        """The terrain's height y at world (x, z) (arrays broadcast), by the same triangles
        the kernels use, on the host (for scenes and tests of a field that has not moved)."""
        dx, dz = self.cell_size
        fx = (np.asarray(x, dtype=np.float64) - self.origin[0]) / dx
        fz = (np.asarray(z, dtype=np.float64) - self.origin[2]) / dz
        i = np.floor(fx)
        j = np.floor(fz)
        ux, uz = fx - i, fz - j
        nx, nz = self.heights.shape
        i, j = i.astype(np.int64), j.astype(np.int64)

        def at(a, b):
            return self.heights[np.clip(a, 0, nx - 1), np.clip(b, 0, nz - 1)]

        h00, h10, h01, h11 = at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)
        lower = h00 + ux * (h10 - h00) + uz * (h11 - h10)
        upper = h00 + uz * (h01 - h00) + ux * (h11 - h01)
        return self.origin[1] + np.where(uz > ux, upper, lower)

    def crossing(self, starts, ends, radius: float = 0.0):
        hit, t, n = super().crossing(starts, ends, radius)
        phi, normal = self._query(starts)
        touching = phi < radius  # in contact at the start, whichever way it moves
        hit[touching], t[touching], n[touching] = True, 0.0, normal[touching]
        return hit, t, n

    def shape_data(self):
        dtype = np.dtype(runtime.float_dtype())
        if dtype not in self._packed:
            nx, nz = self.heights.shape
            order, leaves, boxes, blocks_z = self._block_tree(dtype)
            ishape = np.array([0, 0, nx, nz, blocks_z, leaves, 0, 0], dtype=np.int32)
            fshape = np.array([*self._local_origin, *self.cell_size, 1.0 / np.sqrt(1.0 + self.max_slope ** 2),
                               float(self.heights.max()), 0.0])
            self._packed[dtype] = (ishape, fshape, np.concatenate([self.heights.ravel(), boxes.ravel()]), order)
        return self._packed[dtype]

    def _block_tree(self, dtype):
        """The box tree of the exact distance (terrain.py): blocks of BLOCK x BLOCK cells over
        the cells i = -1 ... nx - 1, j = -1 ... nz - 1 (the footprint and the ring beyond it),
        each boxed by its footprint (unbounded on a side the ring continues) and the range of
        its corner heights. Returns (order, leaves, boxes, blocks along z)."""
        h = self.heights
        nx, nz = h.shape
        dx, dz = self.cell_size
        bx, bz = -(-(nx + 1) // BLOCK), -(-(nz + 1) // BLOCK)
        # Corner heights of every cell i = -1 ... bx BLOCK - 2 (indices clamped, as in the kernels).
        vi = np.clip(np.arange(-1, bx * BLOCK), 0, nx - 1)
        vj = np.clip(np.arange(-1, bz * BLOCK), 0, nz - 1)
        v = h[np.ix_(vi, vj)]
        corners = np.stack([v[:-1, :-1], v[1:, :-1], v[:-1, 1:], v[1:, 1:]])
        low = corners.min(axis=0).reshape(bx, BLOCK, bz, BLOCK).min(axis=(1, 3)).ravel()
        high = corners.max(axis=0).reshape(bx, BLOCK, bz, BLOCK).max(axis=(1, 3)).ravel()
        bi, bj = np.divmod(np.arange(bx * bz), bz)
        x0, z0 = (BLOCK * bi - 1) * dx, (BLOCK * bj - 1) * dz
        x1, z1 = x0 + BLOCK * dx, z0 + BLOCK * dz
        x0 = np.where(bi == 0, -EMPTY, x0)
        z0 = np.where(bj == 0, -EMPTY, z0)
        x1 = np.where(BLOCK * bi + BLOCK - 2 >= nx - 1, EMPTY, x1)
        z1 = np.where(BLOCK * bj + BLOCK - 2 >= nz - 1, EMPTY, z1)
        order, leaves, boxes = box_tree(np.column_stack([x0, low, z0]), np.column_stack([x1, high, z1]),
                                        np.column_stack([bi, np.zeros_like(bi), bj]), 1, dtype)
        return order, leaves, boxes, bz

    def _describe(self):
        return f"{self.heights.shape[0]} x {self.heights.shape[1]} heights, cell_size={self.cell_size}, " \
               f"origin={self.origin.tolist()}"
