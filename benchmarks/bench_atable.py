"""Build and evaluation time of the cached A-function tables (Stream Line preset).

A table (:func:`cwproc.tables.atable.get_a_table`) is built once per instrument
configuration and then read from the disk cache; the retrieval evaluates it for every
block, height and lag. This script times, in a fresh temporary cache directory:

- the cold build for the Stream Line probe (``configs/streamline.toml``: dp = 15.3 m,
  dR = 18 m, physical transfer function) at the elevations of typical VAD scans
  (``--phi``, default 60 and 75 deg) with ``--rays`` rays per scan (default 24, i.e.
  dtheta = 15 deg), ``--lags`` lags, heights 10-3000 m, mu up to 10, for the inertial
  model and (``--finite``) the von Karman model with L_V in 10-3000 m;
- the warm load from the cache;
- the evaluation for 144 blocks x 100 heights x ``--lags`` lags (random mu, and L_V for
  the finite-outer-scale table; seeded).

Run::

    python benchmarks/bench_atable.py                 # inertial tables, phi 60 and 75
    python benchmarks/bench_atable.py --finite        # + von Karman tables (slower build)
    python benchmarks/bench_atable.py --stare --phi 35 --finite   # step-stare VAD tables

Printed figures: build time (s), load time (ms), evaluation time (ms), table size (MiB)
and the peak resident memory of the run. Target: evaluation well under 1 s (measured
16-51 ms inertial, 70-77 ms von Karman; builds 0.5-0.7 s and 11 s on a shared 2-core box).
"""

from __future__ import annotations

import argparse
import math
import resource
import tempfile
import time

import numpy as np

from cwproc.config import load_config
from cwproc.pipeline import probe_from_config
from cwproc.tables.atable import get_a_table


def time_one(
    probe, phi: float, dtheta: float, lags: int, model: str, cache: str, swept: bool = True
) -> None:
    """Build, load and evaluate one table; print the figures."""
    kwargs = {"phi_deg": phi, "delta_theta_deg": dtheta, "n_lags": lags, "model": model}
    kwargs["swept"] = swept
    t0 = time.perf_counter()
    table = get_a_table(probe, cache_dir=cache, **kwargs)
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    table = get_a_table(probe, cache_dir=cache, **kwargs)
    t_load = time.perf_counter() - t0
    rng = np.random.default_rng(20240601)
    blocks, heights = 144, 100
    h = np.geomspace(30.0, 2500.0, heights)[None, :, None]
    lag = np.arange(1, lags + 1)[None, None, :]
    mu = rng.uniform(0.0, 4.0, (blocks, heights, 1))
    outer = rng.uniform(50.0, 800.0, (blocks, heights, 1)) if model != "inertial" else None
    t0 = time.perf_counter()
    _a1, a2 = table.evaluate(lag, h, mu, outer)
    t_eval = time.perf_counter() - t0
    size = (table.log_a1.nbytes + table.log_a2.nbytes) / 2**20
    print(
        f"phi={phi:4.1f} deg dtheta={dtheta:5.2f} deg lags={lags} model={model:10s} "
        f"grid={table.log_a2.shape}  build {t_build:7.1f} s  load {1e3 * t_load:6.1f} ms  "
        f"evaluate {a2.size} points {1e3 * t_eval:6.1f} ms  size {size:6.2f} MiB  "
        f"finite {np.isfinite(a2).mean():.3f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--phi", type=float, nargs="+", default=[60.0, 75.0])
    parser.add_argument("--rays", type=int, default=24, help="rays per 360 deg scan")
    parser.add_argument("--lags", type=int, default=3)
    parser.add_argument("--finite", action="store_true", help="also von Karman tables")
    parser.add_argument("--stare", action="store_true", help="step-stare rays (swept=False)")
    args = parser.parse_args()
    cfg = load_config("streamline")
    probe = probe_from_config(cfg.instrument, pulse_transfer=cfg.turbulence.pulse_transfer)
    dtheta = 360.0 / args.rays
    models = ["inertial", "von_karman"] if args.finite else ["inertial"]
    print(f"probe: {probe}; dtheta = {dtheta:g} deg; l dtheta up to {args.lags * dtheta:g} deg")
    if args.lags * dtheta > 9.0 + 1e-9:
        print(f"note: l dtheta > 9 deg is outside Smalikho (2020) eq. 4 ({math.ceil(dtheta)} deg)")
    with tempfile.TemporaryDirectory(prefix="cwproc-bench-atable-") as cache:
        for model in models:
            for phi in args.phi:
                time_one(probe, phi, dtheta, args.lags, model, cache, not args.stare)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak resident memory {peak:.0f} MiB")


if __name__ == "__main__":
    main()
