"""pycinder: CInDeR image-space collision detection on the GPU through WebGPU.

>>> import trimesh, pycinder
>>> a = trimesh.creation.box((1, 1, 1))
>>> b = trimesh.creation.icosphere(radius=0.4).apply_translation((0.6, 0, 0))
>>> pycinder.find_collisions([a, b]).pairs
array([[0, 1]])
"""

from .contacts import Contacts
from .detector import Detector, find_collisions
from .errors import (ClippedBodyWarning, DegenerateFaceWarning, LossWarning, MeshWarning,
                     OpenMeshWarning, RewoundMeshWarning)
from .gpu.device import ForkedProcessError, NoAdapterError, share_default_device
from .manager import CollisionManager, ContactData, DistanceData, scene_to_collision
from .records import RECORD_DTYPE
from .request import MAX_BODIES, CollisionRequest
from .result import CollisionResult, FocusedStats, SceneStats, Stats
from .scene import PreparedBodies
from .tolerance import DEFAULT_RELATIVE_TOLERANCE
from .util import moved
from .util.quiet import quiet_native_probes
from .view import View

quiet_native_probes()  # before the first query makes wgpu's instance

MOVED = {
    "pycinder.ifc": "pycinder.bim.ifc",
    "pycinder.bcf": "pycinder.bim.bcf",
    "pycinder.clearance": "pycinder.focused.modes.clearance",
    "pycinder.hardclash": "pycinder.focused.modes.hardclash",
}
"""Public modules that moved (earlier name -> where they live now): the earlier names still import
the same modules (:mod:`pycinder.util.moved`)."""
moved.install(MOVED)


def __getattr__(name: str) -> object:
    return moved.attribute(__name__, MOVED, name)


__version__ = "0.3.0"

__all__ = [
    "DEFAULT_RELATIVE_TOLERANCE", "MAX_BODIES", "RECORD_DTYPE", "ClippedBodyWarning",
    "CollisionManager", "CollisionRequest", "CollisionResult", "ContactData", "Contacts",
    "DegenerateFaceWarning", "DistanceData",
    "Detector", "FocusedStats", "ForkedProcessError", "LossWarning", "MeshWarning",
    "NoAdapterError", "OpenMeshWarning", "PreparedBodies", "RewoundMeshWarning", "SceneStats",
    "Stats", "View",
    "find_collisions", "scene_to_collision", "share_default_device",
]
