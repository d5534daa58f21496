"""Start-up: wgpu-py's C types are parsed in one go (``gpu/cffi_types.py``), and they are the very
objects cffi makes when it parses them one by one."""

from __future__ import annotations

import subprocess
import sys

import cffi

from pycinder.gpu import cffi_types

HEADER = """
typedef struct { int x; } A;
typedef struct { float y; A * a; } B;
typedef enum { ONE, TWO } E;
"""


def small_ffi() -> cffi.FFI:
    ffi = cffi.FFI()
    ffi.cdef(HEADER)
    return ffi


NAMES = ("A *", "A * ", "B *", "B[]", "E[]", "char []", "uint8_t *", "intptr_t",
         "void(A *, E, void *)")


def test_preparsed_types_are_the_ones_cffi_makes():
    ffi = small_ffi()
    assert cffi_types.preparse(ffi, NAMES) == len(NAMES)
    cache = ffi._parsed_types
    made = {name: cache[name] for name in NAMES}
    assert made["void(A *, E, void *)"][1] is True  # a function type, as cffi marks it
    assert made["B[]"][0].kind == "array" and made["B[]"][0].item is made["B *"][0].item
    for name in NAMES:
        del cache[name]
        if name.startswith("void("):
            ffi._typeof(name, consider_function_as_funcptr=True)
        else:
            ffi.typeof(name)
        assert cache[name][0] is made[name][0] and cache[name][1] == made[name][1], name
    # and they work: a struct made through a preparsed name
    ffi2 = small_ffi()
    cffi_types.preparse(ffi2, NAMES)
    b = ffi2.new("B *", {"y": 2.5})
    assert b.y == 2.5 and ffi2.typeof(b) is ffi2._parsed_types["B *"][0]
    assert cffi_types.preparse(ffi2, NAMES) == 0  # already there


def test_unknown_names_or_another_cache_leave_cffi_as_it_was():
    ffi = small_ffi()
    before = dict(ffi._parsed_types)
    assert cffi_types.preparse(ffi, NAMES + ("NotAType *",)) == 0
    assert ffi._parsed_types == before

    class Other:
        """An FFI without the cache this relies on."""

    assert cffi_types.preparse(Other(), NAMES) == 0


def test_a_first_query_parses_no_type_one_by_one():
    """In a fresh process, on this wgpu: every listed name is one of its types, and making the
    device, a detector, a query (profiled too), the scene strategy and a manager call parse no
    C type beyond the one combined parse."""
    code = """
from wgpu.backends.wgpu_native import ffi
from pycinder.gpu import cffi_types
parsed = []
original = type(ffi)._typeof_locked
def spy(self, cdecl, *a, **k):
    parsed.append(cdecl)
    return original(self, cdecl, *a, **k)
type(ffi)._typeof_locked = spy
import numpy as np, trimesh, pycinder
box, ball = trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(2, 0.5)
moved = np.eye(4)
moved[0, 3] = 0.95
result = pycinder.Detector().find_collisions([box, ball], [np.eye(4), moved])
assert result.pairs.tolist() == [[0, 1]]
pycinder.Detector(profile=True, records="all").find_collisions([box, ball], [np.eye(4), moved])
pycinder.Detector(strategy="scene").find_collisions([box, ball], [np.eye(4), moved])
manager = pycinder.CollisionManager()
manager.add_object("box", box)
manager.add_object("ball", ball, moved)
assert manager.in_collision_internal()
print(len(cffi_types.TYPES), len(parsed), parsed[0].startswith("void(*)("), parsed[1:])
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    listed, parses, combined, others = out.stdout.split(maxsplit=3)
    assert (parses, combined, others.strip()) == ("1", "True", "[]"), out.stdout

