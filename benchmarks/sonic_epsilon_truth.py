"""Sonic eps against the virtual sonic's exact truth, per structure-function type.

Each realisation is an independent record of the virtual sonic
(:mod:`cwproc.sim.sonic`, Gaussian processes with the prescribed structure function
sampled at 10.7 Hz as the instrument samples, Taylor lag r = V_h tau); the product of
:func:`cwproc.stages.sonic_turbulence.sonic_turbulence` (30-min windows) is compared
with the truth of each component:

* type 1 (D = C r^(2/3)): eps = (C / C_ii)^(3/2);
* type 3 with a 2/3 tail (parabola to r_S = 3 m, then D = C 10^(y_S) (r/r_S)^(2/3)):
  eps = (C 10^(y_S - 2/3 lg r_S) / C_ii)^(3/2);
* type 2 (a parabola, no power law): the apparent eps of the prescribed D over the
  range the product chose, the geometric mean of D/(C_ii r^(2/3)) there (the type-2
  figure tests the estimator, not the existence of an inertial range).

Prints bias = mean(eps/eps_true) - 1 +/- s.e., the scatter of eps/eps_true and the
mean stated relative error; ``--realisations N`` (default 40).

    PYTHONPATH=. python3 benchmarks/sonic_epsilon_truth.py --realisations 40
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from cwproc.physics.sonic_turbulence import C2_LONGITUDINAL, C2_TRANSVERSE
from cwproc.sim.sonic import METEO2_RATE_HZ, SFModel, default_models, simulate_sonic_dataset
from cwproc.stages.sonic_turbulence import sonic_turbulence

CONSTANTS = (C2_LONGITUDINAL, C2_TRANSVERSE, C2_TRANSVERSE)


def models_for(case: str) -> tuple[SFModel, SFModel, SFModel]:
    """The three component models of a case (type 1, 2, or 3 with a 2/3 tail)."""
    if case == "type3":
        return tuple(replace(m, slope=2.0 / 3.0) for m in default_models(3))
    return default_models(int(case[-1]))


def true_epsilon(model: SFModel, constant: float, r_lo: float, r_hi: float, speed: float) -> float:
    """eps of the prescribed D over the lags r_lo..r_hi (exact for a 2/3 power law)."""
    step = speed / METEO2_RATE_HZ
    r = np.arange(1, int(r_hi / step) + 2) * step
    r = r[(r >= r_lo - 1e-9) & (r <= r_hi + 1e-9)]
    e23 = np.exp(np.mean(np.log(model.structure_function(r) / (constant * r ** (2 / 3)))))
    return float(e23**1.5)


def run(case: str, realisations: int, speed: float = 6.0) -> dict[str, np.ndarray]:
    """eps/eps_true and stated relative errors of every window and component."""
    models = models_for(case)
    ratio, stated, no_range = [], [], 0
    for seed in range(realisations):
        ds = simulate_sonic_dataset(hours=1.0, models=models, seed=1000 + seed, speed=speed)
        out = sonic_turbulence(ds)
        eps = out["epsilon_component"].values
        err = out["epsilon_component_error"].values
        lo, hi = out["inertial_range_min"].values, out["inertial_range_max"].values
        for w in range(eps.shape[0]):
            for c in range(3):
                if not np.isfinite(eps[w, c]):
                    no_range += 1
                    continue
                truth = true_epsilon(models[c], CONSTANTS[c], lo[w, c], hi[w, c], speed)
                ratio.append(eps[w, c] / truth)
                stated.append(err[w, c] / eps[w, c])
    return {"ratio": np.array(ratio), "stated": np.array(stated), "no_range": no_range}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--realisations", type=int, default=40)
    args = parser.parse_args()
    print("case   n   no_range  bias(eps/true-1) +/- s.e.   scatter  mean stated rel. error")
    for case in ("type1", "type2", "type3"):
        res = run(case, args.realisations)
        q = res["ratio"]
        print(
            f"{case}  {q.size:4d} {res['no_range']:5d}   {q.mean() - 1:+.3f} +/- "
            f"{q.std(ddof=1) / np.sqrt(q.size):.3f}        {q.std(ddof=1):.3f}    "
            f"{np.mean(res['stated']):.3f}"
        )


if __name__ == "__main__":
    main()
