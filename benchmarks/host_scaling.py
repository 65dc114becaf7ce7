"""How many cores the shared host gives: two busy processes against one, in one call.

The speed-ups of ``cwproc batch`` on 2 workers (issue 15.2 and 15.4: >= 1.8x and 1.7x
one worker) can be no better than the host's own: on this 2-vCPU virtual machine two
pure-Python loops in two processes ran 1.18-2.14x as fast as one after the other within
ten minutes (2026-11-26), as the second vCPU was shared or not. The benchmarks print
this figure before and after their parallel runs, so that a speed-up is read against
what the machine gave at the time.

Run::

    python benchmarks/host_scaling.py
"""

from __future__ import annotations

import multiprocessing
import time

#: additions of the loop each process runs (about 0.3-0.4 s on the benchmark machine)
LOOP = 12_000_000


def busy_loop(_: int = 0) -> float:
    """A pure-Python loop (one core, no memory traffic); returns its wall time (s)."""
    t0 = time.perf_counter()
    total = 0
    for i in range(LOOP):
        total += i
    return time.perf_counter() - t0


def two_core_scaling(repeat: int = 3) -> float:
    """Twice the wall time of one :func:`busy_loop` over the wall time of two at once,
    both run by the same two worker processes (2.0: two full cores; 1.0: one), each
    the best of ``repeat``."""
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        pool.map(busy_loop, [0, 0])  # the processes started and warm
        one, both = [], []
        for _ in range(repeat):
            t0 = time.perf_counter()
            pool.map(busy_loop, [0])
            one.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            pool.map(busy_loop, [0, 1], chunksize=1)
            both.append(time.perf_counter() - t0)
    return 2.0 * min(one) / min(both)


def describe(when: str) -> str:
    """One line: the host's two-process scaling measured now."""
    return f"host: two busy processes ran {two_core_scaling():.2f}x as fast as one ({when})"


if __name__ == "__main__":
    print(describe("now"))
