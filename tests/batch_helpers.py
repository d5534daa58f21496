"""Scenes for the batch tests: a few mesh files shared by many scenes, as manifest entries."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from pycinder.testing import SHAPES, make_shape, random_rotation


def mesh_pool(folder: Path, seed: int = 0) -> list[Path]:
    """One closed primitive of each kind, written as PLY files."""
    rng = np.random.default_rng(seed)
    paths = []
    for kind in SHAPES:
        path = folder / f"{kind}.ply"
        make_shape(kind, rng.uniform(0.8, 1.2), rng).export(path)
        paths.append(path)
    return paths


def random_entries(paths: list[Path], count: int, seed: int = 0, relative_to: Path | None = None
                   ) -> list[dict]:
    """``count`` scenes of 2 to 7 bodies picked from ``paths``, posed at random in a cube
    where about a third of the volume is filled, so that scenes hold overlapping and separate
    pairs; every scene lies about the origin, on top of the others."""
    rng = np.random.default_rng(seed)
    entries = []
    for s in range(count):
        n = int(rng.integers(2, 8))
        side = (n / 0.35) ** (1 / 3) * 0.6
        bodies = []
        for j in range(n):
            t = random_rotation(rng)
            t[:3, 3] = rng.uniform(-side / 2, side / 2, 3)
            path = paths[int(rng.integers(len(paths)))]
            mesh = str(path.relative_to(relative_to)) if relative_to else str(path)
            bodies.append({"mesh": mesh, "transform": t.tolist(), "name": f"part{j}"})
        entries.append({"id": f"scene-{s}", "bodies": bodies})
    return entries


def write_manifest(path: Path, entries: list[dict]) -> Path:
    path.write_text("".join(json.dumps(e) + "\n" for e in entries))
    return path


def expected_pairs(entries: list[dict], detector, base: Path | None = None) -> dict:
    """Each scene's pairs from a query of that scene alone, meshes read as the CLI reads them."""
    from pycinder.files import display_name, load_file

    cache: dict[str, object] = {}
    out = {}
    for e in entries:
        meshes = []
        for b in e["bodies"]:
            path = str(Path(base, b["mesh"])) if base else b["mesh"]
            if path not in cache:
                (body,) = load_file(path, display_name(path))  # one mesh per file here
                cache[path] = body.mesh
            meshes.append(cache[path])
        transforms = np.array([b["transform"] for b in e["bodies"]])
        out[e["id"]] = detector.find_collisions(meshes, transforms).pairs.tolist()
    return out
