"""Benchmarks against python-fcl, coal and trimesh: ``pycinder bench``.

Scenes are in :mod:`.scenes`, the peer systems in :mod:`.peers`, the loop that times them
interleaved on the same frames in :mod:`.runner`, and the report (JSON, Markdown, plots) in
:mod:`.report`. Needs the ``bench`` extra.
"""
