"""The paper's whole-scene strategy (``strategy="scene"``) against exact geometry.

Its pixel is the scene's extent divided by the resolution, so the truth is taken at a tolerance
of three of its pixels.
"""

import numpy as np
import pytest
import trimesh

import pycinder
import pycinder.testing
from pycinder.view import View
from pycinder.debug.pass_buffers import three_boxes
from pycinder.testing import ground_truth, nested_scene, random_scene

from conftest import assert_matches_truth

MODES = ["filter", "prevent", "offset"]


@pytest.fixture(scope="module", params=MODES)
def scene_detector(request) -> pycinder.Detector:
    return pycinder.Detector(strategy="scene", resolution=1024, self_interference=request.param)


def truth_for(result, meshes, transforms=None):
    """Exact truth at a tolerance of three pixels of the result's (first) view."""
    return ground_truth(meshes, transforms, tolerance=3 * result.views[0].pixel_size)


def test_three_boxes(scene_detector):
    boxes, _, _ = three_boxes()
    result = scene_detector.find_collisions(boxes)
    truth = truth_for(result, boxes)
    assert truth.overlap.tolist() == [[0, 1], [1, 2]]  # the scene is what the paper shows
    assert_matches_truth(result.pairs, truth, context="three boxes")
    assert result.pairs.tolist() == [[0, 1], [1, 2]]


def test_three_boxes_through_paper_view(scene_detector):
    boxes, _, view = three_boxes()
    assert scene_detector.find_collisions(boxes, view=view).pairs.tolist() == [[0, 1], [1, 2]]


def test_nested_solid_without_surface_crossing(scene_detector):
    meshes, transforms = nested_scene()
    result = scene_detector.find_collisions(meshes, transforms)
    truth = truth_for(result, meshes, transforms)
    assert truth.overlap.tolist() == [[0, 1]]
    assert_matches_truth(result.pairs, truth, context="nested")
    # Every record is the small sphere's edge inside the box, never the other way round.
    assert set(result.records["penetrating"].tolist()) == {1}
    assert set(result.records["penetrated"].tolist()) == {0}


@pytest.mark.parametrize("n,seed", [(5, 11), (5, 12), (20, 21), (20, 22)])
def test_random_scenes(scene_detector, n, seed):
    meshes, transforms = random_scene(n, seed)
    result = scene_detector.find_collisions(meshes, transforms)
    truth = truth_for(result, meshes, transforms)
    assert len(truth.overlap) and len(truth.separate)  # the scene tests both ways
    assert_matches_truth(result.pairs, truth, context=f"{n} bodies, seed {seed}")


def test_torus_hole_is_not_inside():
    """A rod through a torus's hole, touching nothing, is not a collision (non-convex shapes)."""
    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3)
    rod = trimesh.creation.cylinder(radius=0.3, height=4.0)
    det = pycinder.Detector(strategy="scene", resolution=1024)
    assert det.find_collisions([torus, rod]).pairs.tolist() == []
    shifted = [np.eye(4), trimesh.transformations.translation_matrix((0.75, 0, 0))]
    assert det.find_collisions([torus, rod], shifted).pairs.tolist() == [[0, 1]]


@pytest.mark.parametrize("n,seed", [(60, 31), (60, 32)])
def test_dense_scene_reports_no_false_pair_and_loses_some(n, seed):
    """The paper's limit, kept as a reference: one edge per pixel loses pairs in dense scenes
    (the focused strategy's lists do not; see test_focused.py), but never invents one."""
    meshes, transforms = random_scene(n, seed)
    result = pycinder.Detector(strategy="scene", resolution=1024).find_collisions(meshes, transforms)
    score = truth_for(result, meshes, transforms).score(result.pairs)
    assert not score["false"]
    assert score["recall"] >= 0.9, score


def test_offset_works_through_a_user_view_without_pixel_size():
    """self_interference="offset" through a perspective View (which has no pixel_size): edges
    still move outwards by half a pixel at the scene's depth, so far fewer self-interference
    pixels reach the filter than without the offset."""
    bunny = pycinder.testing.bunny()
    centre, size = bunny.bounds.mean(axis=0), float(np.linalg.norm(bunny.extents))
    view = View.look_at(eye=centre + (0.3 * size, 0.4 * size, 1.5 * size), target=centre,
                        near=0.5 * size, far=4 * size, fov_y=50)
    assert view.pixel_size is None
    offset = pycinder.Detector(strategy="scene", resolution=512, self_interference="offset")
    plain = pycinder.Detector(strategy="scene", resolution=512, self_interference="filter")
    a = offset.find_collisions([bunny], view=view)
    b = plain.find_collisions([bunny], view=view)
    assert a.pairs.tolist() == b.pairs.tolist() == []
    assert b.stats.self_interference_pixels > 0
    assert a.stats.self_interference_pixels < b.stats.self_interference_pixels / 5


# -- The passes as objects: the pass table, structs declared once, binding by name, profiling ----

SHADERS = ("wholescene_raycast", "wholescene_filter", "wholescene_reduce")


def test_pass_table_comes_from_the_classes_in_the_order_passes_run():
    from pycinder.wholescene.filter import FilterPass
    from pycinder.wholescene.raycast import RaycastPasses
    from pycinder.wholescene.reduce import MipReduce
    from pycinder.gpu.states import PASSES
    from pycinder.gpu.table import pass_table

    from pycinder.wholescene.scene_frame import PASS_INFOS

    infos = [*RaycastPasses.INFOS, FilterPass.INFO, MipReduce.INFO]
    assert list(PASS_INFOS) == infos
    assert [i.number for i in infos] == [str(n) for n in range(1, 10)]
    for info, state in zip(infos, PASSES.values()):
        # the state column is the state table's row, not a copy of it
        assert info.kind == "render" and info.state == state.summary
        assert f"depth {state.depth_compare}" in info.state and f"cull {state.cull}" in info.state
    table = pass_table(infos)
    assert all(i.name in table for i in infos)


def test_no_shader_declares_a_struct_the_host_writes():
    import re

    from pycinder.gpu.device import shader_source
    from pycinder.wholescene import filter as filter_pass, raycast, reduce

    for shader, struct in zip(SHADERS, (raycast.FRAME, filter_pass.PARAMS, reduce.PARAMS)):
        source = shader_source(shader)
        assert not re.search(rf"struct\s+{struct.name}\b", source), shader
        assert re.search(rf"var<uniform>\s+\w+\s*:\s*{struct.name}\s*;", source), shader
        assert not re.search(r"\b_pad\w*\s*:", source), shader


def test_a_field_added_to_the_frame_struct_is_seen_by_both_sides():
    """The Frame block grows a field: the generated WGSL declares it, the shader still compiles
    against it, and the host writes it by name at the offset WGSL gives it."""
    from pycinder.gpu.structs import Field, Struct
    from pycinder.gpu.bindings import Stage
    from pycinder.wholescene.raycast import FRAME, PAYLOAD

    grown = Struct(FRAME.name, [*FRAME.fields, Field("extra", "vec3f", "a test field")],
                   uniform=True)
    assert "extra: vec3f" in grown.wgsl() and grown.offset("extra") == 16 and grown.size == 32
    gpu = pycinder.Detector(strategy="scene", resolution=64).gpu
    stage = Stage(gpu, "wholescene_raycast", render={
        "vertex": "vs_edge", "fragment": "fs_edge", "primitive": {"topology": "line-list"},
        "targets": [{"format": "rgba32uint"}]}, structs=(grown,), consts=PAYLOAD,
        layout="declared")
    assert stage.numbers["frame"] == 0
    block = grown.zeros()
    block["extra"] = (1, 2, 3)
    block["edge_offset"] = 0.5
    words = np.frombuffer(block.tobytes(), np.uint32)
    assert words.tolist()[:8] == [np.float32(0.5).view(np.uint32), 0, 0, 0,
                                  np.float32(1).view(np.uint32), np.float32(2).view(np.uint32),
                                  np.float32(3).view(np.uint32), 0]


def test_bindings_are_by_name_and_a_wrong_name_is_refused():
    det = pycinder.Detector(strategy="scene", resolution=64)
    boxes, _, _ = three_boxes()
    det.find_collisions(boxes)
    strategy = det.strategy
    stage = strategy.filter.stage
    with pytest.raises(KeyError, match="declares no binding"):
        stage.group("wrong", records=strategy.targets.records_view, counter=strategy.filter.counters)
    raycast = strategy.raycast
    group = raycast.bind_group(strategy.buffers, strategy.targets)
    assert raycast.bind_group(strategy.buffers, strategy.targets) is group  # cached


@pytest.mark.parametrize("readback", ["compact", "adaptive"])
def test_profile_times_every_pass_in_the_frames_one_readback(monkeypatch, readback):
    """One profiler times the render steps, the filter and the readback mode's passes; the
    timestamps travel with the header: a query that finds nothing is one submission, one map."""
    det = pycinder.Detector(strategy="scene", resolution=128, readback=readback, profile=True)
    a, b = trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(radius=0.4)
    apart = [np.eye(4), trimesh.transformations.translation_matrix((2, 0, 0))]
    det.find_collisions([a, b], apart)
    from pycinder.gpu.buffers import Readback

    maps = []  # every map of pycinder's is asked for by Readback.start
    start = Readback.start
    monkeypatch.setattr(Readback, "start",
                        lambda rb, *args, **kw: maps.append(1) or start(rb, *args, **kw))
    result = det.find_collisions([a, b], apart)
    assert len(maps) == 1 and len(result.records) == 0
    if det.gpu.timestamps:
        want = {step.title for step in det.strategy.raycast.plan} | {"8 filter"}
        if readback == "adaptive":
            want.add("9 mip-map reduction")
        assert set(result.stats.gpu_ms) == want
