"""Winding: a closed mesh whose faces are wound inconsistently, wound again so that it bounds a
solid.

Exporters often write closed meshes whose faces do not all turn the same way (Revit's IFC
ceilings and stairs among them). Such a mesh is closed, every edge shared by two faces, but its
inside is not defined by the faces as given, so it could only be tested as a surface. Here it is
wound again in two steps:

1. **Consistently** (:func:`consistent_flips`, faces alone): a walk over each connected part's
   faces, across shared edges, turns every face the way its first face turns, so that each edge is
   walked once each way. A part that cannot be wound consistently (a one-sided surface, which no
   closed mesh in space is without crossing itself) is left as it was.
2. **Outward** (:func:`outward_flips`, with the vertices): each part is then turned as a whole so
   that its volume is positive. Parts of exported elements overlap more often than they nest (a
   family of overlapping boxes), and a mesh wound inconsistently says nothing of which way a
   part was meant: a part inside another is a solid too, never a cavity, so that its inside is
   found, never missed.

Both steps flip faces (reverse their corners), never move or drop one: face ``k`` of the mesh
wound again is face ``k`` as given, so records and contacts name the same faces.
"""

from __future__ import annotations

from collections import deque

import numpy as np

__all__ = ["consistent_flips", "outward_flips", "flip_faces"]


def consistent_flips(faces: np.ndarray, edge_faces: np.ndarray) -> tuple[np.ndarray, np.ndarray
                                                                        ] | None:
    """Which faces to flip so that a closed two-manifold mesh is wound consistently.

    Parameters
    ----------
    faces : (F, 3) int
        The faces, every undirected edge used by exactly two of them.
    edge_faces : (3 F,) int
        The unique edge of each directed face edge (face-major order: face ``k``'s edges are
        ``3 k``, ``3 k + 1``, ``3 k + 2``, from corner 0 to 1, 1 to 2 and 2 to 0).

    Returns
    -------
    flip : (F,) bool
        Faces to turn the other way.
    part : (F,) int64
        Each face's connected part (0, 1, ...), in the order of the parts' first faces.
    None
        Where some part cannot be wound consistently.
    """
    f = len(faces)
    order = np.argsort(edge_faces, kind="stable")
    first, second = order[0::2], order[1::2]  # the two directed edges of each undirected one
    if len(first) != len(second) or np.any(edge_faces[first] != edge_faces[second]):
        raise ValueError("consistent_flips needs every edge used by exactly two faces")
    start = faces.reshape(-1)  # corner k of face j starts directed edge 3 j + k
    # Two faces walking their shared edge the same way must turn opposite ways.
    opposed = start[first] == start[second]
    fa, fb = first // 3, second // 3
    ends = np.concatenate([fa, fb])
    others = np.concatenate([fb, fa])
    differ = np.concatenate([opposed, opposed])
    by_face = np.argsort(ends, kind="stable")
    offsets = np.searchsorted(ends[by_face], np.arange(f + 1))
    neighbour, change = others[by_face].tolist(), differ[by_face].tolist()
    offsets_list = offsets.tolist()
    flip = np.full(f, -1, np.int8)
    part = np.full(f, -1, np.int64)
    state, label = flip.tolist(), part.tolist()
    parts = 0
    for seed in range(f):
        if state[seed] >= 0:
            continue
        state[seed], label[seed] = 0, parts
        queue = deque([seed])
        while queue:
            j = queue.popleft()
            for e in range(offsets_list[j], offsets_list[j + 1]):
                k = neighbour[e]
                want = state[j] ^ change[e]
                if state[k] < 0:
                    state[k], label[k] = want, parts
                    queue.append(k)
                elif state[k] != want:
                    return None  # one-sided
        parts += 1
    return np.array(state, bool), np.array(label, np.int64)


def flip_faces(faces: np.ndarray, edge_faces: np.ndarray, which: np.ndarray) -> None:
    """Reverse faces ``which`` (F,) bool in place: ``faces`` (F, 3) and their directed edges'
    unique edges ``edge_faces`` (3 F,) (corners ``a b c`` become ``c b a``, so edges 0, 1, 2
    become the old 1, 0, 2)."""
    rows = np.flatnonzero(which)
    if len(rows) == 0:
        return
    faces[rows] = faces[rows][:, ::-1]
    e = edge_faces.reshape(-1, 3)
    e[rows] = e[rows][:, [1, 0, 2]]


def outward_flips(vertices: np.ndarray, faces: np.ndarray, part: np.ndarray) -> np.ndarray:
    """Which faces to flip so that each part of a consistently wound closed mesh faces out (its
    volume positive).

    Parameters
    ----------
    vertices : (V, 3) float
    faces : (F, 3) int
        Wound consistently within each part.
    part : (F,) int64
        Each face's part (:func:`consistent_flips`).

    Returns
    -------
    (F,) bool
    """
    tri = np.asarray(vertices, np.float64)[faces]
    tri = tri - tri.reshape(-1, 3).mean(axis=0)
    volume = np.zeros(int(part.max()) + 1 if len(part) else 0)
    np.add.at(volume, part, np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])))
    return (volume < 0)[part]
