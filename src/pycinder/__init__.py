"""pycinder: CInDeR image-space collision detection on the GPU through WebGPU.

>>> import trimesh, pycinder
>>> a = trimesh.creation.box((1, 1, 1))
>>> b = trimesh.creation.icosphere(radius=0.4)
>>> b.apply_translation((0.6, 0, 0))
>>> pycinder.find_collisions([a, b]).pairs
array([[0, 1]])
"""

from .detector import ClippedBodyWarning, Detector, find_collisions
from .gpu.device import NoAdapterError
from .manager import CollisionManager
from .result import RECORD_DTYPE, CollisionResult, Stats
from .scene import MAX_BODIES, DegenerateFaceWarning, OpenMeshWarning
from .view import View

__version__ = "0.1.0"

__all__ = [
    "MAX_BODIES", "RECORD_DTYPE", "ClippedBodyWarning", "CollisionManager", "CollisionResult", "DegenerateFaceWarning",
    "Detector", "NoAdapterError", "OpenMeshWarning", "Stats", "View", "find_collisions",
]
