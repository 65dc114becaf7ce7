"""Stare eps on exact-statistics stares of 18, 30 and 48 m gates and a sparse stare (issue 29).

Each row: independent 300-s windows of Gaussian w with the exact covariance of a
Kolmogorov field (eps = 0.01 m2 s-3) averaged over the pulsed weighting of the gate
(Delta_p 15.3 m, Delta_R the gate) and over each ray's dwell (20000 pulses at 15 kHz,
1.33 s), carried past at U = 5 m/s, white noise of the sigma_e the SNR (0.05) predicts
(:func:`cwproc.sim.stare.exact_stare_trial`), through
:func:`cwproc.stages.stare.stare_product` with its defaults: the probe from the file's
gate length, the variance windows from the ray rate. Printed: mean eps_hat/eps +- its
standard error, median, the mean reported standard error over the observed scatter
(calibrated: 0.8-1.25), the share of windows whose +-1 SE holds the truth.

Run::

    python benchmarks/bench_stare_gates.py              # 400 / 2000 windows, ~1 min
    python benchmarks/bench_stare_gates.py --windows 120
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from cwproc.sim.stare import exact_stare_trial

#: (gate length m, ray interval s): back-to-back 1.33-s rays, and one ray every 25 s
CASES = ((18.0, 4 / 3), (30.0, 4 / 3), (48.0, 4 / 3), (30.0, 25.0))


def row(gate: float, interval: float, windows: int) -> str:
    """One line of the table."""
    start = time.perf_counter()
    trial = exact_stare_trial(gate_length_m=gate, ray_interval_s=interval, n_windows=windows)
    ratio, se = trial["ratio"], trial["se_ratio"]
    ok = np.isfinite(ratio)
    x, s = ratio[ok], se[ok]
    scatter = float(np.std(x, ddof=1))
    return (
        f"| {gate:g} | {interval:.3g} | {trial['variance_window_s']:g} | {ok.sum()}/{ok.size} "
        f"| {x.mean():.3f} ± {scatter / np.sqrt(x.size):.3f} | {np.median(x):.3f} "
        f"| {s.mean() / scatter:.2f} | {np.mean(np.abs(x - 1) < s):.2f} "
        f"| {time.perf_counter() - start:.1f} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--windows", type=int, default=400, help="windows per dense row")
    parser.add_argument(
        "--sparse-windows", type=int, default=2000, help="windows of the sparse row"
    )
    args = parser.parse_args()
    print(
        "| gate (m) | ray every (s) | T (s) | windows with eps | mean eps/eps ± s.e. "
        "| median | SE / scatter | truth in ±1 SE | time (s) |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for gate, interval in CASES:
        n = args.windows if interval < 2 else args.sparse_windows
        print(row(gate, interval, n), flush=True)


if __name__ == "__main__":
    main()
