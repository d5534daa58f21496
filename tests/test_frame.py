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
