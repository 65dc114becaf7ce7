"""The 72-ray continuous scan at mu 3 of ``../shared/reference/exact-D-72ray-mu3.md`` (issue 29).

Independent reference values of the exact expected ``D(l)`` (lags 1-4) and variance of
``V_r`` of a 72-ray continuous scan whose field the wind carries three ray spacings
during each ray (von Kármán, eps 0.01 m2 s-3, L_V 150 m, 35.3 deg, rotation 230.757 s,
wind towards 60 deg at mu = 3 per gate, 18 m or 30 m gate). Prints, per gate,

- ``model``: the A-tables' ``eps^(2/3) A_2(l)`` (von Kármán, L_V 150 m) over the reference,
  as the ε stage forms it for the pairs the reference averages (:func:`estimator_a2`:
  the ``72 - l`` pairs of lag ``l`` within a rotation, which do not wrap), and in
  brackets the tables' circle mean (0.3-0.7 % lower here, growing with the lag);
- ``variance``: the model's passed variance of ``V_r`` over the reference, with the
  transport during the ray (:func:`cwproc.physics.probe_variance.segment_loss`) and
  without it (the sweep's ``H_perp`` alone);
- with ``--blocks N``: the generator's exact ``D(l)`` and variance (its covariance, no
  sampling) over the reference, and eps_hat / eps, L_V_hat / L_V of the user's chain
  on ``N`` exact-statistics blocks of 10 scans (sigma_e 0.1 m s-1).

Run::

    python benchmarks/bench_reference_72ray.py                # tables and variance (s)
    python benchmarks/bench_reference_72ray.py --blocks 40    # + generator and eps (min)
    python benchmarks/bench_reference_72ray.py --gate 30

Measured 2026-11-29 (issue 29, swept29: the outer scale's difference through the sweep
kernel), model D(1-4) / reference; before (7ab8b20) the circle mean read 0.984-0.989 and
the within-rotation weighting 0.987-0.995::

    gate 18 m  165 m 0.9962 0.9979 0.9983 0.9985   (generator 0.9964 0.9983 0.9988 0.9990)
               195 m 0.9967 0.9978 0.9982 0.9984   (generator 0.9968 0.9981 0.9987 0.9989)
               225 m 0.9963 0.9976 0.9980 0.9975   (generator 0.9965 0.9980 0.9986 0.9982)
    gate 30 m  165 m 0.9961 0.9981 0.9984 0.9987
               195 m 0.9962 0.9979 0.9983 0.9985
               225 m 0.9960 0.9977 0.9980 0.9975

The model is within 0.07 % of the generator's exact D at every gate and lag; the lag-1
shortfall of both (0.33-0.40 %) is the reference's: the direct two-beam sum
(:func:`cwproc.physics.two_beam.two_beam_structure_function`, 6 / 12 / 24 sub-beams,
extrapolated) gives 0.9965 of it at 225 m as well, and its quadrature moves D(1) by up
to 0.35 %. Passed variance 0.9963 / 0.9948 / 0.9931 (unchanged).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "physics"))

from swept_reference import estimator_a2, within_rotation_weights
from swept_reference import tables as reference_tables

from cwproc.config import load_config
from cwproc.physics.geometry import wind_components
from cwproc.physics.probe_variance import passed_variance, segment_loss
from cwproc.physics.transfer import PulsedProbe
from cwproc.pipeline import process_scans
from cwproc.sim import exact_gaussian as eg

PHI, EPS, L_V, NOISE = 35.3, 0.01, 150.0, 0.1
RANGES = (165.0, 195.0, 225.0)
SPEEDS = (11.0, 13.0, 15.0)
PERIOD = 230.757
#: reference D(1..4) and variance of V_r per gate (exact-D-72ray-mu3.md)
REFERENCE = {
    18.0: (
        (0.48710, 1.06561, 1.47860, 1.78171, 1.31190),
        (0.55169, 1.17382, 1.59478, 1.88934, 1.28910),
        (0.60971, 1.26531, 1.68715, 1.97017, 1.26673),
    ),
    30.0: (
        (0.4682, 1.0379, 1.4490, 1.7514, 1.2963),
        (0.5332, 1.1476, 1.5671, 1.8612, 1.2747),
        (0.5916, 1.2405, 1.6612, 1.9439, 1.2533),
    ),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gate", type=float, default=18.0, choices=sorted(REFERENCE))
    parser.add_argument("--blocks", type=int, default=0, help="exact-statistics blocks (0: none)")
    args = parser.parse_args()
    probe = PulsedProbe(15.3, args.gate)
    tables = reference_tables(probe, PHI, 72, (80.0, 150.0), 4.0)
    weights = within_rotation_weights(72, 60.0)
    e23 = EPS ** (2.0 / 3.0)
    config = load_config("streamline")
    config = dataclasses.replace(
        config,
        turbulence=dataclasses.replace(config.turbulence, n_scans=10),
        instrument=dataclasses.replace(config.instrument, delta_r_m=args.gate),
    )
    pattern = eg.conical_pattern(72, PERIOD, continuous=True)
    print(f"72-ray continuous scan, mu 3, gate {args.gate:g} m: ratios to the reference")
    for g, (range_m, speed, ref) in enumerate(
        zip(RANGES, SPEEDS, REFERENCE[args.gate], strict=True)
    ):
        ref = np.asarray(ref)
        height = range_m * math.sin(math.radians(PHI))
        circle = tables[1].evaluate(np.arange(1, 5), height, 3.0, L_V)[1]
        model = estimator_a2(tables, height, 3.0, L_V, weights)
        dy = math.radians(5.0) * range_m * math.cos(math.radians(PHI))
        plain = passed_variance(probe, [dy], [range_m], "von_karman", [L_V])[0, 0]
        lost = segment_loss(probe, [dy], [range_m], [3.0], phi_deg=PHI, swept=True)[0, 0]
        print(
            f"gate {range_m:g} m: model D(1-4) {np.round(model * e23 / ref[:4], 4)} (circle "
            f"mean {np.round(circle * e23 / ref[:4], 4)}), variance "
            f"{(plain - lost) * e23 / ref[4]:.4f} (sweep alone {plain * e23 / ref[4]:.4f})",
            flush=True,
        )
        if args.blocks <= 0:
            continue
        u, v = wind_components(speed, 240.0)
        cov = eg.block_covariance(
            pattern,
            1,
            elevation_deg=PHI,
            range_m=range_m,
            epsilon=EPS,
            outer_scale_m=L_V,
            mean_wind=(u, v, 0.0),
            delta_r_m=args.gate,
        )
        diag = np.diag(cov)
        exact = [np.mean(diag[lag:] + diag[:-lag] - 2 * np.diag(cov, lag)) for lag in (1, 2, 3, 4)]
        scans = eg.gaussian_scans(
            pattern=pattern,
            n_scans=10,
            n_blocks=args.blocks,
            elevation_deg=PHI,
            ranges_m=[range_m],
            epsilon=EPS,
            outer_scale_m=L_V,
            wind_speed_m_s=speed,
            wind_direction_deg=240.0,
            noise_std_m_s=NOISE,
            seed=7 + g,
            delta_r_m=args.gate,
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            turb = process_scans(scans, config, [])["turbulence"]
        eps = turb["epsilon"].values[:, 0] / EPS
        eps = eps[np.isfinite(eps)]
        scale = np.nanmean(turb["integral_scale"].values[:, 0]) / L_V
        print(
            f"   generator D(1-4) {np.round(np.array(exact) / ref[:4], 4)}, variance "
            f"{diag.mean() / ref[4]:.4f}; eps {eps.mean():.3f} ± "
            f"{eps.std(ddof=1) / np.sqrt(eps.size):.3f}, L_V {scale:.3f} ({args.blocks} blocks)",
            flush=True,
        )


if __name__ == "__main__":
    main()
