"""The offscreen renderer: a scene's particles and colliders to an (H, W, 3) uint8 frame.

Everything is read from the scene's numpy state (`positions()`, `radii()`, `velocities()`,
each collider's current pose), so it works on every arch; GGUI (Vulkan) starts at the first
frame, in the process's one hidden window (window.py).

- Particles are drawn as spheres of their own radius (the solver's radius array), coloured
  by an attribute through a colour map, or in one colour.
- Colliders are drawn as shaded triangles (tessellate.py) where they are at this frame; a
  plane as a checkered square around the scene.
- The default camera frames the bounds of the particles and the finite colliders at the
  first frame, looking from the front, right and above (up is against gravity), and stays
  there for the rest of the run.
"""

from __future__ import annotations

import itertools
import logging
import weakref
from pathlib import Path

import numpy as np

from .. import validate
from ..geometry.colliders import Plane
from . import draw, tessellate
from .camera import Camera
from .colormap import check_colormap, map_colors
from .png import write_png

log = logging.getLogger("tai_coll.render")

_SETUPS = itertools.count()

COLOR_ATTRIBUTES = ("speed", "height", "radius", "mass", "constant")
MAX_SIZE = 16384  # pixels per side


def check_resolution(width, height):
    width = validate.integer("width", width, low=1)
    height = validate.integer("height", height, low=1)
    if width > MAX_SIZE or height > MAX_SIZE:
        raise ValueError(f"width and height must be <= {MAX_SIZE}; got {width}x{height}")
    return width, height


def _rgb(name, value):
    arr = validate.vector3(name, value)
    if np.any(arr < 0) or np.any(arr > 1):
        raise ValueError(f"{name} must be an RGB triple in [0, 1]; got {arr.tolist()}")
    return tuple(float(c) for c in arr)


class Renderer:
    """Renders a tc.Scene offscreen.

    width, height: frame size in pixels (1 to 16384).
    camera: a tai_coll.render.Camera, or None to frame the scene at the first frame.
    color_by: what colours a particle: "speed" (m/s, the default), "height" (m along the up
        axis, against gravity), "radius", "mass", "constant" (`particle_color`), or a callable
        scene -> (N,) values.
    colormap: "viridis" (default), "plasma", "turbo", "coolwarm", "gray".
    color_range: (low, high) of the colour map. None: for speed, 0 to the speed of a fall
        through the scene's height (sqrt(2 g h)), of the fastest particle at the first frame
        or twice the fastest collider's, whichever is largest; for height, the framed
        bounds; otherwise the range of values seen so far.
    particle_color, background, collider_color, moving_collider_color: RGB in [0, 1].
    ambient: ambient light (0 to 1). lights: [(position, rgb), ...] point lights; None puts one
        white light above and behind the camera.
    plane_size: half-size of the square drawn for a plane, in m (None: 1.5 x the scene's span).
    """

    def __init__(self, *, width: int = 1280, height: int = 720, camera: Camera | None = None,
                 color_by="speed", colormap: str = "viridis", color_range=None,
                 particle_color=(0.20, 0.45, 0.80), background=(0.93, 0.94, 0.96),
                 collider_color=(0.74, 0.74, 0.77), moving_collider_color=(0.92, 0.56, 0.30),
                 ambient: float = 0.35, lights=None, plane_size: float | None = None):
        self.width, self.height = check_resolution(width, height)
        if camera is not None and not isinstance(camera, Camera):
            raise TypeError(f"camera must be a tai_coll.render.Camera or None; got {type(camera).__name__}")
        self.camera = camera
        if not callable(color_by) and color_by not in COLOR_ATTRIBUTES:
            raise ValueError(f"color_by must be one of {COLOR_ATTRIBUTES} or a callable scene -> values; "
                             f"got {color_by!r}")
        self.color_by = color_by
        self.colormap = check_colormap(colormap)
        self.color_range = None
        if color_range is not None:
            try:
                low, high = (validate.real("color_range low", color_range[0]),
                             validate.real("color_range high", color_range[1]))
            except (TypeError, IndexError):
                raise TypeError(f"color_range must be (low, high) or None; got {color_range!r}") from None
            if high <= low:
                raise ValueError(f"color_range high must exceed low; got {color_range!r}")
            self.color_range = (low, high)
        self.particle_color = _rgb("particle_color", particle_color)
        self.background = _rgb("background", background)
        self.collider_color = _rgb("collider_color", collider_color)
        self.moving_collider_color = _rgb("moving_collider_color", moving_collider_color)
        self.ambient = validate.real("ambient", ambient, low=0.0, high=1.0)
        self.lights = None if lights is None else [(validate.vector3("light position", p), _rgb("light color", c))
                                                   for p, c in lights]
        self.plane_size = validate.real("plane_size", plane_size, low=0.0, low_open=True, allow_none=True)
        self.frames_rendered = 0
        self._scene_ref = None  # the scene the camera, colours and triangles were set up for
        self._scene_id = None
        self._token = None
        self._ggui_camera = None
        self._tessellations = []
        self._seen_range = None
        self._vertices = None  # GGUI's vertex array of the particles (draw.particles), reused

    # ------------------------------------------------------------------ public
    def _set_up_view(self, win):
        """Background, camera and lights of the window's canvas and scene, for one frame."""
        canvas, view = win.get_canvas(), win.get_scene()
        canvas.set_background_color(self.background)
        view.set_camera(self._ggui_camera)
        view.ambient_light((self.ambient,) * 3)
        for position, color in self._light_list():
            view.point_light(tuple(float(c) for c in position), color)
        return canvas, view

    def render(self, scene) -> np.ndarray:
        """The scene as it is now: an (H, W, 3) uint8 array, row 0 at the top."""
        from . import window as ggui

        self._prepare(scene)
        win = ggui.open_window(self.width, self.height)
        canvas, view = self._set_up_view(win)
        buffers = ggui.mesh_buffers()
        self._upload_colliders(scene, buffers)
        if buffers.count:
            draw.mesh(view, buffers)
        if scene.num_particles:
            x = np.ascontiguousarray(scene.positions(), dtype=np.float32)
            # GGUI sizes a particle by the window's width where its projection uses the
            # height (taichi 1.7): scale by height / width so it shows its true radius.
            r = np.ascontiguousarray(scene.radii() * (self.height / self.width), dtype=np.float32)
            self._vertices = draw.particles(view, x, r, self._particle_colors(scene), self._vertices)
        canvas.scene(view)
        image = win.get_image_buffer_as_numpy()  # (W, H, 4) float32, x-major, y up
        self.frames_rendered += 1
        return to_uint8(image)

    def save(self, scene, path) -> Path:
        """Render and write a PNG; returns its path."""
        return write_png(path, self.render(scene))

    def camera_for(self, scene) -> Camera:
        """The camera frames use (the default one framed on this scene if none was given)."""
        self._prepare(scene)
        return self.camera

    def project(self, points):
        """Pixel (column, row) and depth of world points in this renderer's frames
        (after the camera is known: the first render or `camera_for`)."""
        if self.camera is None:
            raise RuntimeError("the camera is not known yet: call render(scene) or camera_for(scene) first")
        return self.camera.project(points, self.width, self.height)

    # ------------------------------------------------------------------ set-up
    def _prepare(self, scene):
        key = (len(scene.colliders),)
        if self._scene_ref is not None and self._scene_ref() is scene and key == self._scene_id:
            return
        import taichi as ti

        self._scene_ref = weakref.ref(scene)
        self._scene_id = key
        self._token = next(_SETUPS)  # names this set-up's triangles in the shared mesh buffers
        self._up = self._up_axis(scene)
        solids = []  # (entry, local tessellation) of every collider but planes
        for entry in scene.colliders:
            if not isinstance(entry.shape, Plane):
                solids.append((entry, tessellate.collider_triangles(entry.shape)))
        lo, hi, points = self._bounds(scene, solids)
        self._bounds_lo, self._bounds_hi = lo, hi
        if self.camera is None:
            self.camera = Camera.framing(lo, hi, points=points, aspect=self.width / self.height, up=self._up,
                                         margin=1.12)
        cam = ti.ui.Camera()
        cam.position(*self.camera.position)
        cam.lookat(*self.camera.look_at)
        cam.up(*self.camera.up)
        cam.fov(self.camera.fov)
        cam.z_near(self.camera.near)
        self._ggui_camera = cam
        self._collect_drawables(scene, solids, lo, hi)
        self._speed_scale = self._default_speed_scale(scene, lo, hi)

    @staticmethod
    def _up_axis(scene):
        g = np.asarray(scene.gravity, dtype=np.float64)
        return -g / np.linalg.norm(g) if np.linalg.norm(g) > 0 else np.array([0.0, 1.0, 0.0])

    @staticmethod
    def _bounds(scene, solids):
        """(lower, upper, points): the box around the particles (padded by their radii) and
        the finite colliders as they are now, and a sample of points to frame."""
        points = []
        pad = 0.0
        if scene.num_particles:
            x = scene.positions()
            x = x[np.all(np.isfinite(x), axis=1)]
            if len(x):
                pad = float(np.max(scene.radii()))
                points.append(x[:: max(1, len(x) // 20000)])
                points.append(np.array([x.min(axis=0), x.max(axis=0)]))
        for entry, tess in solids:
            if tess is not None:
                points.append(tess.vertices @ entry.rotation.T + entry.center)
        if not points:
            c = scene.colliders[0].center if scene.colliders else np.zeros(3)
            return c - 0.5, c + 0.5, None
        pts = np.concatenate(points)
        lo, hi = pts.min(axis=0) - pad, pts.max(axis=0) + pad
        span = max(float(np.max(hi - lo)), 1e-3)
        return lo - 0.02 * span, hi + 0.02 * span, pts

    def _collect_drawables(self, scene, solids, lo, hi):
        """Local-frame triangles and colours of every drawable collider, once per scene;
        planes become squares around the framed bounds."""
        center = (lo + hi) / 2.0
        half = self.plane_size or 1.5 * max(float(np.max(hi - lo)), 1e-3)
        local_of = {id(entry): tess for entry, tess in solids}
        self._tessellations = []
        for entry in scene.colliders:
            if isinstance(entry.shape, Plane):
                local = (center - entry.center) @ entry.rotation
                tess = tessellate.collider_triangles(entry.shape, plane_half_size=half,
                                                     plane_center=(local[0], local[2]))
            else:
                tess = local_of[id(entry)]
            if tess is None:
                log.warning("cannot draw a %s collider (it exposes no triangles); skipping it",
                            type(entry.shape).__name__)
                continue
            color = self.moving_collider_color if entry.is_kinematic else self.collider_color
            colors = tess.colors if tess.colors is not None else np.tile(color, (len(tess.vertices), 1))
            self._tessellations.append((entry, tess, colors))

    def _upload_colliders(self, scene, buffers):
        kinematic = any(entry.is_kinematic for entry, _, _ in self._tessellations)
        token = (self._token, self.frames_rendered if kinematic else -1)
        if buffers.owner == token:
            return
        if not self._tessellations:
            buffers.count, buffers.owner = 0, token
            return
        verts, norms, cols = [], [], []
        for entry, tess, colors in self._tessellations:
            verts.append(tess.vertices @ entry.rotation.T + entry.center)
            norms.append(tess.normals @ entry.rotation.T)
            cols.append(colors)
        buffers.upload(np.concatenate(verts), np.concatenate(norms), np.concatenate(cols), owner=token)

    def _light_list(self):
        if self.lights is not None:
            return self.lights
        right, up, forward = self.camera.basis()
        distance = float(np.linalg.norm(self.camera.look_at - self.camera.position))
        position = self.camera.position + distance * (0.8 * self._up + 0.4 * right - 0.2 * forward)
        return [(position, (0.85, 0.85, 0.85))]

    # ------------------------------------------------------------------ colours
    def _default_speed_scale(self, scene, lo, hi):
        g = float(np.linalg.norm(scene.gravity))
        height = float((hi - lo) @ np.abs(self._up))
        fall = np.sqrt(2.0 * g * max(height, 0.0))
        particles = float(np.max(np.linalg.norm(scene.velocities(), axis=1))) if scene.num_particles else 0.0
        colliders = 0.0
        for entry in scene.colliders:
            if entry.is_kinematic:
                reach = float(entry.shape.params[entry.shape.BOUND_SLOT])
                reach = reach if reach < entry.shape.UNBOUNDED else 0.0
                surface = np.linalg.norm(entry.velocity) + np.linalg.norm(entry.angular_velocity) * reach
                colliders = max(colliders, float(surface))
        return max(fall, particles, 2.0 * colliders, 1e-6)

    def _particle_colors(self, scene) -> np.ndarray:
        n = scene.num_particles
        if self.color_by == "constant":
            return np.tile(np.asarray(self.particle_color, dtype=np.float32), (n, 1))
        if callable(self.color_by):
            values = np.asarray(self.color_by(scene), dtype=np.float64).ravel()
            if values.shape != (n,):
                raise ValueError(f"color_by(scene) must return {n} values; got shape {values.shape}")
        elif self.color_by == "speed":
            values = np.linalg.norm(scene.velocities(), axis=1)
        elif self.color_by == "height":
            values = scene.positions() @ self._up
        elif self.color_by == "radius":
            values = scene.radii()
        else:
            values = scene.masses()
        return map_colors(values, self.colormap, *self._range(values))

    def _range(self, values):
        if self.color_range is not None:
            return self.color_range
        if self.color_by == "speed":
            return 0.0, self._speed_scale
        if self.color_by == "height":
            return float(self._bounds_lo @ self._up), float(self._bounds_hi @ self._up)
        finite = values[np.isfinite(values)]
        if finite.size:
            low, high = float(finite.min()), float(finite.max())
            if self._seen_range is not None:
                low, high = min(low, self._seen_range[0]), max(high, self._seen_range[1])
            self._seen_range = (low, high)
        return self._seen_range or (0.0, 1.0)


def to_uint8(image: np.ndarray) -> np.ndarray:
    """GGUI's (W, H, 4) float image, x-major with y up, to (H, W, 3) uint8 with row 0 on top."""
    rgb = image[:, ::-1, :3].transpose(1, 0, 2)
    return (np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
