"""Rendered ``plot.png`` images: cached by what they show, renders rate-limited.

A plot is a function of its task and the path recorded so far, so the route keys it by a
fingerprint of both (:data:`PlotKey`): a finished task's plot is rendered once, a running
task's again only when its path has grown. At most ``entries`` images are kept (least
recently used dropped). Rendering (matplotlib, ~0.1-0.3 s of CPU) happens one at a time, on
one thread of the cache's own (matplotlib keeps its open font files per thread: drawn on
the server's request threads, each new thread opened two more files), and at most ``rate``
times a second on average (bursts of ``burst``); beyond that the route answers 429 with the
wait (settings ``api_plot_*``).
"""

from __future__ import annotations

import math
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Hashable
from concurrent.futures import ThreadPoolExecutor

from api.rate_limit import TokenBucket

PlotKey = Hashable


class RenderLimited(Exception):
    """Too many renders lately; ``retry_after`` [s] until the next is allowed."""

    def __init__(self, retry_after: float) -> None:
        super().__init__(f"plot renders are rate-limited: retry in {retry_after:.1f} s")
        self.retry_after = retry_after


class PlotCache:
    """Bounded LRU of rendered images in front of a rate-limited renderer; thread-safe."""

    def __init__(
        self,
        entries: int,
        rate: float,
        burst: int,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.entries = entries
        self._images: OrderedDict[PlotKey, bytes] = OrderedDict()
        self._lock = threading.Lock()  # the images
        self._render_lock = threading.Lock()  # one render at a time
        self._bucket = TokenBucket(rate, burst, clock)
        self._renderer = ThreadPoolExecutor(max_workers=1, thread_name_prefix="plot-render")
        #: Renders done and refused so far.
        self.renders = 0
        self.refused = 0

    def get(self, key: PlotKey) -> bytes | None:
        with self._lock:
            image = self._images.get(key)
            if image is not None:
                self._images.move_to_end(key)
            return image

    def render(self, key: PlotKey, draw: Callable[[], bytes]) -> bytes:
        """The image of ``key``: cached, or ``draw()`` now if the rate allows (else
        :class:`RenderLimited`). Concurrent requests for one key draw it once."""
        with self._render_lock:
            image = self.get(key)  # drawn meanwhile by the request we waited for
            if image is not None:
                return image
            wait = self._bucket.take()
            if wait > 0:
                self.refused += 1
                raise RenderLimited(math.ceil(wait * 10) / 10)
            image = self._renderer.submit(draw).result()
            self.renders += 1
        with self._lock:
            self._images[key] = image
            while len(self._images) > self.entries:
                self._images.popitem(last=False)
        return image

    def close(self) -> None:
        """Stop the render thread (after a render under way); renders fail from then on."""
        self._renderer.shutdown(wait=True)
