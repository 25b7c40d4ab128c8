"""A pinhole camera: where it stands, what it looks at, its vertical field of view.

Pure numpy, so the projection can be tested without Vulkan and reused to find where a
particle lands in a frame. The conventions are GGUI's (ti.ui.Camera): a right-handed view
frame looking down -z, a vertical field of view in degrees, the aspect ratio width / height.
"""

from __future__ import annotations

import numpy as np

from .. import validate


class Camera:
    """position, look_at, up: 3-vectors in m (up need not be unit or orthogonal to the view).
    fov: vertical field of view in degrees, in (0, 180). near: distance of the near clipping
    plane in m (None: 1 % of the distance to look_at, so small scenes are not clipped)."""

    def __init__(self, *, position, look_at=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov: float = 45.0,
                 near: float | None = None):
        self.position = validate.vector3("position", position)
        self.look_at = validate.vector3("look_at", look_at)
        self.up = validate.vector3("up", up, nonzero=True)
        self.fov = validate.real("fov", fov, low=0.0, low_open=True)
        if self.fov >= 180.0:
            raise ValueError(f"fov must be < 180 degrees; got {self.fov}")
        distance = float(np.linalg.norm(self.look_at - self.position))
        if distance < 1e-12:
            raise ValueError("camera position and look_at must be distinct points")
        forward = (self.look_at - self.position) / distance
        if np.linalg.norm(np.cross(forward, self.up)) < 1e-9 * np.linalg.norm(self.up):
            raise ValueError(f"camera up {self.up.tolist()} must not be parallel to the view direction")
        self.near = 0.01 * distance if near is None else validate.real("near", near, low=0.0, low_open=True)

    # ------------------------------------------------------------------ frames
    def basis(self):
        """(right, true_up, forward): orthonormal, right-handed with -forward toward the viewer."""
        forward = self.look_at - self.position
        forward = forward / np.linalg.norm(forward)
        right = np.cross(forward, self.up)
        right /= np.linalg.norm(right)
        return right, np.cross(right, forward), forward

    def view_matrix(self) -> np.ndarray:
        """4x4, world to view coordinates, acting on column vectors (GGUI's, transposed)."""
        right, up, forward = self.basis()
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = right, up, -forward
        m[:3, 3] = -m[:3, :3] @ self.position
        return m

    def focal(self, aspect: float):
        """Projection scales (sx, sy): ndc = (sx x, sy y) / depth for view coordinates x, y."""
        sy = 1.0 / np.tan(np.radians(self.fov) / 2.0)
        return sy / aspect, sy

    def project(self, points, width: int, height: int):
        """Pixel coordinates of world points in an image of width x height.

        Returns (pixels (N, 2) as (column, row) with row 0 at the top and pixel (i, j) covering
        [j, j+1) x [i, i+1), depth (N,) in m along the view direction; depth <= near is behind
        or too close to the camera)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        right, up, forward = self.basis()
        rel = p - self.position
        depth = rel @ forward
        sx, sy = self.focal(width / height)
        safe = np.where(np.abs(depth) > 1e-300, depth, 1e-300)
        ndc_x = sx * (rel @ right) / safe
        ndc_y = sy * (rel @ up) / safe
        pixels = np.column_stack([(ndc_x + 1.0) * 0.5 * width, (1.0 - ndc_y) * 0.5 * height])
        return pixels, depth

    def pixels_per_meter(self, depth, height: int):
        """On-screen scale at a depth (m): pixels per m, the same horizontally and vertically."""
        return height / (2.0 * np.asarray(depth) * np.tan(np.radians(self.fov) / 2.0))

    # ------------------------------------------------------------------ framing
    @classmethod
    def framing(cls, lower, upper, *, aspect: float, points=None, up=(0.0, 1.0, 0.0), fov: float = 45.0,
                direction=(0.35, 0.45, 1.0), margin: float = 1.08) -> "Camera":
        """A camera looking at the center of the box [lower, upper] from `direction` (in the
        frame right, up, toward the viewer; for up = +y that is world x, y, z), just far
        enough that `points` ((N, 3); default the box's eight corners) are all in view,
        times `margin`."""
        lo = validate.vector3("lower", lower)
        hi = validate.vector3("upper", upper)
        if np.any(hi < lo):
            raise ValueError(f"framing bounds: upper {hi.tolist()} is below lower {lo.tolist()}")
        up_axis = validate.vector3("up", up, nonzero=True)
        up_axis = up_axis / np.linalg.norm(up_axis)
        toward = None
        for candidate in (np.array([0.0, 0.0, 1.0]), np.array([0.0, -1.0, 0.0]), np.array([1.0, 0.0, 0.0])):
            t = candidate - (candidate @ up_axis) * up_axis
            if np.linalg.norm(t) > 0.3:
                toward = t / np.linalg.norm(t)
                break
        right_axis = np.cross(up_axis, toward)
        d = validate.vector3("direction", direction, nonzero=True)
        back = d[0] * right_axis + d[1] * up_axis + d[2] * toward
        back /= np.linalg.norm(back)

        center = (lo + hi) / 2.0
        span = max(float(np.max(hi - lo)), 1e-6)
        if points is None:
            points = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        right, true_up, _ = cls(position=center + back, look_at=center, up=up_axis, fov=fov).basis()
        tan_v = np.tan(np.radians(fov) / 2.0)
        tan_h = tan_v * aspect
        def fit(center):
            # A point p (relative to the look-at point) is in view from distance D when
            # |p.right| <= (D - p.back) tan_h and |p.up| <= (D - p.back) tan_v.
            rel = points - center
            along, across, rise = rel @ back, rel @ right, rel @ true_up
            need = np.maximum(along + np.abs(across) / tan_h, along + np.abs(rise) / tan_v)
            return max(float(np.max(need)), 0.25 * span), along, across, rise

        for _ in range(4):
            # move the look-at point so the points' extent sits in the middle of the frame
            distance, along, across, rise = fit(center)
            depth = np.maximum(distance - along, 1e-9 * span)
            tx, ty = across / depth, rise / depth
            center = center + distance * (0.5 * (tx.max() + tx.min()) * right + 0.5 * (ty.max() + ty.min()) * true_up)
        distance = fit(center)[0] * margin
        return cls(position=center + distance * back, look_at=center, up=up_axis, fov=fov)

    def __repr__(self):
        return (f"Camera(position={np.round(self.position, 4).tolist()}, look_at={np.round(self.look_at, 4).tolist()}, "
                f"up={self.up.tolist()}, fov={self.fov:g})")
