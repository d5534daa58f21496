"""Validated scenes: bodies in, checked shapes, topologies and packed arrays out.

:mod:`.bodies` checks input and finds each distinct mesh, :mod:`.topology` derives edges and
closedness per distinct face array, :mod:`.normals` the normals of a pose, :mod:`.clusters` the
culling units of the focused passes, and :mod:`.pack` lays a scene out for the whole-scene passes.
"""

from ..errors import DegenerateFaceWarning, OpenMeshWarning
from .bodies import Scene, Shape, ShapeCache, body_label, check_transforms, check_vertices
from .clusters import CLUSTER_FACES, Clusters
from .pack import PackedScene, pack, repack
from .prepared import PreparedBodies, prepare_scene
from .topology import Topology, TopologyCache, build_topology

__all__ = [
    "CLUSTER_FACES", "Clusters", "DegenerateFaceWarning", "OpenMeshWarning", "PackedScene",
    "PreparedBodies", "Scene", "Shape", "ShapeCache", "Topology", "TopologyCache", "body_label",
    "build_topology", "check_transforms", "check_vertices", "pack", "prepare_scene", "repack",
]
