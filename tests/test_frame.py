"""What one query costs the host in GPU round trips: one submission and one map for records
"none" and "found" (the passes, their timestamps and the readback travel together)."""

import sys

import numpy as np
import pytest
import trimesh
import wgpu

import pycinder


class _Count:
    def __init__(self, monkeypatch):
        self.submits = self.maps = 0
        queue_type = type(pycinder.Detector().gpu.device.queue)
        submit = queue_type.submit
        buffer_type = wgpu.backends.wgpu_native.GPUBuffer
        map_async = buffer_type.map_async

        def counted_submit(queue, *args, **kwargs):
            # wgpu-py itself submits an empty command buffer before a buffer's first map for
            # reading (a driver workaround); count pycinder's own submissions.
            if "pycinder" in sys._getframe(1).f_code.co_filename:
                self.submits += 1
            return submit(queue, *args, **kwargs)

        def counted_map(buffer, *args, **kwargs):
            self.maps += 1
            return map_async(buffer, *args, **kwargs)

        monkeypatch.setattr(queue_type, "submit", counted_submit)
        monkeypatch.setattr(buffer_type, "map_async", counted_map)


@pytest.mark.parametrize("records", ["none", "found"])
@pytest.mark.parametrize("profile", [False, True])
def test_one_submission_and_one_map_per_query(monkeypatch, records, profile):
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    det = pycinder.Detector(records=records, profile=profile)
    poses = np.stack([np.eye(4)] * 40)
    poses[:, 0, 3] = 0.8 * np.arange(40)
    det.find_collisions([ball] * 40, poses)               # warm-up: buffers grow here
    count = _Count(monkeypatch)
    for k in range(3):
        poses[:, 1, 3] = 0.01 * k
        vertices = np.array(ball.vertices) * (1 + 0.01 * k)  # deforming: F0 runs too
        result = det.find_collisions([(vertices, np.array(ball.faces))] * 40, poses)
        assert result.pairs.tolist() == [[i, i + 1] for i in range(39)]
    assert (count.submits, count.maps) == (3, 3)


def comb(teeth: int = 6) -> trimesh.Trimesh:
    """One closed body of ``teeth`` thin parallel slabs: rays through it cross many faces."""
    slabs = []
    for k in range(teeth):
        slab = trimesh.creation.box((1.0, 1.0, 0.04))
        slab.apply_translation((0, 0, 0.12 * k))
        slabs.append(slab)
    return trimesh.util.concatenate(slabs)


def test_two_queries_in_flight_answer_as_one_at_a_time():
    """Frame k+1 is submitted (its deformed vertices uploaded) before frame k is read; frame k
    needs retries of undecided tiles, which must still see frame k's vertices."""
    teeth = comb()
    v0, f = np.array(teeth.vertices), np.array(teeth.faces)
    box = trimesh.creation.box((0.3, 0.3, 1.0))
    poses = [np.eye(4), trimesh.transformations.translation_matrix((0.0, 0.0, 0.3))]
    frames = [v0, v0 + [2.0, 0, 0], v0 * [1, 1, 1.5], v0 + [0.6, 0, 0]]
    one_at_a_time = pycinder.Detector(tolerance=0.005, records="all")
    expected = [one_at_a_time.find_collisions([(v, f), box], poses) for v in frames]
    assert [len(r.pairs) for r in expected] == [1, 0, 1, 1]
    assert expected[0].stats.retries > 0              # the comb overflows the crossing lists
    det = pycinder.Detector(tolerance=0.005, records="all")
    pending = [det.submit([(v, f), box], poses) for v in frames[:2]]
    results = [pending[0].result()]
    pending.append(det.submit([(frames[2], f), box], poses))
    pending.append(det.submit([(frames[3], f), box], poses))   # waits for frame 1's GPU work
    results += [p.result() for p in pending[1:]]
    for got, want in zip(results, expected):
        assert got.pairs.tolist() == want.pairs.tolist()
        assert got.stats.retries == want.stats.retries
        # retried tiles' records come from the frame's own vertices
        assert np.array_equal(np.sort(got.records["point"], axis=0),
                              np.sort(want.records["point"], axis=0))
    assert all(p.ready for p in pending)
