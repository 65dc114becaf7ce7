"""Speed of the dissipation-rate stage on a synthetic day (target: under 1 s once tabled).

A day of Stream Line conical scans in 10-minute blocks: 144 blocks x 100 heights x 4 lags
(azimuth step 2 deg, elevation 35.3 deg). The structure functions are the model
``eps^(2/3) A_2 + 2 sigma_e^2`` (Smalikho (2020), eq. 4) with random eps, mu and noise.
Prints the A-table build time (first use of a configuration), the time to load the
cached table, and the time of ``estimate_epsilon`` for the whole day.

Run::

    python benchmarks/bench_epsilon.py                   # model von_karman (preset default)
    python benchmarks/bench_epsilon.py --model inertial
"""

from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np
import xarray as xr

from cwproc.physics.transfer import PulsedProbe
from cwproc.stages.epsilon import estimate_epsilon
from cwproc.tables.atable import get_a_table

PHI, DTHETA, N_LAGS, T_SCAN = 35.3, 2.0, 4, 60.0


def synthetic_day(table, n_blocks: int = 144, n_heights: int = 100, seed: int = 0) -> xr.Dataset:
    """Structure-function dataset of one day, D_L from the inertial A-table."""
    rng = np.random.default_rng(seed)
    heights = np.linspace(40.0, 1500.0, n_heights)
    radius = heights / np.tan(np.deg2rad(PHI))
    v_s = 2 * np.pi * radius / T_SCAN
    mu = rng.uniform(0.0, 3.0, (n_blocks, n_heights))
    eps = 10 ** rng.uniform(-4, -2, (n_blocks, n_heights))
    noise = rng.uniform(0.05, 0.3, (n_blocks, n_heights))
    lags = np.arange(1, N_LAGS + 1)
    _, a2 = table.evaluate(lags[None, None, :], heights[None, :, None], mu[..., None])
    d = eps[..., None] ** (2 / 3) * a2 + 2 * noise[..., None] ** 2
    sigma2 = (eps * 500.0 / 0.6966) ** (2 / 3)
    return xr.Dataset(
        {
            "structure_function": (("time", "height", "lag"), d),
            "n_pairs": (("time", "height", "lag"), np.full(d.shape, 1500)),
            "radial_velocity_variance": (("time", "height"), sigma2 + noise**2),
            "wind_speed": (("time", "height"), mu * v_s[None, :]),
            "azimuth_step": ("time", np.full(n_blocks, DTHETA)),
            "scan_period": ("time", np.full(n_blocks, T_SCAN)),
            "n_scans": ("time", np.full(n_blocks, 10)),
        },
        coords={
            "time": np.datetime64("2024-01-01T00:05", "ns")
            + np.arange(n_blocks) * np.timedelta64(10, "m"),
            "height": heights,
            "range": ("height", heights / np.sin(np.deg2rad(PHI))),
            "lag": lags,
            "elevation": ("time", np.full(n_blocks, PHI)),
        },
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="von_karman", choices=["inertial", "von_karman"])
    parser.add_argument("--cache-dir", default=None, help="A-table cache (default: fresh)")
    args = parser.parse_args()
    cache = args.cache_dir or tempfile.mkdtemp(prefix="cwproc-bench-")
    probe = PulsedProbe()
    models = ["inertial"] + (["von_karman"] if args.model == "von_karman" else [])
    tables = {}
    for model in models:
        t0 = time.perf_counter()
        tables[model] = get_a_table(
            probe,
            phi_deg=PHI,
            delta_theta_deg=DTHETA,
            n_lags=N_LAGS,
            model=model,
            cache_dir=cache,
        )
        built = time.perf_counter() - t0
        t0 = time.perf_counter()
        get_a_table(
            probe,
            phi_deg=PHI,
            delta_theta_deg=DTHETA,
            n_lags=N_LAGS,
            model=model,
            cache_dir=cache,
        )
        loaded = time.perf_counter() - t0
        print(f"A-table {model:>10}: build {built:8.2f} s   cached load {loaded:6.3f} s")
    sf = synthetic_day(tables["inertial"])
    options = {"cache_dir": cache}
    estimate_epsilon(sf, probe=probe, lag_number=3, model=args.model, table_options=options)
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        out = estimate_epsilon(
            sf, probe=probe, lag_number=3, model=args.model, table_options=options
        )
        times.append(time.perf_counter() - t0)
    n = sf.sizes["time"] * sf.sizes["height"]
    valid = int(np.isfinite(out["epsilon"].values).sum())
    print(
        f"estimate_epsilon ({args.model}), {sf.sizes['time']} blocks x {sf.sizes['height']} "
        f"heights: best {min(times):.3f} s, median {np.median(times):.3f} s "
        f"(target < 1 s); {valid}/{n} estimates"
    )


if __name__ == "__main__":
    main()
