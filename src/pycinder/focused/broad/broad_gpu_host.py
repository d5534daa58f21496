"""The broad phase's host side: its inputs checked and packed as :data:`BODY` rows, the NumPy
reference it reproduces, and the sweeps the GPU left unfinished, finished on the host."""

from __future__ import annotations

import numpy as np

from ...scene.bodies import world_boxes
from .broad_common import BODY, COORDINATE_LIMIT, MAX_KEY
from .broad_numpy import sweep_and_prune

HOST_CHUNK = 1 << 22
"""Box tests per NumPy step when the host finishes unfinished sweeps."""


def reference_pairs(local_lo: np.ndarray, local_hi: np.ndarray, radius: np.ndarray,
                    transforms: np.ndarray, within: np.ndarray | None = None,
                    groups: np.ndarray | None = None) -> np.ndarray:
    """The NumPy broad phase that :class:`~pycinder.focused.broad.GpuBroadPhase` reproduces (same
    arguments): world boxes, sweep and prune, then the pairs of different groups.

    Returns
    -------
    (K, 2) int64
        Sorted pairs ``(i, j)``, ``i < j``.
    """
    lo, hi = world_boxes(local_lo, local_hi, radius, transforms)
    return sweep_and_prune(lo, hi, within, groups)


def in_range(local_lo: np.ndarray, local_hi: np.ndarray, radius: np.ndarray,
             transforms: np.ndarray) -> bool:
    """Whether :meth:`~pycinder.focused.broad.GpuBroadPhase.pairs` takes these bodies: every box,
    radius and transform entry (translations from the scene's centre) within
    :data:`COORDINATE_LIMIT`. (The rest of pycinder takes bodies up to 1e30 units; the NumPy
    broad phase serves those.)"""
    translation = transforms[:, :3, 3]
    origin = 0.5 * (translation.min(axis=0) + translation.max(axis=0))
    largest = max(float(np.abs(transforms[:, :3, :3]).max(initial=0.0)),
                  float(np.abs(translation - origin).max(initial=0.0)),
                  float(np.abs(local_lo).max(initial=0.0)),
                  float(np.abs(local_hi).max(initial=0.0)),
                  float(np.abs(radius).max(initial=0.0)))
    return largest <= COORDINATE_LIMIT


def ranks(keys: np.ndarray | None, name: str, n: int) -> np.ndarray:
    """Integer keys as (n,) uint32 ranks that keep equality (0 where none are given)."""
    if keys is None:
        return np.zeros(n, dtype=np.uint32)
    k = np.asarray(keys)
    if k.shape != (n,) or not (np.issubdtype(k.dtype, np.integer) or k.dtype == bool):
        raise ValueError(f"{name} must be ({n},) integers, one per body; got {k.dtype} "
                         f"{k.shape}")
    if n == 0:
        return np.zeros(0, dtype=np.uint32)
    k = k.astype(np.int64)
    low = int(k.min())
    if int(k.max()) - low <= MAX_KEY:
        return (k - low).astype(np.uint32)
    return np.unique(k, return_inverse=True)[1].reshape(-1).astype(np.uint32)


def checked(local_lo: np.ndarray, local_hi: np.ndarray, radius: np.ndarray,
            transforms: np.ndarray) -> tuple[np.ndarray, ...]:
    """The inputs as float64 arrays of agreeing shapes ((N, 3), (N, 3), (N,), (N, 4, 4)); a
    clear error naming the first bad body otherwise (values that are not finite are looked for
    by :func:`packed`)."""
    lo = np.asarray(local_lo, dtype=np.float64)
    hi = np.asarray(local_hi, dtype=np.float64)
    r = np.asarray(radius, dtype=np.float64)
    t = np.asarray(transforms, dtype=np.float64)
    n = len(r) if r.ndim == 1 else -1
    for name, a, shape in (("radius", r, (n,)), ("local_lo", lo, (n, 3)),
                           ("local_hi", hi, (n, 3)), ("transforms", t, (n, 4, 4))):
        if n < 0 or a.shape != shape:
            raise ValueError(f"{name} must have shape {shape if n >= 0 else '(N,)'}, got "
                             f"{a.shape}")
    negative = r < 0
    if negative.any():
        raise ValueError(f"radius of body {int(np.flatnonzero(negative)[0])} is negative")
    empty = (lo > hi).any(axis=1)
    if empty.any():
        raise ValueError(f"local box of body {int(np.flatnonzero(empty)[0])} is empty "
                         "(local_lo above local_hi)")
    return lo, hi, r, t


def packed(lo: np.ndarray, hi: np.ndarray, r: np.ndarray, t: np.ndarray,
           within_keys: np.ndarray, group_keys: np.ndarray) -> tuple[np.ndarray, int, np.ndarray]:
    """The bodies as pass B1 reads them, the sweep axis and the origin.

    Returns
    -------
    bodies : (N,) BODY
        Transform rows (translation less the origin, subtracted in float64), local box, radius,
        keys.
    axis : int
        The axis along which the translations spread most.
    origin : (3,) float64
        The midpoint of the translations' range.
    """
    n = len(r)
    translation = t[:, :3, 3]
    origin = 0.5 * (translation.min(axis=0) + translation.max(axis=0))
    rows = t[:, :3, :].astype(np.float32)
    rows[:, :, 3] = translation - origin
    box = np.empty((n, 7), dtype=np.float32)  # lo, radius, hi: as float32, checked together
    box[:, :3], box[:, 3], box[:, 4:] = lo, r, hi
    bad = ~((np.abs(rows.reshape(n, 12)) <= COORDINATE_LIMIT).all(axis=1)  # NaN too
            & (np.abs(box) <= COORDINATE_LIMIT).all(axis=1))
    if bad.any():
        for name, a in (("transforms", t), ("local_lo", lo), ("local_hi", hi), ("radius", r)):
            finite = np.isfinite(a).reshape(n, -1).all(axis=1)
            if not finite.all():
                raise ValueError(f"{name} of body {int(np.flatnonzero(~finite)[0])} is not "
                                 "finite")
        raise ValueError(f"box or transform of body {int(np.flatnonzero(bad)[0])} has "
                         f"coordinates beyond {COORDINATE_LIMIT:g} (from the scene's centre): "
                         "too large for the float32 broad phase")
    bodies = BODY.zeros(n)
    bodies["rows"], bodies["lo"], bodies["radius"], bodies["hi"] = \
        rows, box[:, :3], box[:, 3], box[:, 4:]
    bodies["within"], bodies["group"] = within_keys, group_keys
    axis = int(np.argmax(translation.var(axis=0)))
    return bodies, axis, origin


def finish_sweeps(which: np.ndarray, lo: np.ndarray, hi: np.ndarray, body: np.ndarray,
                  use_groups: bool) -> np.ndarray:
    """All the pairs of the sorted boxes ``which`` (whose sweeps the GPU left unfinished), from
    the GPU's sorted boxes ``lo``, ``hi`` ((N, 4) float32, ``w``: within key and group bits)
    and their bodies ``body`` ((N,) uint32). Pairs the GPU found too repeat.

    Returns
    -------
    (K, 2) uint32
        Bodies ``(i, j)``, ``i < j``.
    """
    n = len(body)
    within, group = lo[:, 3].view(np.uint32), hi[:, 3].view(np.uint32)
    found = []
    step = max(1, HOST_CHUNK // n)
    for start in range(0, len(which), step):
        p = which[start:start + step]
        meet = (lo[None, :, :3] <= hi[p, None, :3]).all(axis=2) \
            & (lo[p, None, :3] <= hi[None, :, :3]).all(axis=2) \
            & (within[None, :] == within[p, None])
        if use_groups:
            meet &= group[None, :] != group[p, None]
        meet[np.arange(len(p)), p] = False
        i, j = np.nonzero(meet)
        a, b = body[p[i]], body[j]
        found.append(np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1))
    return np.concatenate(found)


__all__ = ["checked", "finish_sweeps", "in_range", "packed", "ranks", "reference_pairs"]
