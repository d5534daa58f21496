"""The one interface both strategies give the detector.

A strategy (:class:`~pycinder.focused.focused_strategy.FocusedStrategy`, the default, or
:class:`~pycinder.wholescene.scene_strategy.WholeSceneStrategy`, the paper's whole-scene image)
takes a validated scene and what one call asks beyond the request (a :class:`Query`), and gives
back a :class:`Pending` query whose :meth:`~Pending.result` finishes it::

    pending = strategy.submit(scene, stats, Query(groups=groups, records="found"))
    result = pending.result()

What a query of a strategy cannot ask for (a view, a list of pairs, a batch of scenes) the strategy
says in :attr:`Strategy.REFUSED` (the option and the error it raises), so that the detector asks
what a strategy does, never which strategy it holds. Per-call records and contacts are the
request's to check (:meth:`~pycinder.CollisionRequest.call_records`); a strategy that keeps its own
records (the scene strategy's) takes none, and one that cannot stop at its first pair runs whole.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

if TYPE_CHECKING:
    from .gpu.device import Gpu
    from .request import CollisionRequest
    from .result import CollisionResult, Stats
    from .scene import Scene
    from .view import View


@dataclass(frozen=True)
class Query:
    """What one call asks of a strategy beyond its request; checked by the detector.

    Attributes
    ----------
    groups : (N,) int, optional
        Only pairs of bodies in different groups are tested.
    records : {"found", "all", "none"}, optional
        The records this call keeps (default: the request's); the focused strategy's.
    within : (N,) int or PairList, optional
        Only pairs of bodies with the same key (a batch's scenes), or only the pairs of a
        :class:`~pycinder.focused.broad.broad_numpy.PairList`.
    body_tolerances : (N,) float, optional
        A tolerance per body (its scene's, in a batch); a pair takes its first body's where it is
        not NaN, the request's ``tolerance`` (or the default) elsewhere.
    stop_at_first : bool
        Only whether anything collides: a strategy may stop at the first pair it finds.
    view : View or sequence of View, optional
        The views to render through (the scene strategy's).
    """

    groups: np.ndarray | None = None
    records: str | None = None
    within: Any = None
    body_tolerances: np.ndarray | None = None
    stop_at_first: bool = False
    view: View | list[View] | None = None


class Pending(Protocol):
    """A query submitted to a strategy."""

    @property
    def ready(self) -> bool:
        """Whether :meth:`result` would not wait for the GPU's first frame."""
        ...

    def result(self) -> CollisionResult:
        """Waits for the query and returns its result."""
        ...


class Strategy(Protocol):
    """How a detector runs its queries."""

    REFUSED: ClassVar[dict[str, str]]
    """What this strategy cannot do: ``"view"``, ``"pairs"``, ``"batch"`` or ``"scenes"`` (many
    scenes in one query) and the message of the ``ValueError`` a call asking for it raises."""

    def __init__(self, gpu: Gpu, request: CollisionRequest) -> None: ...

    def submit(self, scene: Scene, stats: Stats, query: Query) -> Pending:
        """Starts a query of ``scene``; its pending result."""
        ...


class Done:
    """A query answered when it was submitted (the scene strategy's, and empty ones)."""

    ready = True

    def __init__(self, result: CollisionResult) -> None:
        self._result = result

    def result(self) -> CollisionResult:
        """The result, which is already there."""
        return self._result


def refuse(strategy: Strategy, option: str) -> None:
    """Raise the ``ValueError`` a strategy gives for an option it cannot honour (see
    :attr:`Strategy.REFUSED`); nothing where it can."""
    message = type(strategy).REFUSED.get(option)
    if message is not None:
        raise ValueError(message)


__all__ = ["Done", "Pending", "Query", "Strategy", "refuse"]
