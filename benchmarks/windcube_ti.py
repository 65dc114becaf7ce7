"""TI and mean wind of the virtual WindCube: .rtd (DBS, each correction) and .sta vs truth.

Usage: ``python3 benchmarks/windcube_ti.py [N_SEEDS] [CNR_DB_GROUND]``: N_SEEDS fields x 4
lidar positions, 10 min each; prints per height the mean (estimate - truth) +- its
standard error over the realisations (cwproc.sim.windcube.ti_trials).
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace

from cwproc.sim.windcube import WindCubeSpec, bias_table, ti_trials


def main(argv: list[str]) -> None:
    n_seeds = int(argv[0]) if argv else 8
    spec = WindCubeSpec()
    if len(argv) > 1:
        spec = replace(spec, cnr_db_ground=float(argv[1]))
    origins = [(0.0, 600.0 * k, 0.0) for k in range(4)]
    start = time.process_time()
    trials = ti_trials(spec, [100 + k for k in range(n_seeds)], origins)
    n = trials["truth_ti"].shape[0]
    print(
        f"{n} realisations of 10 min, heights {spec.heights_m} m, CNR "
        f"{spec.cnr_db_ground:g} dB at the ground ({spec.cnr_db_per_100m:g} dB/100 m), "
        f"{time.process_time() - start:.0f} s CPU"
    )
    print("truth TI  ", "  ".join(f"{x:.4f}" for x in trials["truth_ti"].mean(axis=0)))
    print("truth U   ", "  ".join(f"{x:.3f}" for x in trials["truth_speed"].mean(axis=0)))
    for c in "uvw":
        truth = trials[f"truth_{c}_variance"].mean(axis=0)
        print(f"truth var {c}", "  ".join(f"{x:.3f}" for x in truth))
    for name, (bias, se) in bias_table(trials).items():
        cells = "  ".join(f"{b:+.4f} +- {s:.4f}" for b, s in zip(bias, se, strict=True))
        print(f"{name:32s} {cells}")


if __name__ == "__main__":
    main(sys.argv[1:])
