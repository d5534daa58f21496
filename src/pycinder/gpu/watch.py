"""What a wait on the GPU can say when it passes its deadline: whether the device was lost,
which passes the waited-for submission held, and whether the GPU started it and finished it.

A :class:`DeviceWatch` is installed on each device pycinder makes (:func:`install`). It listens
to every signal wgpu-py 0.32 gives of a device's trouble:

* **device lost**: wgpu-native's device-lost callback only logs (``"DEVICE LOST!"`` and "The
  WGPU device was lost" on the ``wgpu`` logger; ``device.lost`` is not implemented), and a call
  on a lost device raises "Parent device is lost". The watch notes both (a logging handler on
  the ``wgpu`` logger, whose records name no device: a loss logged after a device was made is
  a hint, taken as the device's own only when the device itself fails), and
  :meth:`DeviceWatch.probe_lost` asks the device by making a 4-byte buffer.
* **uncaptured errors**: wgpu-py logs the errors no call raised on the same logger
  (``device.onuncapturederror`` is not implemented): the last few are kept.
* **progress**: every submission on the device gets one more command buffer, last, that copies
  its sequence number into a tiny marker buffer, alternating between two markers. After a
  timeout, mapping the marker of the submission before the waited-for one says whether the GPU
  got to it (a queue runs its submissions in order), and mapping its own marker whether it
  finished it; each map waits at most :data:`PROGRESS_DEADLINE` seconds. Where neither answers
  in time, or the device is lost, progress is "unknown".
* **passes**: the labels of the compute and render passes of each submission's command buffers.

The cost per submission is one 4-byte ``queue.write_buffer`` and one command buffer of one
4-byte copy, recorded through wgpu-native's C functions (:mod:`pycinder.gpu.native`).
"""

from __future__ import annotations

import logging
import re
import threading
import time
import weakref
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import wgpu

from . import native

PROGRESS_DEADLINE = 0.5
"""Seconds each progress marker's map may take after a timeout before progress is "unknown"."""
KEPT_ERRORS = 5
"""Uncaptured errors (wgpu's error log records) kept per device."""
_LOST = re.compile(r"device (was|is) lost|DEVICE LOST", re.IGNORECASE)


@dataclass
class Submission:
    """One ``queue.submit`` on a watched device."""

    number: int
    passes: list[str]
    at: float = field(default_factory=time.monotonic)


class DeviceWatch:
    """The signals of one device's trouble (see the module's docstring).

    Parameters
    ----------
    device : wgpu.GPUDevice
        The device to watch; :func:`install` wraps its queue's ``submit`` and its
        ``create_command_encoder``.
    """

    def __init__(self, device: wgpu.GPUDevice) -> None:
        self.device = device
        self.made = time.time()
        self.lost: str | None = None
        """Why the device was lost, once a call on it said so (or the probe failed)."""
        self.lost_hint: str | None = None
        """A loss wgpu logged since this device was made. The log does not say which device, so
        it is confirmed by :meth:`probe_lost` before the device is taken as lost."""
        self.errors: deque[str] = deque(maxlen=KEPT_ERRORS)
        self.submissions = 0
        self.last: Submission | None = None
        self._lock = threading.RLock()
        self._seq = device.create_buffer(label="progress sequence", size=4,
                                         usage=wgpu.BufferUsage.COPY_SRC
                                         | wgpu.BufferUsage.COPY_DST)
        self._markers = self._new_markers()
        self._queue = device.queue
        self._seq_data = np.zeros(1, np.uint32)
        self._seq_pointer = native.pointer(self._seq_data)

    def _create_encoder(self, *args: Any, **kwargs: Any) -> wgpu.GPUCommandEncoder:
        """The class's ``create_command_encoder``, looked up at each call (so that a patch of
        the class, as tests and the benchmarks' round-trip counts make, still sees it)."""
        return type(self.device).create_command_encoder(self.device, *args, **kwargs)

    def _submit(self, buffers: list[Any]) -> None:
        """The class's ``submit``, looked up at each call (see :meth:`_create_encoder`)."""
        type(self._queue).submit(self._queue, buffers)

    def _new_markers(self) -> list[wgpu.GPUBuffer]:
        return [self.device.create_buffer(label=f"progress marker {k}", size=4,
                                          usage=wgpu.BufferUsage.MAP_READ
                                          | wgpu.BufferUsage.COPY_DST) for k in range(2)]

    # -- the wrapped calls ------------------------------------------------------------------

    def create_command_encoder(self, *args: Any, **kwargs: Any) -> wgpu.GPUCommandEncoder:
        """The device's own, with the labels of its passes noted on the command buffer."""
        encoder = self._create_encoder(*args, **kwargs)
        labels: list[str] = []
        for name in ("begin_compute_pass", "begin_render_pass"):
            begin = getattr(encoder, name)

            def noting(*a: Any, _begin: Any = begin, _kind: str = name, **kw: Any) -> Any:
                labels.append(str(kw.get("label") or _kind.removeprefix("begin_")
                                   .replace("_", " ")))
                return _begin(*a, **kw)

            setattr(encoder, name, noting)
        # Passes recorded through the C functions (pycinder.gpu.native) note theirs here.
        encoder._pycinder_labels = labels
        finish = encoder.finish

        def finishing(*a: Any, **kw: Any) -> Any:
            buffer = finish(*a, **kw)
            try:
                buffer._pycinder_passes = labels
            except AttributeError:  # pragma: no cover - a command buffer with slots
                pass
            return buffer

        encoder.finish = finishing
        return encoder

    def submit(self, command_buffers: Any) -> None:
        """The queue's own, with the marker copy appended (see the module's docstring)."""
        buffers = list(command_buffers)
        with self._lock:
            self.submissions += 1
            n = self.submissions
            passes = [p for b in buffers for p in getattr(b, "_pycinder_passes", ())]
            self.last = Submission(n, passes)
            self._submit([*buffers, self._marker_copy(n)])

    def _marker_copy(self, n: int) -> wgpu.GPUCommandBuffer:
        """The command buffer that copies sequence number ``n`` into its marker (recorded
        through wgpu-native's C functions where the device is wgpu-native's: five calls)."""
        marker = self._markers[n % 2]
        if not native.available(self.device):  # pragma: no cover - another wgpu-py backend
            self._queue.write_buffer(self._seq, 0, np.array([n], np.uint32))
            encoder = self._create_encoder(label="progress marker")
            encoder.copy_buffer_to_buffer(self._seq, 0, marker, 0, 4)
            return encoder.finish()
        self._seq_data[0] = n
        lib = native.LIB
        lib.wgpuQueueWriteBuffer(self._queue._internal, self._seq._internal, 0,
                                 self._seq_pointer, 4)
        encoder = lib.wgpuDeviceCreateCommandEncoder(self.device._internal, native.NULL)
        lib.wgpuCommandEncoderCopyBufferToBuffer(encoder, self._seq._internal, 0,
                                                 marker._internal, 0, 4)
        buffer = lib.wgpuCommandEncoderFinish(encoder, native.NULL)
        lib.wgpuCommandEncoderRelease(encoder)
        return native.command_buffer(buffer, self.device, "progress marker")

    # -- signals ----------------------------------------------------------------------------

    def note_log(self, record: logging.LogRecord) -> None:
        """A record of the ``wgpu`` logger, made after this device (see the module's
        docstring)."""
        if record.created < self.made:
            return
        message = record.getMessage()
        if _LOST.search(message):
            at = time.strftime("%H:%M:%S", time.localtime(record.created))
            self.lost_hint = f"wgpu logged at {at}: {message.splitlines()[0]}"
        elif record.levelno >= logging.ERROR:
            self.errors.append(message.splitlines()[0] if message else "")

    def note_error(self, exc: BaseException) -> None:
        """An error a call on this device raised: one that says the device is lost marks it."""
        if _LOST.search(str(exc)):
            self.lost = self.lost or f"a call raised: {' '.join(str(exc).split())}"

    def probe_lost(self) -> str | None:
        """Why the device was lost, asking it (a 4-byte buffer) when no call on it has said so;
        None while it is not known to be lost. A loss wgpu logged (:attr:`lost_hint`, which
        names no device) is taken as this device's only when the probe fails too."""
        if self.lost is None:
            try:
                self.device.create_buffer(label="lost probe", size=4,
                                          usage=wgpu.BufferUsage.COPY_DST)
            except Exception as exc:  # wgpu raises its own types per error kind
                self.note_error(exc)
                if self.lost is not None and self.lost_hint is not None:
                    self.lost = f"{self.lost_hint}; {self.lost}"
        return self.lost

    def progress(self, deadline: float = PROGRESS_DEADLINE) -> str:
        """Whether the GPU started and finished the last submission, in words.

        Each marker's map waits at most ``deadline`` seconds. A marker that did not answer is
        replaced (a buffer left pending a map cannot be copied into), so the next submission
        has two markers to write.
        """
        last = self.last
        if last is None:
            return "no work was submitted on this device"
        if self.probe_lost() is not None:
            return "progress unknown (the device was lost)"
        with self._lock:
            if self.last is not last:
                return "progress unknown (more work was submitted meanwhile)"
            before = self._markers[(last.number - 1) % 2]
            own = self._markers[last.number % 2]
            started = last.number == 1 or self._read(before, deadline) == last.number - 1
            finished = self._read(own, deadline) == last.number
            if not (started and finished):
                self._markers = self._new_markers()
        what = f"submission {last.number}"
        if finished:
            return f"the GPU finished {what} (the wait ended before its map was answered)"
        if started:
            return f"the GPU started {what} but did not finish it"
        return f"the GPU never started {what} (it had not finished the work before it)"

    def _read(self, marker: wgpu.GPUBuffer, deadline: float) -> int | None:
        """The number a marker holds, or None when its map is not answered within
        ``deadline`` seconds (or fails)."""
        try:
            try:  # without wgpu-py's flushing submission (see Readback.start)
                promise = marker.map_async("READ_NOSYNC", 0, 4)
            except (KeyError, ValueError, TypeError):  # pragma: no cover - older wgpu-py
                promise = marker.map_async(wgpu.MapMode.READ, 0, 4)
            if not wait_for(promise, deadline):
                return None
            promise.sync_wait()
            try:
                return int(np.frombuffer(marker.read_mapped(0, 4), np.uint32)[0])
            finally:
                marker.unmap()
        except Exception as exc:  # a lost device fails the map
            self.note_error(exc)
            return None

    def explain(self) -> Diagnosis:
        """After a timeout: everything known of the device's state (see :class:`Diagnosis`)."""
        lost = self.probe_lost()
        last = self.last
        return Diagnosis(lost, "progress unknown (the device was lost)" if lost
                         else self.progress(),
                         f"submission {last.number} held {describe_passes(last.passes)}"
                         if last is not None and last.passes else None,
                         list(self.errors))


@dataclass(frozen=True)
class Diagnosis:
    """What :meth:`DeviceWatch.explain` found after a timeout."""

    lost: str | None
    """Why the device was lost; None while it is not known to be."""
    progress: str
    """Whether the GPU started and finished the last submission, in words."""
    passes: str | None
    """The passes the last submission held, in words (None where it held none)."""
    errors: list[str]
    """The last uncaptured errors wgpu reported."""

    @property
    def sentence(self) -> str:
        """Everything in one sentence, for an error message."""
        parts = [f"the device was lost ({self.lost})" if self.lost else "the device was not lost",
                 self.progress]
        if self.passes:
            parts.append(self.passes)
        if self.errors:
            parts.append(f"wgpu reported: {'; '.join(self.errors)}")
        return "; ".join(parts)


def describe_passes(labels: list[str], most: int = 12) -> str:
    """Pass labels in order, repeats counted: ``"bounds, F6 crossings (x3)"``."""
    counts = Counter(labels)
    names = list(dict.fromkeys(labels))
    words = [f"{n} (x{counts[n]})" if counts[n] > 1 else n for n in names[:most]]
    if len(names) > most:
        words.append(f"and {len(names) - most} more")
    return f"{len(labels)} passes: " + ", ".join(words)


_watches: weakref.WeakSet[DeviceWatch] = weakref.WeakSet()
"""Every watch alive: the device holds its watch (the two go together)."""


class _WgpuLog(logging.Handler):
    """Hands every ``wgpu`` log record of level WARNING and up to the watches."""

    def emit(self, record: logging.LogRecord) -> None:
        for watch in list(_watches):
            watch.note_log(record)


_handler: _WgpuLog | None = None


def install(device: wgpu.GPUDevice) -> DeviceWatch:
    """Watch ``device``: wrap its queue's ``submit`` and its ``create_command_encoder``, and
    listen to the ``wgpu`` logger. Once per device."""
    global _handler
    watch = watch_of(device)
    if watch is None:
        watch = DeviceWatch(device)
        device.queue.submit = watch.submit
        device.create_command_encoder = watch.create_command_encoder
        device._pycinder_watch = watch
        _watches.add(watch)
    if _handler is None:
        _handler = _WgpuLog(logging.WARNING)
        logging.getLogger("wgpu").addHandler(_handler)
    return watch


def watch_of(device: Any) -> DeviceWatch | None:
    """The watch :func:`install` put on ``device``, if any."""
    return getattr(device, "_pycinder_watch", None)


def wait_for(promise: object, timeout: float) -> bool:
    """Wait for a wgpu promise for at most ``timeout`` seconds; False when it is still pending.

    wgpu-native resolves promises on a polling thread that sets an event; waiting on that event
    with a timeout is the only bounded wait wgpu-py offers. A map asked for through the C
    function (:class:`~pycinder.gpu.native.PendingMap`) is answered on the same thread. Other
    backends fall back to an unbounded wait.
    """
    if isinstance(promise, native.PendingMap):
        return promise.wait(timeout)
    event = getattr(promise, "_thread_event", None)
    if event is None:  # pragma: no cover - another wgpu backend
        return True
    return bool(event.wait(timeout))
