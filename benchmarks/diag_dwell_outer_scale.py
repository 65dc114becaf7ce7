"""Step-stare tables with a dwell against the exact generator (issue 29, dwell29k).

The model ``A_2(1..4)`` of a step-stare VAD whose rays dwell the fraction ``d`` of the
ray period, as the ε stage forms it (the pairs of one scan, no wrap:
``tests/physics/swept_reference.py``), over the exact ``D(1..4)`` per eps^(2/3) of
:func:`cwproc.sim.exact_gaussian.block_covariance` (Banakh et al. (1999), eqs. 15-16)
for the same pattern; von Kármán ``L_V`` 200 m, h 100 m, phi 35 deg, 18 m gate.

Run: ``PYTHONPATH=$PWD python3 benchmarks/diag_dwell_outer_scale.py [--rays 24]
[--ray-period 2 --dwell-s 1] [--mu 1 --mu 3]``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "physics"))

from swept_reference import estimator_a2, exact_d, tables, within_rotation_weights

from cwproc.physics.transfer import PulsedProbe
from cwproc.sim import exact_gaussian as eg

PHI, HEIGHT, L_V, GATE, PRF = 35.0, 100.0, 200.0, 18.0, 15000.0


def main() -> None:
    """Print model / exact of ``D(1..4)`` per case."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rays", type=int, action="append")
    parser.add_argument("--ray-period", type=float, action="append", help="s")
    parser.add_argument("--dwell-s", type=float, action="append", help="s, per ray period")
    parser.add_argument("--mu", type=float, action="append")
    parser.add_argument("--scale", type=float, default=L_V, help="L_V (m)")
    args = parser.parse_args()
    probe = PulsedProbe(15.3, GATE)
    range_m = HEIGHT / math.sin(math.radians(PHI))
    mus = args.mu or [0.0, 0.3, 1.0, 3.0]
    for rays in args.rays or [24, 36]:
        for period, dwell_s in zip(args.ray_period or [2.0], args.dwell_s or [1.0], strict=True):
            frac = dwell_s / period
            t0 = time.perf_counter()
            heights = (0.8 * HEIGHT, 1.25 * HEIGHT)
            step_stare = {"swept": False, "dwell": frac}
            pair = tables(probe, PHI, rays, heights, max(mus) + 0.5, (80.0, 1000.0), **step_stare)
            built = time.perf_counter() - t0
            weights = within_rotation_weights(rays, 60.0)
            pattern = eg.conical_pattern(
                rays, rays * period, continuous=False, pulses_per_ray=round(dwell_s * PRF)
            )
            v_s = 2 * math.pi * range_m * math.cos(math.radians(PHI)) / (rays * period)
            for mu in mus:
                model = estimator_a2(pair, HEIGHT, mu, args.scale, weights)
                exact = exact_d(pattern, PHI, range_m, mu * v_s, args.scale, GATE)
                ratio = " ".join(f"{r:.4f}" for r in model / exact[1:])
                print(
                    f"rays {rays} dwell {dwell_s:g}/{period:g} s (d {frac:.3f}) mu {mu:g}: "
                    f"model/exact D(1-4) {ratio}"
                    f"  (tables {built:.0f} s)",
                    flush=True,
                )


if __name__ == "__main__":
    main()
