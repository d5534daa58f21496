"""Many small scenes in one query (:func:`find_collisions_batch`): the scenes are joined into
one, the broad phase pairs only bodies of one scene, and the result is split back per scene
(:mod:`pycinder.joined_scenes`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ..detector import Detector
    from ..result import CollisionResult


def find_collisions_batch(detector: Detector, scenes: Sequence[Any], *, tolerance: Any = None,
                          labels: Sequence[Any] | None = None, records: str | None = None,
                          contacts: bool | None = None) -> list[CollisionResult]:
    """Find the colliding pairs of many scenes in one query.

    Parameters
    ----------
    detector : Detector
        With the focused strategy; its pipelines and shape cache serve the batch.
    scenes : sequence of (bodies, transforms) or (bodies, transforms, names)
        ``bodies``: trimesh meshes or ``(vertices (V, 3), faces (F, 3))`` pairs; ``transforms``:
        (N, 4, 4) world-from-body matrices or None; ``names``: N body names for messages.
    tolerance : None, float, or sequence of (float or None)
        World units, one for every scene or one per scene; None: the detector's.
    labels : sequence, optional
        Scene labels for messages (default: the scenes' positions).
    records : {"found", "all", "none"}, optional
        The records kept for this call (default: the detector's request's).
    contacts : bool, optional
        True: each scene's result keeps what its contacts are reduced from (every record), and
        ``result.contacts()`` gives them. Default: the detector's request's.

    Returns
    -------
    list of CollisionResult
        One per scene, in order. ``pairs`` and the records' bodies are indices into the
        scene's own bodies; ``scene`` is the scene alone, ``tiles`` the batch's plan (which
        ``records["view"]`` indexes). ``stats`` counts the whole query (one per batch), except
        ``bodies`` and ``records``, which are the scene's.

    Notes
    -----
    The same as ``detector.find_collisions_batch(scenes, ...)``: the batch is submitted and
    finished by the detector as a single query is, with the scenes joined into one and a key per
    body that keeps pairs within a scene.
    """
    return detector.find_collisions_batch(scenes, tolerance=tolerance, labels=labels,
                                          records=records, contacts=contacts)
