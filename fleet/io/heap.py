"""A bounded C heap for a long-running server: few ``malloc`` arenas, free pages given back.

A long-running server allocates and frees many short-lived buffers through ``malloc``
(request and event bodies, numpy arrays of the planner, SQLite pages, Zenoh payloads) from
several threads. glibc keeps what is freed inside its arenas and returns memory to the
kernel only from the top of a heap, so the free space in the middle of the arenas grows
with the work done: in a 14-minute soak of ``parkfleet serve`` the Python objects stayed
flat (``sys.getallocatedblocks``) while the arenas grew 62 -> 157 MB, 89 MB of it free
(``mallinfo2``), and the resident size grew with them; one ``malloc_trim(0)`` released
70 MB, but the resident size grew back within minutes. The free space is spread over
glibc's per-thread arenas (up to 8 per core: the server's threads are Zenoh's, uvicorn's
and the service's): each keeps its own free lists, and memory freed in one is no use to a
thread allocating in another. :func:`limit_arenas` caps them (``mallopt(M_ARENA_MAX)``,
like ``MALLOC_ARENA_MAX``); with 2 arenas and a trim every minute the same soak's arenas
stayed at 71-89 MB with 11-24 MB free. :class:`HeapTrimmer` calls ``malloc_trim(0)`` every
``interval_s`` seconds on a thread of its own. On a C library without these (musl, macOS)
both do nothing.

Python's own collector is the other half: a full (generation 2) collection walks every
container object alive, and stops every thread while it does -- a server that has imported
numba, scipy, pydantic and FastAPI holds some 260 000 of them before its first request, and
``bench api`` measured its full collections at 250-620 ms each (most of the 99th
percentile of ``POST /tasks``; one every second or two under load). :func:`freeze_startup_heap`,
called once the server is up, moves everything alive then out of the collector's reach
(``gc.freeze``); what the requests and the fleet make afterwards is collected as before.
"""

from __future__ import annotations

import ctypes
import gc
import threading
from collections.abc import Callable

#: ``mallopt`` parameter number of the arena cap (glibc's ``malloc.h``).
M_ARENA_MAX = -8


#: The process's own symbols (the C library among them): no ``find_library`` subprocess.
_PROCESS = ctypes.CDLL(None)


def _libc_function(name: str, *argtypes: type) -> Callable[..., int] | None:
    """A C library function returning ``int``, or None where the C library has none."""
    function = getattr(_PROCESS, name, None)
    if function is None:
        return None
    function.argtypes = list(argtypes)
    function.restype = ctypes.c_int
    return function  # type: ignore[no-any-return]


_MALLOC_TRIM = _libc_function("malloc_trim", ctypes.c_size_t)
_MALLOPT = _libc_function("mallopt", ctypes.c_int, ctypes.c_int)


def limit_arenas(arenas: int) -> bool:
    """Let ``malloc`` use at most ``arenas`` arenas from now on (call it before starting
    threads: arenas already made stay); True if the C library took it. ``arenas <= 0``
    leaves the library's default."""
    return arenas > 0 and _MALLOPT is not None and _MALLOPT(M_ARENA_MAX, arenas) == 1


def freeze_startup_heap() -> int:
    """Collect once, then exempt every object alive now from later collections (module
    docstring); returns how many are frozen. Call it once startup is done (imports, the app,
    the fleet opened): objects made after it are collected as usual, and startup objects
    freed by their reference counts still are; only a reference cycle among frozen objects
    that dies later stays (``gc.freeze``'s documentation)."""
    gc.collect()
    gc.freeze()
    return gc.get_freeze_count()


def can_trim() -> bool:
    """Whether this process's C library can give free heap pages back (glibc)."""
    return _MALLOC_TRIM is not None


def trim_heap() -> bool:
    """Release the free pages of every ``malloc`` arena to the kernel; True if any were.

    Walks the arenas under their locks: a few milliseconds for a few hundred MB.
    """
    return _MALLOC_TRIM is not None and _MALLOC_TRIM(0) == 1


class HeapTrimmer:
    """Calls :func:`trim_heap` every ``interval_s`` [s] on a daemon thread until closed.

    ``interval_s <= 0`` or a C library without ``malloc_trim``: :meth:`start` does nothing.
    ``trims`` counts the calls that released memory.
    """

    def __init__(self, interval_s: float) -> None:
        self.interval_s = interval_s
        self.trims = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        if self.interval_s <= 0 or not can_trim() or self._thread is not None:
            return
        self._thread = threading.Thread(target=self._run, name="heap-trim", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self.interval_s):
            if trim_heap():
                self.trims += 1

    def close(self) -> None:
        """Stop the thread (waits for a trim under way); idempotent."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
