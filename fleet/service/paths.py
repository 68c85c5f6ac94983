"""Recorded task paths, bounded per task and in total (pure; the service guards it with its lock).

A task's robot reports its pose at its control rate (50 Hz) for as long as the task runs.
:class:`PathRecorder` keeps, per task, at most ``per_task`` samples in a flat ``array('d')``
(6 floats = 48 bytes a sample). When a path is full it is **downsampled**: every other sample
is dropped and from then on only every ``stride``-th reported sample is kept (the stride
doubles each time), so a path always spans the whole task at a resolution that halves as it
grows. The latest sample is always returned (the path ends where the robot is).

Across tasks at most ``total`` samples are kept: over the cap, the paths of finished tasks
go first (oldest first); if only running tasks remain, the longest running path is halved.
At most ``max_finished`` finished paths are kept however short they are.
"""

from __future__ import annotations

from array import array
from collections import OrderedDict

#: (t [s since epoch], x [m], y [m], theta [rad], u [m/s], omega [rad/s])
PathSample = tuple[float, float, float, float, float, float]

_WIDTH = 6  # floats per sample

#: Default bounds: 2 000 samples per task (40 s at 50 Hz before the first halving) and
#: 200 000 samples in total (about 10 MB).
PATH_SAMPLES_PER_TASK = 2_000
PATH_SAMPLES_TOTAL = 200_000
PATHS_FINISHED_KEPT = 1_000


class _Path:
    """One task's samples (committed every ``stride``-th offer) and the latest offer."""

    __slots__ = ("count", "data", "offers", "stride", "tail")

    def __init__(self) -> None:
        self.data = array("d")
        self.count = 0  # committed samples (len(data) / 6)
        self.stride = 1
        self.offers = 0  # samples offered since the last committed one
        self.tail: PathSample | None = None  # latest offered sample if not committed

    def __len__(self) -> int:
        return self.count

    def halve(self) -> int:
        """Keep every other committed sample and double the stride; returns samples freed."""
        before = self.count
        kept = array("d")
        for i in range(0, before, 2):
            kept.extend(self.data[i * _WIDTH : (i + 1) * _WIDTH])
        self.data = kept
        self.count = (before + 1) // 2
        self.stride *= 2
        return before - self.count


class PathRecorder:
    """Paths of the tasks under way and of recently finished ones (see the module docstring)."""

    def __init__(
        self,
        per_task: int = PATH_SAMPLES_PER_TASK,
        total: int = PATH_SAMPLES_TOTAL,
        max_finished: int = PATHS_FINISHED_KEPT,
    ) -> None:
        if per_task < 2 or total < per_task or max_finished < 0:
            raise ValueError("need per_task >= 2, total >= per_task and max_finished >= 0")
        self.per_task = per_task
        self.total = total
        self.max_finished = max_finished
        self._running: dict[str, _Path] = {}
        self._finished: OrderedDict[str, _Path] = OrderedDict()
        self._samples = 0

    @property
    def samples(self) -> int:
        """Committed samples held, all paths together."""
        return self._samples

    def __len__(self) -> int:
        return len(self._running) + len(self._finished)

    def __contains__(self, task_id: object) -> bool:
        return task_id in self._running or task_id in self._finished

    def start(self, task_id: str) -> None:
        """Begin (or begin again) recording the path of a task that got a robot."""
        self.discard(task_id)
        self._running[task_id] = _Path()

    def record(self, task_id: str, sample: PathSample) -> None:
        """Offer a sample of a running task (ignored for tasks not being recorded)."""
        path = self._running.get(task_id)
        if path is None:
            return
        path.offers += 1
        if path.offers < path.stride:
            path.tail = sample
            return
        path.offers = 0
        path.tail = None
        path.data.extend(sample)
        path.count += 1
        self._samples += 1
        if path.count >= self.per_task:
            self._samples -= path.halve()
        if self._samples > self.total:
            self._shrink()

    def finish(self, task_id: str) -> None:
        """The task ended: keep its path among the finished ones (evicted oldest first)."""
        path = self._running.pop(task_id, None)
        if path is None:
            return
        if path.tail is not None:  # the path ends where the robot stopped
            path.data.extend(path.tail)
            path.tail = None
            path.count += 1
            self._samples += 1
        self._finished[task_id] = path
        while len(self._finished) > self.max_finished:
            self._evict_oldest_finished()
        if self._samples > self.total:
            self._shrink()

    def discard(self, task_id: str) -> None:
        path = self._running.pop(task_id, None) or self._finished.pop(task_id, None)
        if path is not None:
            self._samples -= len(path)

    def get(self, task_id: str) -> list[PathSample] | None:
        """The samples of a task, oldest first, or None if it has no path (any more)."""
        path = self._running.get(task_id) or self._finished.get(task_id)
        if path is None:
            return None
        d = path.data
        out: list[PathSample] = [
            (d[i], d[i + 1], d[i + 2], d[i + 3], d[i + 4], d[i + 5])
            for i in range(0, len(d), _WIDTH)
        ]
        if path.tail is not None:
            out.append(path.tail)
        return out

    def _evict_oldest_finished(self) -> None:
        _, path = self._finished.popitem(last=False)
        self._samples -= len(path)

    def _shrink(self) -> None:
        while self._samples > self.total and self._finished:
            self._evict_oldest_finished()
        while self._samples > self.total:
            longest = max(self._running.values(), key=len)
            freed = longest.halve()
            self._samples -= freed
            if freed == 0:  # every path is down to one sample: nothing more to give
                return
