"""Sphinx configuration: Markdown pages through MyST, API pages through autodoc and numpydoc.

Built by ``make docs`` with warnings as errors and no network (no intersphinx).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
try:  # an installed pycinder (editable or wheel) wins; else the source tree
    import pycinder
except ImportError:
    sys.path.insert(0, str(HERE.parent / "src"))
    import pycinder

os.environ.setdefault("XDG_RUNTIME_DIR", "/tmp")

project = "pycinder"
author = "The pycinder developers"
copyright = "the pycinder developers"
release = pycinder.__version__
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "numpydoc",
    "cliref",
    "passtable",
    "repolinks",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build"]
templates_path: list[str] = []

myst_enable_extensions = ["colon_fence", "deflist"]
myst_heading_anchors = 3

autodoc_member_order = "bysource"
autodoc_typehints = "none"  # numpydoc's Parameters sections carry the types
autodoc_default_options = {"show-inheritance": False}

numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

html_theme = "alabaster"
html_static_path = ["_static"]
html_title = f"pycinder {release}"
html_theme_options = {
    "description": "Collision detection on the GPU for triangle meshes",
    "fixed_sidebar": True,
}
