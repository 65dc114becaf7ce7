"""Benchmark: the full seed-000 Monte-Carlo error study (target: under 2 minutes on 2 cores).

Run ``python benchmarks/bench_montecarlo.py [REALISATIONS]``; prints the wall time,
the peak resident memory and the error table (Banakh et al. (1999), Figs. 5-7).
"""

from __future__ import annotations

import resource
import sys
import time

from cwproc.config import SimulationConfig
from cwproc.sim.montecarlo import format_table, run_study

TARGET_S = 120.0


def main() -> None:
    realisations = int(sys.argv[1]) if len(sys.argv) > 1 else 1000
    start = time.perf_counter()
    cpu_start = time.process_time()
    study = run_study(SimulationConfig(), realisations=realisations, seed=0)
    elapsed = time.perf_counter() - start
    cpu = time.process_time() - cpu_start
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(format_table(study))
    print()
    print(
        f"montecarlo: {realisations} realisations x 10 scans x 6 heights in {elapsed:.1f} s "
        f"wall, {cpu:.1f} s CPU (all threads; target < {TARGET_S:.0f} s wall on 2 idle "
        f"cores: {'met' if elapsed < TARGET_S else 'MISSED'}), peak RSS {peak_mb:.0f} MB"
    )


if __name__ == "__main__":
    main()
