#!/usr/bin/env bash
# Checks the wheel a user would install: its files, then a fresh virtual environment of its own
# (the wheel, not an editable install; no source tree on the path), a smoke test there, and the
# examples of the README and the docs run against it.
#
#   scripts/check-wheel.sh PYTHON DIST
#
# PYTHON makes the environment; DIST holds the wheel and the sdist that `python -m build` made.
#
# The wheel holds the library alone: nothing outside `pycinder/` and its dist-info (the
# benchmarks' harness, benchmarks/, runs from a checkout), and it stays under MOST_WHEEL_BYTES.
set -euo pipefail
py=$1
dist=$2
# The wheel of 0.3.0 was 636,647 bytes once the benchmarks' harness left it (708,226 with it);
# the limit leaves about 25% above that.
MOST_WHEEL_BYTES=${MOST_WHEEL_BYTES:-800000}
root=$(cd "$(dirname "$0")/.." && pwd)
wheel=$(ls "$dist"/pycinder-*.whl)
sdist=$(ls "$dist"/pycinder-*.tar.gz)

echo "check-wheel: $(basename "$wheel") and $(basename "$sdist")"
"$py" - "$wheel" "$sdist" "$root/src/pycinder" "$MOST_WHEEL_BYTES" <<'PYEOF'
"""Every shader, the sample data and py.typed are in the wheel, and the sources in the sdist;
the wheel holds nothing but the library, and is no larger than its limit."""
import os, pathlib, sys, tarfile, zipfile

wheel, sdist, src, most = sys.argv[1], sys.argv[2], pathlib.Path(sys.argv[3]), int(sys.argv[4])
in_wheel = set(zipfile.ZipFile(wheel).namelist())
outside = sorted(n for n in in_wheel if n.split("/", 1)[0] != "pycinder"
                 and not (n.startswith("pycinder-") and n.split("/", 1)[0].endswith(".dist-info")))
outside += sorted(n for n in in_wheel if n.startswith("pycinder/benchmarks/"))
if outside:
    sys.exit("check-wheel: outside the library, in the wheel: " + ", ".join(outside))
size = os.path.getsize(wheel)
if size > most:
    sys.exit(f"check-wheel: the wheel is {size:,} bytes, over its limit of {most:,} "
             "(MOST_WHEEL_BYTES in scripts/check-wheel.sh)")
print(f"check-wheel: the wheel holds the library alone, {size:,} bytes (limit {most:,})")
shipped = [p.relative_to(src.parent).as_posix() for pattern in ("shaders/*.wgsl", "data/*.npz",
           "py.typed", "**/*.py") for p in src.glob(pattern)]
missing = sorted(set(shipped) - in_wheel)
in_sdist = {n.split("/", 1)[1] for n in tarfile.open(sdist).getnames() if "/" in n}
missing += sorted(f"sdist: src/{n}" for n in shipped if f"src/{n}" not in in_sdist)
if missing:
    sys.exit("check-wheel: missing from the packages: " + ", ".join(missing))
print(f"check-wheel: {len(shipped)} files of the package in both")
PYEOF

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$py" -m venv "$tmp/venv"
"$tmp/venv/bin/python" -m pip install -q --disable-pip-version-check "$wheel" pytest \
    2> >(grep -v "^WARNING: Location" >&2)

# The examples run from a folder that holds only them: no source tree on the path.
mkdir -p "$tmp/check/tests"
cp -r "$root/README.md" "$root/docs" "$tmp/check/"
rm -rf "$tmp/check/docs/_build"
cp "$root/tests/test_docs_examples.py" "$tmp/check/tests/"
cd "$tmp/check"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"

"$tmp/venv/bin/pycinder" --version
"$tmp/venv/bin/python" - "$tmp/venv" <<'PYEOF'
"""Smoke test: the installed package, its shaders and sample data, and one query."""
import pathlib, sys

import pycinder
from pycinder.gpu.device import shader_source
from pycinder.testing import bunny

where = pathlib.Path(pycinder.__file__).resolve()
venv = pathlib.Path(sys.argv[1]).resolve()
assert venv in where.parents, f"pycinder imported from {where}, not from the installed wheel"
assert "fn " in shader_source("frame_tiles"), "the shaders are not in the wheel"
mesh = bunny()
moved = mesh.copy()
moved.apply_translation((0.25 * mesh.extents[0], 0, 0))
result = pycinder.find_collisions([mesh, moved], names=["bunny", "moved"])
assert result.pair_names() == {("bunny", "moved")}, result
print(f"check-wheel: pycinder {pycinder.__version__} from the wheel: {result!r}")
PYEOF
"$tmp/venv/bin/python" -m pytest -q -p no:cacheprovider tests/test_docs_examples.py
