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


def test_a_recording_replays_its_commands_on_another_encoder():
    """Commands noted while recorded (a pass, clears, a copy) replay on a new encoder with the
    same effect and the watch's labels; a recording that saw a call through wgpu-py refuses to
    replay. (Dispatches replay in every query's frame: the next test.)"""
    device = get_gpu().device
    usage = wgpu.BufferUsage
    data = device.create_buffer(size=4 * 256, usage=usage.STORAGE | usage.COPY_DST
                                | usage.COPY_SRC)
    out = device.create_buffer(size=4 * 256, usage=usage.COPY_DST | usage.MAP_READ)

    def fill() -> None:
        device.queue.write_buffer(data, 0, np.full(256, 7, np.uint32))

    def read() -> np.ndarray:
        out.map_sync(wgpu.MapMode.READ)
        try:
            return np.frombuffer(out.read_mapped(), np.uint32).copy()
        finally:
            out.unmap()

    fill()
    first = native.encoder(device, "recorded")
    recording = first.record()
    first.clear_buffer(data, 4 * 200, 16)                         # words 200-203
    cpass = first.begin_compute_pass(label="empty, recorded")
    cpass.end()
    first.clear_buffer(data, 0, 4 * 100)                          # words 0-99
    first.copy_buffer_to_buffer(data, 0, out, 0, 4 * 256)
    first.stop()
    assert recording.complete and len(recording.ops) == 5
    device.queue.submit([first.finish()])
    expected = np.full(256, 7, np.uint32)
    expected[:100] = 0
    expected[200:204] = 0
    assert np.array_equal(read(), expected)
    fill()
    again = native.encoder(device, "replayed")
    again.replay(recording)
    device.queue.submit([again.finish()])
    assert "empty, recorded" in watch_of(device).last.passes
    assert np.array_equal(read(), expected)
    mixed = native.encoder(device, "mixed")
    partial = mixed.record()
    mixed.insert_debug_marker("through wgpu-py")
    mixed.stop()
    mixed.finish()
    assert not partial.complete
    with pytest.raises(RuntimeError, match="cannot be replayed"):
        native.encoder(device, "refused").replay(partial)


def test_rounds_replayed_from_earlier_frames_give_the_answers_of_rounds_encoded_anew(monkeypatch):
    """A detector's frames replay the rounds of earlier frames whatever their sizes (their
    clears and culls are indirect), across scenes of different sizes, buffers grown between
    them (new recordings), mirrored, scaled and tiny bodies: the pairs equal those of frames
    whose every round is encoded anew."""
    from pycinder.focused.frame import frames

    replayed = []
    real = native.Encoder.replay
    monkeypatch.setattr(native.Encoder, "replay",
                        lambda self, rec: replayed.append(rec) or real(self, rec))
    det = pycinder.Detector(records="all")  # every record: the same ones each run
    answers = []
    for n, seed in ((150, 1), (20, 2), (60, 3), (20, 4), (150, 5), (60, 6), (20, 7)):
        meshes, poses = _scene(n, seed)
        answers.append((meshes, poses, det.find_collisions(meshes, poses)))
    assert len(replayed) >= 3
    monkeypatch.setattr(frames.FocusedFrames, "_round_key", lambda *args: None)
    fresh = pycinder.Detector(records="all")
    for meshes, poses, result in answers:
        anew = fresh.find_collisions(meshes, poses)
        assert len(result.pairs) and result.pairs.tolist() == anew.pairs.tolist()
        for field in ("penetrating", "penetrated", "view", "pixel_x", "pixel_y", "pixel_z"):
            np.testing.assert_array_equal(result.records[field], anew.records[field], field)
