"""Mass properties of a rigid body made of a closed collider shape (docs/physics.md 2, "Mass
properties of bodies"): mass, centre of mass, inertia tensor about the centre of mass and
volume, at uniform density unless the caller gives the inertia.

Everything is in the shape's local frame, the one its signed distance is written in
(geometry/analytic.py, the mesh colliders): the analytic shapes are centred on its origin,
cylinder and capsule along its y axis; a mesh's origin is the centre of its bounding box,
so its centre of mass is in general off the origin. The tensor's axes are the local axes;
in the world it is `R I R^T`, R the shape's rotation. Host side only (numpy, and trimesh for
meshes): nothing here reaches a kernel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import validate
from ..geometry.colliders import Box, Capsule, Collider, Cylinder, Plane, Sphere
from ..geometry.height_field import HeightField
from ..geometry.implicit import Implicit
from ..geometry.mesh_sdf import MeshSDF
from ..geometry.triangle_mesh import TriangleMesh, is_closed

ACCEPTED = "Sphere, Box, Cylinder, Capsule, a closed TriangleMesh or a MeshSDF of a closed mesh"
SYMMETRY_TOLERANCE = 1e-9  # relative to the largest entry of a given inertia
TRIANGLE_TOLERANCE = 1e-9  # relative to the largest principal moment (a flat plate has I3 = I1 + I2)
MIN_RELATIVE_VOLUME = 1e-9  # of the bounding box: below it a closed mesh encloses nothing


@dataclass(frozen=True)
class MassProperties:
    """What a rigid body needs of its shape (docs/physics.md 2, "Mass properties of bodies").

    mass (kg); center_of_mass (3,) in m, in the shape's local frame; inertia (3, 3) in
    kg m^2, about the centre of mass, along the local axes (the body frame), symmetric
    positive definite; volume (m^3) of the solid. The arrays are read-only copies.
    """

    mass: float
    center_of_mass: np.ndarray
    inertia: np.ndarray
    volume: float

    def __post_init__(self):
        for name in ("center_of_mass", "inertia"):
            value = np.array(getattr(self, name), dtype=np.float64)
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        object.__setattr__(self, "mass", float(self.mass))
        object.__setattr__(self, "volume", float(self.volume))

    @property
    def density(self) -> float:
        """The mean density, mass / volume (kg/m^3)."""
        return self.mass / self.volume


def mass_properties(shape, *, mass=None, density=None, inertia=None) -> MassProperties:
    """Mass properties of `shape` as a solid body (docs/physics.md 2, "Mass properties of bodies").

    shape: a closed collider: tc.Sphere, tc.Box, tc.Cylinder, tc.Capsule, a closed
        tc.TriangleMesh (thickness 0) or a tc.MeshSDF of a closed, consistently oriented mesh
        (thickness 0, signed). Planes, height fields, implicit surfaces, open meshes and
        shells bound no solid and are refused (ValueError); what is not a collider is a
        TypeError.
    mass (kg, > 0) or density (kg/m^3, > 0): exactly one; mass = density x volume.
    inertia: None for the shape's at uniform density (closed forms for the analytic shapes,
        the volume integrals of the triangles for meshes), scaled to `mass`; or a 3x3 tensor
        (kg m^2) about the centre of mass in the local axes: symmetric (to a relative 1e-9;
        it is symmetrised), positive definite, and with principal moments obeying the
        triangle inequality I1 + I2 >= I3, as every rigid body's do.

    The centre of mass is the centroid of the solid: the local origin for the analytic
    shapes, the volume centroid for a mesh (whose local origin is its bounding-box centre).
    """
    volume, center, per_mass = _uniform(shape)
    if (mass is None) == (density is None):
        raise ValueError(f"give exactly one of mass (kg) or density (kg/m^3); got "
                         f"{'both' if mass is not None else 'neither'}")
    if mass is not None:
        mass = validate.real("mass", mass, low=0.0, low_open=True)
    else:
        density = validate.real("density", density, low=0.0, low_open=True)
        mass = validate.representable("mass (density x volume)", density * volume)  # (inf included)
    if inertia is None:
        tensor = _stored("inertia (the shape's at this mass)", mass * per_mass)
    else:
        tensor = _checked_inertia(inertia)
    return MassProperties(mass=mass, center_of_mass=center, inertia=tensor, volume=volume)


def _uniform(shape):
    """(volume m^3, centre of mass (3,) m, inertia per unit mass (3, 3) m^2 about the centre
    of mass) of the shape at uniform density, in its local frame."""
    if isinstance(shape, Sphere):
        r = shape.radius
        return 4.0 / 3.0 * np.pi * r ** 3, np.zeros(3), np.eye(3) * (0.4 * r * r)
    if isinstance(shape, Box):
        a, b, c = shape.half_extents  # full sides 2a, 2b, 2c: (2b)^2 / 12 = b^2 / 3
        return 8.0 * a * b * c, np.zeros(3), np.diag([b * b + c * c, a * a + c * c, a * a + b * b]) / 3.0
    if isinstance(shape, Cylinder):
        r, h = shape.radius, shape.half_height  # axis y, length 2h: (3 r^2 + (2h)^2) / 12
        across = r * r / 4.0 + h * h / 3.0
        return 2.0 * np.pi * r * r * h, np.zeros(3), np.diag([across, r * r / 2.0, across])
    if isinstance(shape, Capsule):
        return _capsule(shape.radius, shape.half_height)
    if isinstance(shape, TriangleMesh):
        if shape.thickness > 0:
            raise ValueError(f"shape: a TriangleMesh with thickness > 0 (here {shape.thickness:g} m) is a shell "
                             f"around its surface, not a solid; a body needs {ACCEPTED}")
        if not is_closed(shape.faces):
            raise ValueError(f"shape: the TriangleMesh is open (not every edge is shared by exactly two "
                             f"triangles), so it bounds no solid; a body needs {ACCEPTED}")
        if not shape.closed:
            raise ValueError("shape: the TriangleMesh was made with closed=False, a surface with no inside; "
                             "leave closed=None for a body")
        # the collider tells inside by ray parity, whichever way the triangles face
        return _mesh(shape.vertices, shape.faces, either_orientation=True)
    if isinstance(shape, MeshSDF):
        if shape.thickness > 0:
            raise ValueError(f"shape: a MeshSDF with thickness > 0 (here {shape.thickness:g} m) is a shell around "
                             f"its surface, not a solid; a body needs {ACCEPTED}")
        faces = np.asarray(shape.mesh.faces, dtype=np.int64)
        if not is_closed(faces):
            raise ValueError(f"shape: the MeshSDF's mesh is open (not every edge is shared by exactly two "
                             f"triangles), so it bounds no solid; a body needs {ACCEPTED}")
        if shape.sign_method.startswith("none"):  # (the others, for a closed mesh: winding number or parity)
            raise ValueError(f"shape: the MeshSDF was baked with sign={shape.sign!r}, an unsigned distance with no "
                             f"inside; bake it with sign='auto' for a body")
        vertices = np.asarray(shape.mesh.vertices, dtype=np.float64) - shape.mesh_center  # its local frame
        return _mesh(vertices, faces, either_orientation="parity" in shape.sign_method)
    if isinstance(shape, Collider):
        if isinstance(shape, Plane):
            why = "a Plane is a half-space, with no finite mass"
        elif isinstance(shape, HeightField):
            why = "a HeightField is terrain, solid without end below its surface"
        elif isinstance(shape, Implicit):
            why = "an Implicit surface has no closed form or triangles to integrate its mass over"
        else:
            why = f"a {type(shape).__name__} ({shape.kind_name}) has no mass properties here"
        raise ValueError(f"shape: {why}; a body needs {ACCEPTED}")
    raise TypeError(f"shape must be a tai_coll collider ({ACCEPTED}); got {type(shape).__name__}")


def _capsule(r: float, h: float):
    """A capsule of radius r around the segment (0, -h, 0) -> (0, h, 0): a cylinder of radius
    r and length 2h plus two hemispheres, whose masses split by volume at uniform density.

    Along the axis (y) the two hemispheres are one ball: I_yy = m_c r^2 / 2 + m_s 2 r^2 / 5.
    Across (x, z), a hemisphere of mass m_s / 2:
      - about a diameter of its flat face it has half a ball's moment, (m_s / 2) 2 r^2 / 5
        (a ball's moment about a diameter splits equally between its halves, by symmetry);
      - its centroid lies 3r/8 from the flat face (the integral of z over the half ball,
        pi r^4 / 4, divided by its volume 2 pi r^3 / 3), so about a parallel axis through
        the centroid the moment is (m_s / 2) (2 r^2 / 5 - (3r/8)^2) (parallel axes, back);
      - the centroid is h + 3r/8 from the capsule's centre: parallel axes again, forward,
        (m_s / 2) (2 r^2 / 5 - (3r/8)^2 + (h + 3r/8)^2) = (m_s / 2) (2 r^2 / 5 + h^2 + 3 h r / 4).
    Both hemispheres, with the cylinder's m_c (3 r^2 + (2h)^2) / 12:
      I_xx = I_zz = m_c (r^2 / 4 + h^2 / 3) + m_s (2 r^2 / 5 + h^2 + 3 h r / 4).
    """
    v_cylinder = 2.0 * np.pi * r * r * h
    v_ball = 4.0 / 3.0 * np.pi * r ** 3
    volume = v_cylinder + v_ball
    f_c, f_s = v_cylinder / volume, v_ball / volume  # mass fractions
    along = f_c * r * r / 2.0 + f_s * 0.4 * r * r
    across = f_c * (r * r / 4.0 + h * h / 3.0) + f_s * (0.4 * r * r + h * h + 0.75 * h * r)
    return volume, np.zeros(3), np.diag([across, along, across])


def _mesh(vertices: np.ndarray, faces: np.ndarray, *, either_orientation: bool):
    """Volume, centroid and inertia per unit mass of the solid a closed mesh bounds (local
    frame), from trimesh's volume integrals of the triangles (Eberly's polyhedral mass
    properties). With `either_orientation` (a collider that tells inside by ray parity)
    an inward-facing mesh counts as the same solid: reversing every triangle negates every
    integral, which leaves the centroid and the inertia per unit mass unchanged."""
    import trimesh

    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False, validate=False)
    if not mesh.is_winding_consistent:
        raise ValueError("shape: the mesh's triangles are not consistently oriented (an edge is traversed the "
                         "same way by both its triangles), so its volume is undefined; orient them first "
                         "(trimesh's mesh.fix_normals(), which needs networkx)")
    with np.errstate(divide="ignore", invalid="ignore"):  # (a flat mesh's centroid: 0 / 0, refused below)
        props = trimesh.triangles.mass_properties(mesh.triangles, crosses=mesh.triangles_cross, density=1.0)
    volume = float(props.volume)
    extent = float(np.max(np.ptp(vertices[faces].reshape(-1, 3), axis=0)))
    if not abs(volume) > MIN_RELATIVE_VOLUME * extent ** 3:
        raise ValueError(f"shape: the closed mesh encloses no volume ({volume:g} m^3); a body needs a solid")
    if volume < 0 and not either_orientation:
        raise ValueError(f"shape: the mesh's triangles face inward (its signed volume is {volume:g} m^3), so "
                         f"the MeshSDF's winding number leaves it no inside; invert the mesh (mesh.invert()) "
                         f"before baking it")
    per_mass = np.asarray(props.inertia, dtype=np.float64) / float(props.mass)  # both negate when inverted
    per_mass = 0.5 * (per_mass + per_mass.T) + 0.0  # (+ 0.0: no negative zeros)
    return abs(volume), np.asarray(props.center_mass, dtype=np.float64) + 0.0, per_mass


def _checked_inertia(value) -> np.ndarray:
    """A user's inertia tensor (kg m^2): 3x3 finite, symmetric, positive definite, with
    principal moments satisfying the triangle inequality; symmetrised."""
    tensor = validate._float_array("inertia", value, "a 3x3 matrix")
    if tensor.shape != (3, 3):
        raise ValueError(f"inertia must be a 3x3 tensor; got shape {tensor.shape}")
    if not np.all(np.isfinite(tensor)):
        raise ValueError("inertia must be finite")
    scale = float(np.max(np.abs(tensor)))
    asymmetry = float(np.max(np.abs(tensor - tensor.T)))
    if asymmetry > SYMMETRY_TOLERANCE * scale:
        raise ValueError(f"inertia must be symmetric; entries differ from their transposes by up to {asymmetry:g} "
                         f"(largest entry {scale:g})")
    tensor = 0.5 * (tensor + tensor.T)
    moments = np.linalg.eigvalsh(tensor)  # ascending
    if not moments[0] > 0:
        raise ValueError(f"inertia must be positive definite; its principal moments are {moments.tolist()}")
    if moments[0] + moments[1] < moments[2] * (1.0 - TRIANGLE_TOLERANCE):
        raise ValueError(f"inertia's principal moments {moments.tolist()} break the triangle inequality "
                         f"I1 + I2 >= I3 that every rigid body's satisfy")
    return _stored("inertia", tensor)


def _stored(name: str, tensor: np.ndarray) -> np.ndarray:
    """The storage precision's range rule (validate.representable) for an inertia tensor:
    entries up to its largest number, principal moments also above its smallest normal one
    (flushed to 0, a moment would make the tensor singular); off-diagonal entries may be
    round-off of any size."""
    validate.representable(name, tensor, underflow=False)
    validate.representable(f"{name}'s principal moments", np.linalg.eigvalsh(tensor))
    return tensor
