"""Regenerate ``src/pycinder/data/bunny.npz``, the sample bunny the package ships.

The source is the closed Stanford bunny (Stanford 3D Scanning Repository) as bundled with
pymeshlab's sample meshes (56,172 triangles). It is decimated by quadric edge collapse to about
3,500 triangles, so that two Loop subdivisions (``pycinder.testing.bunny(subdivisions=2)``) give
back about the original's 56k. Only this script needs pymeshlab:

    pip install pymeshlab && python scripts/make_bunny.py
"""

from pathlib import Path

import numpy as np
import pymeshlab
import trimesh

TARGET_FACES = 3512
OUT = Path(__file__).resolve().parents[1] / "src" / "pycinder" / "data" / "bunny.npz"


def main() -> None:
    source = Path(pymeshlab.__file__).parent / "tests" / "sample_meshes" / "bunny.obj"
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(source))
    ms.meshing_decimation_quadric_edge_collapse(targetfacenum=TARGET_FACES, preservetopology=True,
                                                preservenormal=True, qualitythr=0.5,
                                                optimalplacement=True)
    m = ms.current_mesh()
    vertices = np.asarray(m.vertex_matrix(), np.float32)
    faces = np.asarray(m.face_matrix())
    mesh = trimesh.Trimesh(vertices.astype(np.float64), faces, process=True)
    if not (mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0):
        raise SystemExit("the decimated bunny is not a closed, outward-wound solid")
    assert len(mesh.vertices) < 2**16
    np.savez_compressed(OUT, vertices=np.asarray(mesh.vertices, np.float32),
                        faces=np.asarray(mesh.faces, np.uint16))
    print(f"wrote {OUT}: {len(mesh.vertices)} vertices, {len(mesh.faces)} faces, "
          f"{OUT.stat().st_size} bytes")


if __name__ == "__main__":
    main()
