"""The process's memory allocator, tuned only when the process's owner asks for it.

Library code never changes the allocator of the process it runs in: a notebook, a test
or a Dask worker keeps glibc's defaults. A process that cwproc owns (the ``cwproc``
program, :class:`cwproc.cli._group.CwprocGroup`; a batch worker,
:func:`cwproc.batch.worker.process_unit_task`) calls :func:`tune_allocator` once; from
then on the library's long phases run with the glibc thresholds that suit their arrays
(:func:`phase`). ``sf-type`` also keeps freed arrays for the whole run
(:func:`keep_freed_arrays`). All of it is glibc's ``mallopt``/``malloc_trim`` through
:mod:`ctypes`; with another C library nothing changes. The values computed never depend
on where an array lies, so the products are the same either way; only the time (page
faults) and the peak memory move.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from typing import Any, Literal

#: glibc ``mallopt`` parameters (``malloc.h``): free memory at the top of the heap above
#: which ``free`` returns it to the system; size from which ``malloc`` maps a block
#: apart; the number of arenas
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD, _M_ARENA_MAX = -1, -3, -8
#: while the chunks of a day are processed: arrays up to glibc's largest mmap threshold
#: (64-bit) come from the heap, and up to this much free heap is kept for the next
#: chunk's arrays (bytes)
HEAP_BLOCK_BYTES, HEAP_KEEP_BYTES = 32 << 20, 256 << 20
#: free heap kept at the top while the dissipation rate is fitted (its groups of blocks
#: make and drop arrays of the same sizes), bytes
DAY_FIT_KEEP_BYTES = 64 << 20
#: glibc's default trim threshold (bytes), set back after a phase
DEFAULT_TRIM_BYTES = 128 << 10

#: the C library once :func:`tune_allocator` found glibc; None: phases do nothing
_tuned: Any = None

Phase = Literal["chunks", "day_fit"]


def _glibc() -> Any:
    """The GNU C library of this process (with ``mallopt`` and ``malloc_trim``), or None."""
    if not sys.platform.startswith("linux"):
        return None
    import ctypes

    try:
        libc = ctypes.CDLL(None)  # the symbols of the process, its C library's among them
        libc.gnu_get_libc_version  # noqa: B018 -- glibc only (musl's mallopt does nothing)
        mallopt, trim = libc.mallopt, libc.malloc_trim
    except (OSError, AttributeError):
        return None
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    trim.argtypes, trim.restype = (ctypes.c_size_t,), ctypes.c_int
    return libc


def tune_allocator() -> bool:
    """Let the library's phases (:func:`phase`) set glibc's thresholds in this process.

    Called by the owner of the process (the ``cwproc`` program for ``retrieve``,
    ``plot`` and ``sf-type``; a batch worker before its first unit), never by library
    code. Nothing is set here: each phase sets its thresholds and restores the default
    trim threshold after it.

    Returns
    -------
    bool
        True when the process runs on glibc (the phases then act), else False.
    """
    global _tuned
    _tuned = _glibc()
    return _tuned is not None


def untune_allocator() -> None:
    """Phases do nothing again (the allocator as the process's owner left it)."""
    global _tuned
    _tuned = None


def tuned() -> bool:
    """Whether :func:`tune_allocator` was called in this process (and found glibc)."""
    return _tuned is not None


@contextlib.contextmanager
def phase(name: Phase) -> Iterator[None]:
    """Run a phase of a day's retrieval with the allocator set for its arrays.

    Does nothing unless the process's owner called :func:`tune_allocator`.

    ``"chunks"``: the chunks of a day. Each chunk's stages make and drop hundreds of
    arrays of a few MiB (the padded (scan, ray, gate) arrays of the fits, the structure
    function's); by default glibc maps such arrays apart or returns the freed heap top
    to the system, so every one is faulted in page by page and zeroed by the kernel
    again (about a third of the stages' time). Here arrays up to
    :data:`HEAP_BLOCK_BYTES` come from the heap and up to :data:`HEAP_KEEP_BYTES` of free
    heap is kept, so the next array reuses pages already resident; afterwards the free
    heap is given back (``malloc_trim``) and the default trim threshold restored.

    ``"day_fit"``: the dissipation rate of the day, after the chunks. The chunks' freed
    heap is given back first, so the step's peak is what it uses; up to
    :data:`DAY_FIT_KEEP_BYTES` of free heap is then kept while it runs, so that one
    group of blocks reuses the pages of the group before. For a day of 1920 scans the
    run then faults in about 116 000 pages instead of 280 000 (0.3-1.0 s), for a peak
    about 10 MiB higher.
    """
    libc = _tuned
    if libc is None:
        yield
        return
    if name == "chunks":
        libc.mallopt(_M_MMAP_THRESHOLD, HEAP_BLOCK_BYTES)
        libc.mallopt(_M_TRIM_THRESHOLD, HEAP_KEEP_BYTES)
    elif name == "day_fit":
        libc.malloc_trim(0)
        libc.mallopt(_M_TRIM_THRESHOLD, DAY_FIT_KEEP_BYTES)
    else:
        raise ValueError(f"unknown allocator phase {name!r}: 'chunks' or 'day_fit'")
    try:
        yield
    finally:
        libc.mallopt(_M_TRIM_THRESHOLD, DEFAULT_TRIM_BYTES)
        if name == "chunks":
            libc.malloc_trim(0)


def keep_freed_arrays() -> bool:
    """Let glibc's allocator reuse the memory of freed arrays for the rest of the process.

    glibc maps large blocks (numpy arrays of a few MB: a column of a day of 10.7 Hz
    samples is 7.4 MB) on their own and unmaps them when freed, and gives the free top
    of its heap back beyond a few MB; the next array then costs fresh pages, which the
    kernel zeroes on first touch. A day of ``sf-type`` allocates its temporaries many
    times over: about 0.4 s of system time of a 2-s run. With blocks of up to
    :data:`HEAP_BLOCK_BYTES` taken from the heap and up to :data:`HEAP_KEEP_BYTES` of
    free heap kept (``mallopt`` M_MMAP_THRESHOLD and M_TRIM_THRESHOLD, the settings of
    the ``MALLOC_MMAP_THRESHOLD_`` and ``MALLOC_TRIM_THRESHOLD_`` variables), the memory
    of freed arrays serves the next ones: the same results. With one arena for every
    thread (M_ARENA_MAX 1) the memory the reading threads free serves the main thread's
    arrays too, where each thread's own arena would keep it apart: a day's peak memory
    430 -> 290 MB. Called by the process's owner only (``cwproc sf-type``).

    Returns
    -------
    bool
        True when the three settings were taken (glibc), False elsewhere (macOS,
        Windows, musl: the allocator is left as it is).
    """
    libc = _glibc()
    if libc is None:
        return False
    settings = (
        (_M_ARENA_MAX, 1),
        (_M_MMAP_THRESHOLD, HEAP_BLOCK_BYTES),
        (_M_TRIM_THRESHOLD, HEAP_KEEP_BYTES),
    )
    return all([bool(libc.mallopt(key, value)) for key, value in settings])
