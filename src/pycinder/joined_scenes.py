"""Many small scenes in one query: the scenes joined into one, a key that keeps pairs within a
scene, and the result split back per scene (:meth:`pycinder.Detector.find_collisions_batch`).

    scenes (bodies, transforms) -> one validated scene, a scene key and a tolerance per body
      -> the focused strategy (broad phase within each scene, tiles, passes: one submission)
      -> per scene: its pairs and records, with body indices local to it

A query has a floor of a few milliseconds however small it is (a submission, a readback, host work
per stage). A batch pays it once for all its scenes. Each scene keeps its own answer: the broad
phase pairs only bodies of one scene (:func:`pycinder.focused.broad.broad_numpy.side_by_side`), and
every pair gets its scene's tolerance, so a scene's pairs are those a query of that scene alone
gives.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .request import CollisionRequest
from .result import CollisionResult, Stats
from .scene import Scene, ShapeCache, prepare_scene


def scene_tolerances(tolerance: Any, count: int, labels: Sequence[Any]) -> np.ndarray:
    """(S,) tolerance of each scene, NaN where the detector's own applies.

    Parameters
    ----------
    tolerance : None, float, or sequence of (float or None)
        One for all scenes, or one per scene.
    count : int
        Number of scenes.
    labels : sequence
        Scene labels for messages.
    """
    if tolerance is None or np.ndim(tolerance) == 0:
        tolerance = [tolerance] * count
    tolerance = list(tolerance)
    if len(tolerance) != count:
        raise ValueError(f"tolerance must be one number or one per scene: {len(tolerance)} "
                         f"given for {count} scenes")
    out = np.full(count, np.nan)
    for s, t in enumerate(tolerance):
        if t is None:
            continue
        try:
            out[s] = CollisionRequest(tolerance=t).tolerance
        except ValueError as exc:
            raise ValueError(f"scene {labels[s]}: {exc}") from None
    return out


def _unpack(scene: Any, label: Any) -> tuple[list, Any, list | None]:
    """(bodies, transforms, names) of one scene given as a pair or a triple."""
    if not isinstance(scene, (tuple, list)) or len(scene) not in (2, 3):
        raise TypeError(f"scene {label}: expected (bodies, transforms) or "
                        f"(bodies, transforms, names), got {type(scene).__name__}")
    bodies = list(scene[0])
    names = list(scene[2]) if len(scene) == 3 and scene[2] is not None else None
    if names is not None and len(names) != len(bodies):
        raise ValueError(f"scene {label}: {len(names)} names for {len(bodies)} bodies")
    return bodies, scene[1], names


def _transforms(transforms: Any, n: int, label: Any) -> np.ndarray:
    if transforms is None:
        return np.tile(np.eye(4), (n, 1, 1))
    t = np.asarray(transforms, dtype=np.float64)
    if t.shape != (n, 4, 4):
        raise ValueError(f"scene {label}: transforms must have shape ({n}, 4, 4) for its {n} "
                         f"bodies, got {t.shape}")
    return t


@dataclass
class JoinedScenes:
    """Scenes joined into one for a query.

    Attributes
    ----------
    scene : Scene
        The validated bodies of every scene, scene after scene.
    key : (N,) int
        The scene of each body: the broad phase pairs only bodies of one scene.
    body_tolerances : (N,) float
        The tolerance of each body's scene; NaN where the detector's own applies.
    counts : (S,) int
        Bodies per scene.
    names : list of (list or None)
        Each scene's own body names, as given.
    """

    scene: Scene
    key: np.ndarray
    body_tolerances: np.ndarray
    counts: np.ndarray
    names: list[list | None]


def join_scenes(scenes: Sequence[Any], labels: Sequence[Any] | None, tolerance: Any, *,
                strict: bool, cache: ShapeCache, max_bodies: int) -> JoinedScenes:
    """Validate ``scenes`` (each ``(bodies, transforms)`` or ``(bodies, transforms, names)``) as
    one scene.

    Parameters
    ----------
    scenes : sequence
    labels : sequence, optional
        Scene labels for messages (default: the scenes' positions).
    tolerance : None, float, or sequence of (float or None)
        One for every scene or one per scene.
    strict : bool
    cache : ShapeCache
    max_bodies : int
        As the detector's request says.
    """
    scenes = list(scenes)
    labels = list(range(len(scenes))) if labels is None else list(labels)
    if len(labels) != len(scenes):
        raise ValueError(f"{len(labels)} labels for {len(scenes)} scenes")
    tol = scene_tolerances(tolerance, len(scenes), labels)
    bodies: list = []
    transforms: list[np.ndarray] = []
    names: list[str] = []
    counts = np.zeros(len(scenes), dtype=np.int64)
    local_names: list[list | None] = []
    for s, (scene, label) in enumerate(zip(scenes, labels)):
        b, t, n = _unpack(scene, label)
        counts[s] = len(b)
        bodies += b
        transforms.append(_transforms(t, len(b), label))
        local_names.append(n)
        names += [f"scene {label}: {n[j] if n is not None and n[j] is not None else f'body {j}'}"
                  for j in range(len(b))]
    key = np.repeat(np.arange(len(scenes)), counts)
    joined = prepare_scene(bodies, np.concatenate(transforms) if bodies else None, names=names,
                           strict=strict, cache=cache, max_bodies=max_bodies)
    return JoinedScenes(joined, key, tol[key], counts, local_names)


FIGURES = ("distances", "distance_errors", "depths", "depth_errors")
"""Per-pair figures of a result (a clearance or a hard-clash query), cut with its pairs."""


def split(result: CollisionResult, scenes: JoinedScenes) -> list[CollisionResult]:
    """The result of a batch, one per scene, with the scene's own body indices."""
    joined, counts, names = scenes.scene, scenes.counts, scenes.names
    first = np.concatenate([[0], np.cumsum(counts)])
    key = np.repeat(np.arange(len(counts)), counts)
    # Pairs are sorted by their first body, and scenes are contiguous: they come in scene order.
    pair_cut = np.searchsorted(key[result.pairs[:, 0]], np.arange(len(counts) + 1))
    rec = result.records
    order = np.argsort(key[rec["penetrating"]], kind="stable")
    rec = rec[order]
    rec_cut = np.searchsorted(key[rec["penetrating"]], np.arange(len(counts) + 1))
    out = []
    for s in range(len(counts)):
        a, b = first[s], first[s + 1]
        part = rec[rec_cut[s]:rec_cut[s + 1]].copy()
        part["penetrating"] -= a
        part["penetrated"] -= a
        n = names[s] if names[s] is not None else [None] * int(counts[s])
        scene = Scene(joined.shapes, joined.body_shape[a:b], joined.transforms[a:b], list(n))
        stats = _copy_stats(result.stats)
        stats.bodies, stats.records = int(counts[s]), len(part)
        one = CollisionResult(result.pairs[pair_cut[s]:pair_cut[s + 1]] - a, part, stats,
                              tiles=result.tiles, scene=scene, records_kept=result.records_kept)
        cut = slice(pair_cut[s], pair_cut[s + 1])
        for name in FIGURES:
            figures = getattr(result, name)
            if figures is not None:
                setattr(one, name, figures[cut])
        measured = result.measured_contacts
        if measured is not None:
            mine = measured.select(key[measured.pair[:, 0]] == s)
            mine.pair = mine.pair - a
            one.measured_contacts = mine
        out.append(one)
    return out


def _copy_stats(stats: Stats) -> Stats:
    """A copy of a batch's stats for one of its scenes: its own dicts and strategy part (a deep
    copy costs about 0.35 ms, which a batch of thousands of scenes pays per scene)."""
    out = copy.copy(stats)
    out.wall_ms, out.gpu_ms = dict(stats.wall_ms), dict(stats.gpu_ms)
    object.__setattr__(out, "detail", copy.copy(stats.detail))
    return out
