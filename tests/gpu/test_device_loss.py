"""No wait without a cause: a wait that passes its deadline says whether the device was lost,
which passes its submission held and whether the GPU started and finished it; a lost device is
replaced by a new one, and the detector answers the next query correctly."""

from __future__ import annotations

import logging
import pickle
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.errors import GpuDeviceLostError, GpuTimeoutError
from pycinder.gpu import buffers as gpu_buffers
from pycinder.gpu import watch as gpu_watch
from pycinder.gpu.device import get_gpu
from pycinder.gpu.watch import Diagnosis, describe_passes, watch_of

BOX = trimesh.creation.box((1.0, 1.0, 1.0))


def _scene(x: float = 0.8) -> tuple[list, list]:
    pose = np.eye(4)
    pose[0, 3] = x
    return [BOX, BOX], [np.eye(4), pose]


def _never(promise: object, timeout: float) -> bool:
    """A frame's map that never comes: waits out its deadline."""
    time.sleep(timeout)
    return False


def _too_late(promise: object, timeout: float) -> bool:
    """A frame's map that comes after its deadline: the GPU finished the frame (waited for
    here, whatever the load), the wait did not see it."""
    assert gpu_watch.wait_for(promise, 120)
    return False


def test_a_timeout_says_the_device_was_not_lost_and_what_the_gpu_did(monkeypatch):
    det = pycinder.Detector(timeout=0.5)
    assert det.find_collisions(*_scene()).pairs.tolist() == [[0, 1]]
    monkeypatch.setattr(gpu_buffers, "wait_for", _too_late)
    with pytest.raises(GpuTimeoutError) as caught:
        det.find_collisions(*_scene())
    message = str(caught.value)
    assert caught.value.device_lost is False
    assert "the device was not lost" in message
    # the markers are read for real: the frame was submitted, and the GPU finished it
    assert caught.value.progress.startswith("the GPU finished submission"), message
    assert "passes:" in message and "detector was reset" in message
    monkeypatch.setattr(gpu_buffers, "wait_for", _never)
    t0 = time.perf_counter()
    with pytest.raises(GpuTimeoutError, match="within 0.5 s: the device was not lost"):
        det.find_collisions(*_scene())
    elapsed = time.perf_counter() - t0
    assert elapsed < 0.5 + 2 * gpu_watch.PROGRESS_DEADLINE + 5, f"the timeout took {elapsed:.1f} s"
    monkeypatch.undo()
    assert det.find_collisions(*_scene()).pairs.tolist() == [[0, 1]]


def _in_a_fresh_process(scenario: str) -> None:
    """Run ``scenario`` (a function of this module) in a fresh process, on pycinder's own
    device: a device shared with pygfx (as the demos' tests leave this process) cannot be made
    again, and losing it would take every later test's device with it."""
    out = subprocess.run([sys.executable, "-c", f"import test_device_loss as t; t.{scenario}()"],
                         cwd=str(Path(__file__).parent), capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stdout + out.stderr
    assert out.stdout.strip().endswith(f"{scenario}: right"), out.stdout + out.stderr


def test_a_device_lost_while_waiting_is_said_and_replaced():
    _in_a_fresh_process("lost_while_waiting")


def lost_while_waiting() -> None:
    """wgpu logs a lost device while a frame's map never comes: the timeout says the device was
    lost, within the timeout; the detector moves to a new device and answers the next query."""
    det = pycinder.Detector(timeout=0.5)
    old = det.gpu.device
    assert det.find_collisions(*_scene()).pairs.tolist() == [[0, 1]]

    def lost(promise: object, timeout: float) -> bool:
        old.destroy()  # the device is lost while the map waits ...
        logging.getLogger("wgpu").error("DEVICE LOST!")  # ... and wgpu-native's callback logs it
        return _never(promise, timeout)

    real, gpu_buffers.wait_for = gpu_buffers.wait_for, lost
    t0 = time.perf_counter()
    try:
        with pytest.raises(GpuTimeoutError, match=r"within 0.5 s: the device was lost "
                           r"\(wgpu logged.*DEVICE LOST.*made a new device") as caught:
            det.find_collisions(*_scene())
    finally:
        gpu_buffers.wait_for = real
    assert time.perf_counter() - t0 < 0.5 + 5
    assert caught.value.device_lost is True
    assert det.gpu.device is not old and get_gpu().device is det.gpu.device
    assert det.find_collisions(*_scene()).pairs.tolist() == [[0, 1]]
    assert det.find_collisions(*_scene(1.5)).pairs.tolist() == []
    print("lost_while_waiting: right")


def test_a_destroyed_device_fails_one_query_clearly_and_the_next_is_answered():
    _in_a_fresh_process("destroyed")


def destroyed() -> None:
    """A destroyed device: the next query fails at once with GpuDeviceLostError, the one after
    it is answered on a new device, which detectors made afterwards use too."""
    det = pycinder.Detector(timeout=5)
    assert det.find_collisions(*_scene()).pairs.tolist() == [[0, 1]]
    old = det.gpu.device
    old.destroy()
    t0 = time.perf_counter()
    with pytest.raises(GpuDeviceLostError, match="device was lost: the detector made a new"):
        det.find_collisions(*_scene())
    assert time.perf_counter() - t0 < 5
    assert det.gpu.device is not old
    assert det.find_collisions(*_scene()).pairs.tolist() == [[0, 1]]
    other = pycinder.Detector()  # made after: on the new device
    assert other.gpu.device is det.gpu.device
    assert other.find_collisions(*_scene(1.5)).pairs.tolist() == []
    print("destroyed: right")


def test_the_watch_counts_submissions_and_notes_their_passes():
    det = pycinder.Detector()
    watch = watch_of(det.gpu.device)
    assert watch is not None
    before = watch.submissions
    det.find_collisions(*_scene())
    assert watch.submissions > before
    assert watch.last is not None and watch.last.number == watch.submissions
    assert watch.progress().startswith(f"the GPU finished submission {watch.submissions}")
    found = watch.explain()
    assert isinstance(found, Diagnosis) and found.lost is None
    assert "the device was not lost" in found.sentence


def test_passes_are_described_in_order_with_repeats_counted():
    assert describe_passes(["a", "b", "a", "c"]) == "4 passes: a (x2), b, c"
    assert describe_passes([f"p{k}" for k in range(14)], most=12).endswith("and 2 more")


def test_a_timeout_error_keeps_what_it_found_through_pickling():
    err = GpuTimeoutError("late", device_lost=True, progress="progress unknown")
    again = pickle.loads(pickle.dumps(err))
    assert (str(again), again.device_lost, again.progress) == ("late", True, "progress unknown")
