"""Lidar and mast sonic in one virtual field: each eps against its truth, and their ratio.

For each realisation (an independent field, ``cwproc.sim.mast.MastCase`` with
L_V = 300 m, eps = 0.01 m2 s-3, 1 h, a mast at 26 m inside the cone of a 35.3 deg
Stream Line scan) the chain runs as a user would: ``cwproc retrieve`` (lidar .hpl),
``cwproc sonic-turbulence`` (mast Meteo-2), ``cwproc compare --height 26``. Printed:

* sonic eps over the field's own structure functions on its grid
  (:func:`cwproc.sim.mast.field_structure_functions`, fitted over the range the product
  chose) - the sonic's truth on this grid;
* sonic eps over the nominal eps (the grid lacks the variance of scales below ~2
  spacings, so the grid truth is below the nominal one);
* lidar eps (blocks averaged per sonic window) over the nominal eps;
* lidar/sonic ratio (what ``cwproc compare`` reports) with the ratio the truths predict.

    PYTHONPATH=. python3 benchmarks/lidar_mast_truth.py --realisations 4
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.io.netcdf import read_product
from cwproc.physics.sonic_turbulence import C2_LONGITUDINAL, C2_TRANSVERSE
from cwproc.sim.mast import MastCase, case_field, field_structure_functions, write_mast_case

SITE = Path(__file__).resolve().parents[1] / "sample_data" / "site.toml"
CONSTANTS = (C2_LONGITUDINAL, C2_TRANSVERSE, C2_TRANSVERSE)


def grid_truth(case: MastCase, sonic) -> np.ndarray:
    """eps of the field's own D over each window's and component's chosen range."""
    field = case_field(case)
    out = np.full(sonic["epsilon_component"].shape, np.nan)
    step = case.wind_speed / case.sonic_rate_hz
    for w in range(out.shape[0]):
        for c in range(3):
            lo = float(sonic["inertial_range_min"][w, c])
            hi = float(sonic["inertial_range_max"][w, c])
            if not np.isfinite(lo):
                continue
            r = np.arange(round(lo / step), round(hi / step) + 1) * step
            d = field_structure_functions(
                field, r, direction_deg=case.wind_direction_deg, height_m=case.mast_height_m
            )[c]
            out[w, c] = np.exp(np.mean(np.log(d / (CONSTANTS[c] * r ** (2 / 3))))) ** 1.5
    return out


def run(seed: int, folder: Path) -> dict[str, np.ndarray]:
    case = MastCase(seed=seed, integral_scale_m=300.0, hours=1.0)
    write_mast_case(folder, case)
    out = folder / "out"
    runner = CliRunner()

    def invoke(*args: str) -> None:
        res = runner.invoke(main, list(args))
        assert res.exit_code == 0, res.output

    invoke("retrieve", str(folder / "lidar"), "-c", str(SITE), "-o", str(out), "-q")
    invoke("sonic-turbulence", str(folder / "mast"), "-o", str(out), "-q", "--height", "26")
    lidar = next(out.glob("streamline_*_turbulence.nc"))
    invoke(
        "compare",
        str(lidar),
        str(next(out.glob("*_sonic-turbulence.nc"))),
        "--height",
        "26",
        "-o",
        str(out),
    )
    sonic = read_product(next(out.glob("*_sonic-turbulence.nc")))
    cmp = read_product(next(out.glob("lidar-sonic_*.nc")))
    grid = grid_truth(case, sonic)
    return {
        "sonic_grid": (sonic["epsilon_component"].values / grid).ravel(),
        "sonic_nominal": sonic["epsilon"].values / case.epsilon,
        "lidar_nominal": cmp["lidar_epsilon"].values / case.epsilon,
        "ratio": cmp["lidar_sonic_epsilon_ratio"].values,
        "grid_nominal": np.nanmean(grid, axis=1) / case.epsilon,
    }


def line(name: str, q: np.ndarray) -> str:
    q = q[np.isfinite(q)]
    return (
        f"{name:<34} n={q.size:3d}  mean {q.mean():.3f} +/- {q.std(ddof=1) / np.sqrt(q.size):.3f}"
    )


def main_() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--realisations", type=int, default=4)
    args = parser.parse_args()
    parts: dict[str, list[np.ndarray]] = {}
    for k in range(args.realisations):
        with tempfile.TemporaryDirectory() as tmp:
            for key, val in run(100 + k, Path(tmp)).items():
                parts.setdefault(key, []).append(val)
    res = {k: np.concatenate(v) for k, v in parts.items()}
    print(line("sonic eps / grid truth (components)", res["sonic_grid"]))
    print(line("grid truth / nominal eps", res["grid_nominal"]))
    print(line("sonic eps / nominal eps", res["sonic_nominal"]))
    print(line("lidar eps / nominal eps", res["lidar_nominal"]))
    print(line("lidar / sonic (cwproc compare)", res["ratio"]))


if __name__ == "__main__":
    main_()
