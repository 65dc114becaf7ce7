"""Benchmark: a month (744 h) of synthetic 10.7 Hz sonic data typed end to end.

Target (issue "Sonic anemometers"): under 60 s wall time and under 2 GB peak memory on
2 cores. The record is generated in one-hour chunks by the virtual sonic
(:mod:`cwproc.sim.sonic`) and typed one UTC day at a time by
:func:`cwproc.stages.sonic_sf.structure_function_types`, in ``--workers`` processes;
only the per-window results are kept (the per-lag arrays are dropped), so memory stays
bounded by one day per worker. Prints wall time, peak RSS and the type occurrence.

Run::

    python benchmarks/bench_sonic_sf.py               # 744 h, 2 workers
    python benchmarks/bench_sonic_sf.py --hours 48 --workers 1
"""

from __future__ import annotations

import argparse
import os
import resource
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import xarray as xr

from cwproc.sim.sonic import iter_sonic_chunks
from cwproc.stages.sonic_sf import structure_function_types
from cwproc.stages.sonic_sf_tables import parameter_statistics, type_occurrence

PER_LAG = ("lag_distance", "normalised_sf", "normalised_sf_fit", "n_pairs")


def type_one_day(args: tuple[int, int, int]) -> xr.Dataset:
    """Generate and type one day (``day`` index) of the month; per-window results only."""
    day, hours, seed = args
    start = np.datetime64("2014-06-01T00:00:00") + np.timedelta64(day, "D")
    chunks = list(
        iter_sonic_chunks(
            hours=hours,
            sf_type=1 + day % 3,
            seed=seed + day,
            start=str(start),
        )
    )
    day_ds = xr.concat(chunks, dim="time")
    del chunks
    sf = structure_function_types(day_ds)
    return sf.drop_vars([v for v in PER_LAG if v in sf], errors="ignore").drop_dims("sf_lag")


def peak_rss_mb() -> tuple[float, float]:
    """Peak resident set size (MB) of this process and of its largest child."""
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    child = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    return own, child


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=744.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    n_days = int(np.ceil(args.hours / 24))
    jobs = [(d, min(24.0, args.hours - 24 * d), args.seed) for d in range(n_days)]
    t0 = time.perf_counter()
    if args.workers > 1:
        with ProcessPoolExecutor(max_workers=args.workers) as pool:
            days = list(pool.map(type_one_day, jobs))
    else:
        days = [type_one_day(j) for j in jobs]
    month = xr.concat(days, dim="window")
    occurrence = type_occurrence(month)
    stats = parameter_statistics(month)
    wall = time.perf_counter() - t0
    own, child = peak_rss_mb()
    cpu = sum(
        getattr(resource.getrusage(who), f)
        for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)
        for f in ("ru_utime", "ru_stime")
    )
    n_samples = round(args.hours * 3600 * 10.7)
    print(f"hours: {args.hours:g} ({n_samples:,} samples x 3 components at 10.7 Hz)")
    print(f"windows typed: {month.sizes['window']} x 3 components, workers: {args.workers}")
    print(f"wall time: {wall:.1f} s (target < 60 s); CPU time {cpu:.1f} s")
    print(f"load average at the end: {os.getloadavg()[0]:.1f} (others share the cores)")
    print(f"peak RSS: main {own:.0f} MB, largest worker {child:.0f} MB (target < 2048 MB)")
    print(occurrence.round(2).to_string())
    print(stats[stats["count"] > 0].round(3).to_string(index=False))


if __name__ == "__main__":
    main()
