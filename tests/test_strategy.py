"""The one interface both strategies give the detector (:mod:`pycinder.strategy`): each takes
``submit(scene, stats, query)`` and gives a pending query, and says what it cannot be asked in its
``REFUSED``; the detector raises those errors without asking which strategy it holds."""

import inspect

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.detector import STRATEGIES
from pycinder.strategy import Done, Query, refuse

OPTIONS = {"view", "pairs", "batch", "scenes"}
"""What a call may ask that a strategy can refuse (the detector asks each by this name)."""


def test_every_strategy_is_found_by_its_request_name_and_submits_the_same_way():
    assert set(STRATEGIES) == {"focused", "scene"}
    for name, strategy in STRATEGIES.items():
        pycinder.CollisionRequest(strategy=name)  # a name the request accepts
        assert set(strategy.REFUSED) <= OPTIONS, name
        assert list(inspect.signature(strategy.submit).parameters) == [
            "self", "scene", "stats", "query"], name
        assert all(isinstance(m, str) and "strategy" in m for m in strategy.REFUSED.values())
    # Between them the strategies refuse every option one of them cannot take, and no option is
    # refused by both (each is a real choice of strategy).
    refused = [set(s.REFUSED) for s in STRATEGIES.values()]
    assert set.union(*refused) == OPTIONS and not set.intersection(*refused)


def test_refuse_raises_the_strategys_own_message_and_nothing_for_what_it_takes():
    focused, scene = (object.__new__(STRATEGIES[k]) for k in ("focused", "scene"))
    with pytest.raises(ValueError, match="view applies to strategy='scene'"):
        refuse(focused, "view")
    refuse(focused, "pairs")
    refuse(scene, "view")
    with pytest.raises(ValueError, match="pairs applies to strategy='focused'"):
        refuse(scene, "pairs")


def test_a_query_holds_what_one_call_asks_and_a_done_query_is_ready():
    query = Query()
    assert (query.groups, query.records, query.within, query.body_tolerances, query.view,
            query.stop_at_first) == (None, None, None, None, None, False)
    with pytest.raises(AttributeError):
        query.records = "all"  # frozen: a query is what the call asked
    done = Done("result")
    assert done.ready and done.result() == "result"


def _overlapping() -> tuple[list[trimesh.Trimesh], list[np.ndarray]]:
    box = trimesh.creation.box((1, 1, 1))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.4)
    return [box, ball], [np.eye(4), trimesh.transformations.translation_matrix((0.6, 0, 0))]


@pytest.mark.parametrize("strategy", ["focused", "scene"])
def test_both_strategies_answer_through_the_one_path(strategy):
    """The same calls on either strategy: a query, a submitted query, whether anything collides,
    and the options the other strategy takes refused with its message."""
    meshes, transforms = _overlapping()
    options = {"resolution": 256} if strategy == "scene" else {}
    det = pycinder.Detector(strategy=strategy, **options)
    assert det.find_collisions(meshes, transforms).pairs.tolist() == [[0, 1]]
    pending = det.submit(meshes, transforms)
    assert pending.result().pairs.tolist() == [[0, 1]] and pending.ready
    assert det.in_collision(meshes, transforms)
    far = [transforms[0], trimesh.transformations.translation_matrix((5, 0, 0))]
    assert not det.in_collision(meshes, far)
    if strategy == "focused":
        with pytest.raises(ValueError, match="view applies to strategy='scene'"):
            det.find_collisions(meshes, transforms, view=object())
    else:
        with pytest.raises(ValueError, match="pairs applies to strategy='focused'"):
            det.find_collisions(meshes, transforms, pairs=[[0, 1]])
        with pytest.raises(ValueError, match="find_collisions_batch needs strategy='focused'"):
            det.find_collisions_batch([(meshes, transforms)])
