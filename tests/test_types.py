"""The package is typed: py.typed ships, and every CollisionManager overload's return annotation
describes what the method returns (tuples, sets, ContactData and DistanceData, as trimesh's)."""

import types
import typing
from importlib import resources
from typing import Any, Literal, Union, get_args, get_origin

import numpy as np
import pytest
import trimesh

from pycinder import CollisionManager, manager as manager_module


def conforms(value: Any, hint: Any) -> bool:
    """Whether ``value`` is an instance of the type ``hint`` (unions, tuples, sets, lists)."""
    origin, args = get_origin(hint), get_args(hint)
    if hint is Any:
        return True
    if hint is type(None) or hint is None:
        return value is None
    if origin in (Union, types.UnionType):
        return any(conforms(value, a) for a in args)
    if origin is tuple:
        return isinstance(value, tuple) and len(value) == len(args) and \
            all(conforms(v, a) for v, a in zip(value, args))
    if origin in (set, list):
        return isinstance(value, origin) and all(conforms(v, args[0]) for v in value)
    if hint is float:
        return isinstance(value, float)
    return isinstance(value, hint)


def test_the_checker_rejects_wrong_types():
    assert conforms((True, {("a", "b")}), tuple[bool, set[tuple[str, str]]])
    assert not conforms(True, tuple[bool, set[str]])
    assert not conforms((True, [("a", "b")]), tuple[bool, set[tuple[str, str]]])
    assert not conforms((1.0, ("a", None)), manager_module.DistanceAnswer[manager_module.NamePair])


def test_py_typed_ships():
    assert resources.files("pycinder").joinpath("py.typed").is_file()


def overload_for(method, names_kw: str, names: bool, data: bool):
    """The overload of ``method`` selected by these two keywords, and its resolved hints."""
    for fn in typing.get_overloads(method):
        hints = typing.get_type_hints(fn)
        if hints[names_kw] == Literal[names] and hints["return_data"] == Literal[data]:
            return hints["return"]
    raise AssertionError(f"no overload of {method.__name__} for {names_kw}={names}, "
                         f"return_data={data}")


CALLS = [
    ("in_collision_internal", "return_names", lambda m, probe, other: ((), {})),
    ("in_collision_single", "return_names", lambda m, probe, other: ((probe, np.eye(4)), {})),
    ("in_collision_other", "return_names", lambda m, probe, other: ((other,), {})),
    ("min_distance_internal", "return_names", lambda m, probe, other: ((), {})),
    ("min_distance_single", "return_name", lambda m, probe, other: ((probe,), {})),
    ("min_distance_other", "return_names", lambda m, probe, other: ((other,), {})),
]


@pytest.mark.parametrize("touching", [True, False])
def test_every_overload_describes_what_comes_back(touching):
    box = trimesh.creation.box((1, 1, 1))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.4)
    place = trimesh.transformations.translation_matrix((0.6 if touching else 3.0, 0, 0))
    m = CollisionManager()
    m.add_object("box", box)
    m.add_object("ball", ball, place)
    other = CollisionManager()
    other.add_object("probe", ball, place)
    probe = ball.copy().apply_transform(place)
    for name, names_kw, args in CALLS:
        method = getattr(CollisionManager, name)
        positional, _ = args(m, probe, other)
        for names in (False, True):
            for data in (False, True):
                hint = overload_for(method, names_kw, names, data)
                value = getattr(m, name)(*positional, **{names_kw: names, "return_data": data})
                assert conforms(value, hint), (name, names, data, value, hint)
                # the general signature's annotation holds as well
                general = typing.get_type_hints(method)["return"]
                assert conforms(value, general), (name, general)
