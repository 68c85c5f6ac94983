"""The heap trimmer gives freed C-heap pages back, and the server runs one."""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from support import wait_for

from fleet.io.heap import HeapTrimmer, can_trim, limit_arenas, trim_heap
from fleet.io.settings import load_settings
from fleet.service.host import open_fleet

pytestmark = pytest.mark.skipif(not can_trim(), reason="no malloc_trim in this C library")

_PAGE = os.sysconf("SC_PAGE_SIZE")
CHUNK = 64 * 1024  # below glibc's mmap threshold: served from the heap
CHUNKS = 400  # 25 MB


def _rss() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * _PAGE


def _holes_in_the_heap() -> list[int]:
    """Fill 2 x CHUNKS heap chunks and free every other one: 25 MB free between chunks still
    in use, where free() cannot return it. Returns the chunks kept (free them afterwards)."""
    libc = ctypes.CDLL(ctypes.util.find_library("c"))
    libc.malloc.restype = ctypes.c_void_p
    libc.malloc.argtypes = [ctypes.c_size_t]
    libc.free.argtypes = [ctypes.c_void_p]
    chunks = []
    for _ in range(2 * CHUNKS):
        chunk = libc.malloc(CHUNK)
        ctypes.memset(chunk, 1, CHUNK)  # resident
        chunks.append(chunk)
    for chunk in chunks[1::2]:
        libc.free(chunk)
    return chunks[0::2]


def _free(pins: list[int]) -> None:
    libc = ctypes.CDLL(ctypes.util.find_library("c"))
    libc.free.argtypes = [ctypes.c_void_p]
    for pin in pins:
        libc.free(pin)


def test_trim_gives_free_pages_in_the_middle_of_the_heap_back() -> None:
    pins = _holes_in_the_heap()
    try:
        held = _rss()
        assert trim_heap()
        released = held - _rss()
        assert released > CHUNK * CHUNKS // 2, f"released {released / 2**20:.1f} MB"
    finally:
        _free(pins)


def test_the_trimmer_trims_until_closed_and_zero_means_never() -> None:
    never = HeapTrimmer(0.0)
    never.start()
    assert not any(t.name == "heap-trim" for t in threading.enumerate())
    never.close()

    trimmer = HeapTrimmer(0.01)
    trimmer.start()
    try:
        pins = _holes_in_the_heap()
        try:
            wait_for(lambda: trimmer.trims >= 1, 60.0, "a trim that released memory")
        finally:
            _free(pins)
    finally:
        trimmer.close()
    assert not any(t.name == "heap-trim" for t in threading.enumerate())


#: Eight threads alive at once, each allocating, then glibc's per-arena statistics.
ARENA_PROBE = """
import ctypes, sys, threading
from fleet.io.heap import limit_arenas
if int(sys.argv[1]):
    assert limit_arenas(int(sys.argv[1]))
gate = threading.Barrier(9)
def work():
    buf = bytearray(100_000)
    gate.wait(); gate.wait()
threads = [threading.Thread(target=work) for _ in range(8)]
for t in threads: t.start()
gate.wait()
ctypes.CDLL(None).malloc_stats()
gate.wait()
for t in threads: t.join()
"""


def _arenas(limit: int) -> int:
    probe = subprocess.run(
        [sys.executable, "-c", ARENA_PROBE, str(limit)], capture_output=True, text=True, check=True
    )
    return sum(line.startswith("Arena ") for line in probe.stderr.splitlines())


def test_limit_arenas_caps_the_arenas_of_threads_allocating_at_once() -> None:
    assert _arenas(0) >= 5  # glibc's default: a new arena per thread, up to 8 per core
    assert _arenas(2) == 2
    assert not limit_arenas(0)  # 0: the default is left alone


def test_the_server_runs_a_trimmer_while_open(tmp_path: Path) -> None:
    settings = load_settings(data_dir=tmp_path, listen=["tcp/127.0.0.1:0"])
    with open_fleet(settings):
        assert any(t.name == "heap-trim" for t in threading.enumerate())
    assert not any(t.name == "heap-trim" for t in threading.enumerate())
