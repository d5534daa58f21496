"""Commands recorded through wgpu-native's C functions (pycinder.gpu.native): the same answers
as through wgpu-py, errors still raised, passes still noted by the device watch, maps bounded."""

import numpy as np
import pytest
import trimesh
import wgpu

import pycinder
from pycinder.gpu import native
from pycinder.gpu.buffers import Readback
from pycinder.gpu.device import get_gpu
from pycinder.gpu.watch import watch_of

pytestmark = pytest.mark.skipif(not native.available(get_gpu().device),
                                reason="the device is not wgpu-native's")


def _scene(n: int, seed: int):
    """``n`` bodies of three kinds, some mirrored, scaled or tiny, scattered so that about
    half of them touch another."""
    rng = np.random.default_rng(seed)
    kinds = [trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(subdivisions=2),
             trimesh.creation.annulus(0.3, 0.6, 0.4)]
    meshes = [kinds[k] for k in rng.integers(0, 3, n)]
    poses = np.stack([trimesh.transformations.random_rotation_matrix(rng.random(3))
                      for _ in range(n)])
    scale = rng.choice([1.0, -1.0, 0.3, 1e-3], n)
    poses[:, :3, :3] *= scale[:, None, None]
    poses[:, :3, 3] = rng.uniform(0, 0.8 * n ** (1 / 3), (n, 3))
    return meshes, poses


def test_a_query_records_its_frame_through_the_c_functions_with_the_same_answers(monkeypatch):
    det = pycinder.Detector()
    for seed in range(3):
        meshes, poses = _scene(40, seed)
        det.find_collisions(meshes, poses)
        with native.counting() as calls:
            direct = det.find_collisions(meshes, poses)
        assert calls.get("wgpuComputePassEncoderSetPipeline", 0) >= 5
        assert calls["wgpuBufferMapAsync"] >= 1
        with monkeypatch.context() as m:  # the same query through wgpu-py alone
            m.setattr(native, "available", lambda device: False)
            with native.counting() as none:
                through_wgpu_py = det.find_collisions(meshes, poses)
            assert none == {}
        assert len(direct.pairs) and direct.pairs.tolist() == through_wgpu_py.pairs.tolist()


def test_the_watch_notes_the_passes_recorded_through_the_c_functions():
    det = pycinder.Detector()
    meshes, poses = _scene(12, 7)
    det.find_collisions(meshes, poses)
    passes = watch_of(det.gpu.device).last.passes
    assert any(p.startswith("F1 cull") for p in passes), passes
    assert any(p.startswith("F3 crossings") for p in passes), passes  # a render pass: wgpu-py's


def test_a_command_recorded_wrongly_is_raised_by_finish():
    encoder = native.encoder(get_gpu().device, "wrong on purpose")
    cpass = encoder.begin_compute_pass(label="no pipeline")
    cpass.dispatch_workgroups(1)
    cpass.end()
    with pytest.raises(wgpu.GPUValidationError, match="pipeline must be set"):
        encoder.finish()


def test_a_map_given_up_on_stops_the_polling_and_an_answer_in_time_is_undone():
    device = get_gpu().device
    source = device.create_buffer(size=16, usage=wgpu.BufferUsage.COPY_SRC
                                  | wgpu.BufferUsage.COPY_DST)

    def copy_into(readback, values):
        device.queue.write_buffer(source, 0, np.asarray(values, np.uint32))
        encoder = native.encoder(device, "copy")
        encoder.copy_buffer_to_buffer(source, 0, readback.ensure(16), 0, 16)
        device.queue.submit([encoder.finish()])

    for answered in (True, False):
        given_up = Readback(device, "given up")
        copy_into(given_up, [1, 2, 3, 4])
        pending = given_up.start(16)
        if answered:
            assert pending.wait(60)
        pending.abandon()
        assert pending.key not in native._maps and pending.token.is_done()
        # The answer sets the event only if it came before the map was given up on.
        in_time = pending.ready()
        assert in_time or not answered
        if in_time:                         # then the map was undone: it maps again
            copy_into(given_up, [9, 10, 11, 12])
            assert given_up.read(16).tolist() == [9, 10, 11, 12]
        # Another map: the given-up one's answer, if it comes meanwhile, is ignored.
        other = Readback(device, "read")
        for values in ([5, 6, 7, 8], [13, 14, 15, 16]):
            copy_into(other, values)
            assert other.read(16).tolist() == values
        assert pending.ready() == in_time   # a later answer is ignored


def test_a_map_of_a_range_wgpu_refuses_raises_instead_of_aborting():
    device = get_gpu().device
    readback = Readback(device, "odd")
    readback.ensure(16)
    for nbytes in (0, 6, readback.buf.buffer.size + 4):
        with pytest.raises(ValueError, match="multiple of 4"):
            native.map_read(device, readback.buf.buffer, nbytes)


def test_render_passes_of_one_plain_attachment_go_through_the_c_functions_others_wgpu_py():
    device = get_gpu().device
    target = device.create_texture(size=(8, 8, 1), format="r8unorm",
                                   usage=wgpu.TextureUsage.RENDER_ATTACHMENT)
    view = target.create_view()
    plain = {"view": view, "load_op": "clear", "store_op": "store", "clear_value": (0, 0, 0, 1)}
    others = [dict(plain, clear_value={"r": 0, "g": 0, "b": 0, "a": 1}),
              dict(plain, resolve_target=None)]
    encoder = native.encoder(device, "render passes")
    for attachment, kind in [(plain, native.RenderPass)] + [(o, wgpu.GPURenderPassEncoder)
                                                             for o in others]:
        rpass = encoder.begin_render_pass(label="one", color_attachments=[attachment])
        assert isinstance(rpass, kind), attachment
        rpass.end()
    device.queue.submit([encoder.finish()])
