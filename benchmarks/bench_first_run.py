"""Seconds of table work of the first retrieve of a new geometry (issue 30, item 1).

The first ``retrieve`` of an instrument geometry (gate length, pulse, elevation, ray
count, range) builds every table the ε stage requests: the inertial A-table and the
table of the preset's spectrum model (:func:`cwproc.stages.epsilon.atable_fit.a_tables`,
with the lags of :func:`cwproc.stages.structure.lag_count` and the height range of
:func:`cwproc.stages.epsilon.atable_fit.table_height_range`), the removed-share
curve of the elevation (:func:`cwproc.tables.removed_share.mean_removed_share`) and,
for full circles of up to ``MAX_SECTOR_RAYS`` (60) rays, the correlated-circle factors
of the error bars (:func:`cwproc.tables.scan_factor.circle_variance_factor`, called by
:func:`cwproc.stages.epsilon.errors.correlated_scans_covariance`): one table per node of
``FACTOR_MU`` that the day's ``mu = U/V_s`` reaches, here those of winds of 1-15 m/s
(the day of ``bench_epsilon_day.py``) at the geometry's heights, scan period and the
preset's scans per block, consecutive circles. Denser circles request no factor. This
script times them in a cold temporary cache (``XDG_CACHE_HOME``, where the factors are
kept too) for five geometries that are not shipped in ``cwproc/atables/`` (checked: the
script stops if one is; the samples' 30 m / 180-ray scans at 35.3 deg ship, so that
geometry is timed at another site's elevation, 30 deg), one process, one core:

    python benchmarks/bench_first_run.py                 # all five
    python benchmarks/bench_first_run.py --only 0 3      # some of them

Printed: wall and CPU seconds per geometry, wall seconds per table (with the number of
scan-factor nodes built). Target (issue 30): at most 10 s each on one core.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Geometry:
    """One instrument geometry: preset, probe lengths, elevation, rays and gates."""

    name: str
    preset: str
    phi_deg: float
    rays: int
    heights_m: np.ndarray
    swept: bool = True
    delta_r_m: float | None = None  # gate length of a pulsed probe (m); preset's if None
    scan_period_s: float = 36.0  # one circle (s): V_s = 2 pi R' / T_scan, so the day's mu


def _gates(length: float, n: int, phi: float) -> np.ndarray:
    return (np.arange(n) + 0.5) * length * np.sin(np.radians(phi)) + 3 * length


GEOMETRIES = [
    Geometry(  # the samples' 30 m / 180-ray scans at another site's elevation
        "Stream Line 30 m gates, 180 rays, phi 30",
        "streamline",
        30.0,
        180,
        _gates(30.0, 100, 30.0),
        True,
        30.0,
        36.0,  # 0.2 s a ray
    ),
    Geometry(
        "Stream Line 48 m gates, 72 rays, phi 60",
        "streamline",
        60.0,
        72,
        _gates(48.0, 60, 60.0),
        True,
        48.0,
        36.0,  # 0.5 s a ray
    ),
    Geometry(
        "Stream Line step-stare, 24 rays, phi 75",
        "streamline",
        75.0,
        24,
        _gates(18.0, 100, 75.0),
        False,
        scan_period_s=72.0,  # 3 s a ray, as bench_epsilon_day.py
    ),
    Geometry(
        "cw (Banakh-like) focus 50-300 m, 100 rays, phi 45",
        "banakh1999",
        45.0,
        100,
        np.geomspace(50.0, 300.0, 8),
        True,
        scan_period_s=7.0,  # Banakh et al. (1999)
    ),
    Geometry(
        "ZephIR 300, 36 rays, phi 60",
        "zephir300",
        60.0,
        36,
        np.array([10.0, 20, 40, 60, 80, 100, 150, 200]),
        True,
        scan_period_s=1.0,  # one rotation a second
    ),
]


#: wind speeds (m s-1) of the day whose scan factors are requested (bench_epsilon_day.py)
WIND_M_S = np.linspace(1.0, 15.0, 29)


def _request(geo: Geometry) -> tuple:
    """``(probe, phi, dtheta, n_lags, model, options)`` of the tables a retrieve requests."""
    import dataclasses

    from cwproc.config import load_config
    from cwproc.pipeline import probe_from_config
    from cwproc.stages.epsilon.atable_fit import table_height_range
    from cwproc.stages.structure import lag_count

    cfg = load_config(geo.preset)
    instrument = cfg.instrument
    if geo.delta_r_m is not None:
        instrument = dataclasses.replace(instrument, delta_r_m=geo.delta_r_m)
    probe = probe_from_config(instrument, pulse_transfer=cfg.turbulence.pulse_transfer)
    dtheta = 360.0 / geo.rays
    n_lags = max(2, lag_count(dtheta, 9.0))
    options = {"height_range_m": table_height_range(geo.heights_m), "swept": geo.swept}
    return probe, geo.phi_deg, dtheta, n_lags, cfg.turbulence.model, options


def shipped_tables(geo: Geometry) -> list[str]:
    """The tables of ``geo`` that ship in ``cwproc/atables/`` (none, for a fair timing)."""
    from cwproc.tables import atable

    probe, phi, dtheta, n_lags, model, options = _request(geo)
    found = []
    for name in dict.fromkeys(["inertial", model]):
        params = atable.table_parameters(
            probe, phi_deg=phi, delta_theta_deg=dtheta, n_lags=n_lags, model=name, **options
        )
        path = atable.shipped_path(atable.table_key(params))
        if path.exists():
            found.append(path.name)
    return found


def time_scan_factors(geo: Geometry, probe: object, model: str) -> str:
    """The scan-factor tables a day of ``geo`` requests, built in the current cache.

    :func:`cwproc.tables.scan_factor.circle_variance_factor` as the ε stage calls it, for
    cells at the geometry's heights with the winds :data:`WIND_M_S` (``mu = U/V_s``,
    ``V_s = 2 pi R'/T_scan`` with ``R'`` of the probe centre, as
    :mod:`cwproc.stages.epsilon.cells`), the preset's scans per block and consecutive
    circles. Returns the table's part of the printed line (nodes: the tables written).
    """
    from cwproc.config import load_config
    from cwproc.physics.removed_share import MAX_SECTOR_RAYS
    from cwproc.tables.scan_factor import circle_variance_factor
    from cwproc.tables.store import default_cache_dir

    if geo.rays > MAX_SECTOR_RAYS:
        return f"scan factors: none ({geo.rays} rays > {MAX_SECTOR_RAYS})"
    n_scans = load_config(geo.preset).turbulence.n_scans
    phi = np.radians(geo.phi_deg)
    radius = probe.centre_range(geo.heights_m / np.sin(phi)) * np.cos(phi)
    mu = (WIND_M_S[:, None] * geo.scan_period_s / (2.0 * np.pi * radius[None, :])).ravel()
    cells = np.ones(mu.size)
    before = set(default_cache_dir().glob("scan-factor-*"))
    t0 = time.perf_counter()
    circle_variance_factor(
        geo.rays * cells, n_scans * cells, cells, mu, cells, np.nan * cells, geo.phi_deg, model
    )
    seconds = time.perf_counter() - t0
    nodes = len(set(default_cache_dir().glob("scan-factor-*")) - before)
    return (
        f"scan factors ({geo.rays} rays, {n_scans} scans, mu {mu.min():.2g}-{mu.max():.2g}: "
        f"{nodes} nodes) {seconds:.1f} s"
    )


def time_geometry(geo: Geometry) -> tuple[float, float, list[str]]:
    """Wall and CPU seconds of the tables a retrieve of ``geo`` requests (current cache).

    The CPU seconds (this process, all its threads) are the figure to compare on a
    shared machine: the wall clock also counts the other users' jobs.
    """
    from cwproc.stages.epsilon.atable_fit import TableOptions, a_tables
    from cwproc.tables.removed_share import mean_removed_share

    probe, phi, dtheta, n_lags, model, options = _request(geo)
    parts = []
    started, cpu = time.perf_counter(), time.process_time()
    t0 = time.perf_counter()
    a_tables(probe, phi, dtheta, n_lags, model, TableOptions(**options))
    parts.append(f"A-tables (inertial + {model}, {n_lags} lags) {time.perf_counter() - t0:.1f} s")
    if model != "inertial":
        t0 = time.perf_counter()
        mean_removed_share(np.array([0.5]), round(geo.phi_deg, 2), model)
        parts.append(f"removed share {time.perf_counter() - t0:.1f} s")
    parts.append(time_scan_factors(geo, probe, model))
    return time.perf_counter() - started, time.process_time() - cpu, parts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", type=int, nargs="+", help="indices of the geometries")
    args = parser.parse_args()
    chosen = args.only if args.only else range(len(GEOMETRIES))
    for k in chosen:
        if shipped := shipped_tables(GEOMETRIES[k]):
            raise SystemExit(f"{GEOMETRIES[k].name}: shipped ({shipped}), not a new site")
    with tempfile.TemporaryDirectory(prefix="cwproc-bench-first-run-") as cache:
        os.environ["XDG_CACHE_HOME"] = cache  # cold: nothing cached, nothing shipped found
        for k in chosen:
            geo = GEOMETRIES[k]
            seconds, cpu, parts = time_geometry(geo)
            print(
                f"{geo.name}: {seconds:6.1f} s wall, {cpu:6.1f} s CPU  ({'; '.join(parts)})",
                flush=True,
            )


if __name__ == "__main__":
    main()
