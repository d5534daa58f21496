"""The scene strategy's readback modes (paper 4.3.2) and self-interference modes (4.3.1), against
exact geometry and hand-computed expectations."""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.testing import bunny as load_bunny
from pycinder.testing import ground_truth, random_scene

from conftest import assert_matches_truth

SCENES = [(8, 41), (20, 42), (40, 43)]


def pixel_set(records):
    return {tuple(r) for r in records[["pixel_x", "pixel_y", "penetrating", "penetrated", "edge"]].tolist()}


@pytest.fixture(scope="module")
def full():
    return pycinder.Detector(strategy="scene", resolution=512, readback="full")


@pytest.mark.parametrize("n,seed", SCENES)
def test_compact_returns_exactly_the_full_records(full, n, seed):
    meshes, transforms = random_scene(n, seed)
    compact = pycinder.Detector(strategy="scene", resolution=512, readback="compact")
    a = full.find_collisions(meshes, transforms)
    b = compact.find_collisions(meshes, transforms)
    assert len(a.records) > 0
    # same rows in the same order (sorted by pixel); normals are NaN without encode="normal"
    fields = [f for f in a.records.dtype.names if f not in ("normal", "point")]
    assert np.array_equal(a.records[fields], b.records[fields])
    assert b.stats.bytes_read <= 16 + 16 * len(b.records)
    assert a.stats.bytes_read == 16 + 512 * 512 * 16


def test_compact_reads_16_bytes_when_nothing_collides():
    det = pycinder.Detector(strategy="scene", resolution=1024, readback="compact")
    a, b = trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(radius=0.4)
    r = det.find_collisions([a, b], [np.eye(4), trimesh.transformations.translation_matrix((2, 0, 0))])
    assert r.stats.bytes_read <= 16 and len(r.records) == 0


def mip_reduce(records, level: int = 1) -> tuple[int, set]:
    """A CPU re-statement of the paper's mip-map, level by level as the reduction does: the
    blocks of 2**level pixels in which records of different pairs meet, and the pairs that
    survive (each block keeps its highest pair key, as the GPU does)."""
    if len(records) == 0:
        return 0, set()
    key = (np.minimum(records["penetrating"], records["penetrated"]).astype(np.int64) << 16) \
        | np.maximum(records["penetrating"], records["penetrated"])
    x, y = records["pixel_x"].astype(np.int64), records["pixel_y"].astype(np.int64)
    lost = 0
    for _ in range(level):
        bx, by = x // 2, y // 2
        block = (by << 32) | bx
        order = np.lexsort((-key, block))
        block, key_s = block[order], key[order]
        first = np.r_[True, block[1:] != block[:-1]]
        distinct = np.unique(np.c_[block, key_s], axis=0)
        counts = np.unique(distinct[:, 0], return_counts=True)[1]
        lost += int((counts > 1).sum())
        x, y, key = bx[order][first], by[order][first], key_s[first]
    return lost, {(int(k >> 16), int(k & 0xFFFF)) for k in np.unique(key)}


def lossy_blocks(records, level: int = 1) -> int:
    """Blocks of 2**level pixels in which records of different pairs meet (see mip_reduce)."""
    return mip_reduce(records, level)[0]


@pytest.mark.parametrize("n,seed", SCENES)
def test_mipmap_counts_exactly_the_blocks_where_pairs_meet(full, n, seed):
    meshes, transforms = random_scene(n, seed)
    reference = full.find_collisions(meshes, transforms).records
    for levels in (1, 2):
        mip = pycinder.Detector(strategy="scene", resolution=512, readback="mipmap", mipmap_levels=levels)
        r = mip.find_collisions(meshes, transforms)
        assert r.stats.possibly_lost == lossy_blocks(reference, levels)
        assert r.stats.bytes_read < 16 + 512 * 512 * 16 / 4 ** levels + 64
        # what survives is a subset of the real pixels
        assert pixel_set(r.records) <= pixel_set(reference)


def two_pairs_in_one_block():
    """Two pairs of spheres whose contacts are about a pixel apart on screen, at different depths."""
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    t = trimesh.transformations.translation_matrix
    # pair (0, 1) in front, pair (2, 3) far behind and shifted by a sliver on screen
    return [ball] * 4, [t((0, 0, 0)), t((0.8, 0, 0)), t((0.03, 0.03, -6)), t((0.83, 0.03, -6))]


def test_mipmap_flags_a_block_with_two_collisions():
    meshes, transforms = two_pairs_in_one_block()
    view = pycinder.View.fit_bodies(meshes, transforms, direction=(0, 0, -1), resolution=64)
    full_r = pycinder.Detector(strategy="scene", resolution=64).find_collisions(meshes, transforms, view=view)
    assert full_r.pairs.tolist() == [[0, 1], [2, 3]]
    assert lossy_blocks(full_r.records) > 0  # the scene does what it says
    mip = pycinder.Detector(strategy="scene", resolution=64, readback="mipmap", mipmap_levels=5)
    r = mip.find_collisions(meshes, transforms, view=view)
    lost, survivors = mip_reduce(full_r.records, 5)
    assert len(survivors) == 1  # the reduction merges the two pairs: one is dropped ...
    assert {tuple(p) for p in r.pairs.tolist()} == survivors
    assert r.stats.possibly_lost == lost >= 1  # ... and the loss is reported


@pytest.mark.parametrize("n,seed", SCENES + [(60, 44)])
def test_mipmap_reports_loss_whenever_a_pair_is_dropped(full, n, seed):
    meshes, transforms = random_scene(n, seed)
    full_r = full.find_collisions(meshes, transforms)
    full_records = full_r.records
    reference = {tuple(p) for p in full_r.pairs.tolist()}
    dropped = 0
    for levels in (2, 4, 6):
        r = pycinder.Detector(strategy="scene", resolution=512, readback="mipmap", mipmap_levels=levels).find_collisions(
            meshes, transforms)
        got = {tuple(p) for p in r.pairs.tolist()}
        lost, survivors = mip_reduce(full_records, levels)
        assert got == survivors <= reference
        # every dropped pair is among the blocks reported as possibly lost
        assert len(reference - got) <= r.stats.possibly_lost == lost
        dropped += len(reference - got)
    assert dropped > 0  # the scene makes the mip-map lose pairs: the check above is exercised


@pytest.mark.parametrize("n,seed", SCENES + [(60, 44)])
def test_adaptive_never_loses_a_pair(full, n, seed):
    meshes, transforms = random_scene(n, seed)
    reference = full.find_collisions(meshes, transforms)
    r = pycinder.Detector(strategy="scene", resolution=512, readback="adaptive").find_collisions(meshes, transforms)
    assert r.pairs.tolist() == reference.pairs.tolist()
    assert r.stats.possibly_lost == 0
    assert r.stats.bytes_read <= reference.stats.bytes_read + 64


def test_adaptive_reduces_a_sparse_scene():
    a, b = trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(radius=0.4)
    far = trimesh.creation.icosphere(radius=0.4)
    t = [np.eye(4), trimesh.transformations.translation_matrix((0.7, 0, 0)),
         trimesh.transformations.translation_matrix((4, 0, 0))]
    r = pycinder.Detector(strategy="scene", resolution=512, readback="adaptive").find_collisions([a, b, far], t)
    assert r.pairs.tolist() == [[0, 1]]
    assert r.stats.mip_level >= 6 and r.stats.bytes_read < 4096


def bunny_with_spheres():
    bunny = load_bunny()
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.03)
    points, faces = trimesh.sample.sample_surface_even(bunny, 24, seed=5)
    rng = np.random.default_rng(5)
    meshes, transforms = [bunny], [np.eye(4)]
    for p, f in zip(points, faces):
        # centre on the surface (overlap), or a radius and a half outside (clear miss)
        lift = 0.0 if rng.random() < 0.7 else 0.045
        meshes.append(ball)
        transforms.append(trimesh.transformations.translation_matrix(p + bunny.face_normals[f] * lift))
    return meshes, transforms


def test_prevent_finds_what_filter_finds_and_what_its_overwriting_lost():
    meshes, transforms = bunny_with_spheres()
    truth = ground_truth(meshes, transforms, tolerance=0.004)
    assert len(truth.overlap) >= 10 and len(truth.separate) >= 5
    filt = pycinder.Detector(strategy="scene", resolution=512, self_interference="filter").find_collisions(meshes, transforms)
    prev = pycinder.Detector(strategy="scene", resolution=512, self_interference="prevent").find_collisions(meshes, transforms)
    assert_matches_truth(prev.pairs, truth, context="prevent")
    assert not truth.score(filt.pairs)["false"]
    assert {tuple(p) for p in filt.pairs.tolist()} <= {tuple(p) for p in prev.pairs.tolist()}
    # The filter's overwriting is visible pixel by pixel: prevention keeps strictly more.
    assert len(prev.records) > len(filt.records)
    assert filt.stats.self_interference_pixels > 0 and prev.stats.self_interference_pixels == 0


def test_offset_trades_self_interference_for_accuracy():
    meshes, transforms = bunny_with_spheres()
    truth = ground_truth(meshes, transforms, tolerance=0.004)
    r = pycinder.Detector(strategy="scene", resolution=512, self_interference="offset").find_collisions(meshes, transforms)
    f = pycinder.Detector(strategy="scene", resolution=512, self_interference="filter").find_collisions(meshes, transforms)
    assert r.stats.self_interference_pixels < f.stats.self_interference_pixels / 5
    assert not truth.score(r.pairs)["false"]


def test_records_are_ordered_when_decoded_as_by_their_four_fields():
    """sort_records (two 64-bit keys) gives the order of the four fields' lexsort, ties and
    words of all 32 bits included: records are ordered when decoded, not when read back."""
    from pycinder.focused.frame.frameio import sort_records
    from pycinder.gpu.layout import RECORD

    rng = np.random.default_rng(11)
    for n in (0, 1, 2, 5000):
        recs = np.zeros(n, RECORD.dtype)
        for name, top in (("tile", 40), ("uv", 2**32), ("z_bits", 2**32), ("ident", 3)):
            recs[name] = rng.integers(0, top, n, dtype=np.uint64)
        recs["uv"][: n // 2] = 0xFFFF_FFFF                # high bits and many ties
        want = recs[np.lexsort((recs["ident"], recs["z_bits"], recs["uv"], recs["tile"]))]
        assert sort_records(recs).tobytes() == want.tobytes()
        assert sort_records(recs[::-1].copy()).tobytes() == want.tobytes()
