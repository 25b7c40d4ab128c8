"""tai_coll: particles colliding with shapes, on Taichi, on the CPU and on GPUs.

    import tai_coll as tc
    tc.init(arch="cpu")
    scene = tc.Scene(dt=1/600, substeps=10)
    scene.add_collider(tc.Plane(point=(0, 0, 0), normal=(0, 1, 0)),
                       material=tc.Material(restitution=0.5, friction=0.3))
    scene.add_particles(positions=np.random.rand(1000, 3), radius=0.005)
    scene.step(frames=10)

Importing this package never touches a GPU or Vulkan; `tc.init()` (or first use) starts Taichi.
"""

from . import params
from .bodies import Body, MassProperties, mass_properties
from .errors import SimulationError
from .export import UsdRecorder
from .geometry import Box, Capsule, Collider, Cylinder, Plane, Sphere, rotation_matrix
from .geometry import HeightField, TriangleMesh
from .geometry.implicit import Implicit
from .geometry.mesh_sdf import MeshSDF, bake_mesh
from .materials import Material
from .response import collide, collide_pair
from .response.repulsion import RepulsionField
from .runtime import RuntimeInfo, init
from .scene.emitters import Emitter
from .scene.scene import Scene
from .solvers import ImpulseSolver, PenaltySolver, Solver
from .solvers.pairs import PairSettings, ParticleCollisions
from .sweeps import sweep

__version__ = "0.1.0"

__all__ = [
    "Body", "Box", "Capsule", "Collider", "Cylinder", "ImpulseSolver", "Material", "PairSettings", "ParticleCollisions",
    "PenaltySolver", "Plane", "RepulsionField", "RuntimeInfo", "Scene", "SimulationError", "Solver", "Sphere",
    "collide", "collide_pair", "init", "params", "rotation_matrix",
    "HeightField", "TriangleMesh",
    "Implicit", "MeshSDF", "bake_mesh",
    "MassProperties", "mass_properties",
    "Emitter", "UsdRecorder",
    "sweep",
]
