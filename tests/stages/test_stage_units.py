"""Stage outputs carry units and long names from the one metadata table (issue 33).

Every public stage function is decorated with :func:`cwproc.metadata.described`; this
test runs each on the shipped samples (or the small inputs of its own test module) and
checks that every variable and coordinate of the output has a ``long_name`` and
``units`` (a datetime, a flag or a count may go without, as CF allows), equal to its
declaration. An AST pass checks that no decorated stage is left out here.
"""

from __future__ import annotations

import ast
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import cwproc
from cwproc import stages
from cwproc.metadata import INTERMEDIATE_VARIABLES, VARIABLES, product_table

sys.path.insert(0, str(Path(__file__).resolve().parent))

from test_doppler_lidar import layered
from test_lidar_sonic import lidar_product, sonic_product
from test_snr_correction import _background, _scans
from test_stare import constant_wind, stare_dataset

REPO = Path(__file__).resolve().parents[2]
SAMPLES = REPO / "sample_data"
STAGES = REPO / "cwproc" / "stages"


def decorated_stages() -> set[str]:
    """``module:function`` of every stage function decorated with ``@described``."""
    found = set()
    for path in STAGES.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef):
                for deco in node.decorator_list:
                    if isinstance(deco, ast.Call) and getattr(deco.func, "id", "") == "described":
                        found.add(f"{path.relative_to(STAGES).with_suffix('')}:{node.name}")
    return found


@pytest.fixture(scope="module")
def scan_chain() -> dict[str, xr.Dataset]:
    scans = cwproc.read(sorted((SAMPLES / "streamline").glob("*.hpl")))
    screened = stages.screen_radial_velocity(scans)
    wind = stages.fit_vad(screened)
    sf = stages.azimuth_structure_function(screened, wind)
    return {"screened": screened, "wind": wind, "sf": sf, "turbulence": stages.estimate_epsilon(sf)}


def _stare() -> xr.Dataset:
    from cwproc.sim.stare import gaussian_stares
    from cwproc.stages.stare import StareOptions

    w = gaussian_stares(
        4, 225, epsilon=1e-3, noise_std_m_s=0.1, seed=7, ray_duration_s=4 / 3, wind_speed_m_s=5.0
    )
    return stages.stare_product(stare_dataset(w), constant_wind(5.0), StareOptions())


def _dbs() -> xr.Dataset:
    from cwproc.stages.dbs import dbs_statistics

    return dbs_statistics(
        cwproc.read(SAMPLES / "windcube_rtd" / "WLS7-999_2024_06_01__00_10_00.rtd")
    )


def _sonic_turbulence() -> xr.Dataset:
    from cwproc.sim.sonic import default_models, simulate_sonic_dataset
    from cwproc.stages.sonic_turbulence import sonic_turbulence

    return sonic_turbulence(simulate_sonic_dataset(hours=1.0, models=default_models(1), seed=500))


def _doppler_lidar() -> xr.Dataset:
    from cwproc.stages.doppler_lidar import DopplerLidarOptions, doppler_lidar_product

    return doppler_lidar_product(layered(), options=DopplerLidarOptions())


def _compare() -> xr.Dataset:
    from cwproc.stages.lidar_sonic import compare_lidar_sonic

    eps = np.array([1e-3, 4e-3, 2e-2])
    return compare_lidar_sonic(
        lidar_product(1.5 * eps), sonic_product(eps, 0.05 * eps), height_m=45.0
    )


def _correct_snr() -> xr.Dataset:
    bg = _background("2024-06-01T10:00:02", 150, "Background_010624-100002.txt")
    return stages.correct_snr(_scans(), [bg], max_age_h=1.0)


def _wind_record(folder: str, name: str) -> Callable[[], xr.Dataset]:
    return lambda: stages.wind_record_product(cwproc.read(SAMPLES / folder / name))


#: ``module:function`` -> (product or intermediate table that applies, or None: every
#: variable's; how to make an output)
OUTPUTS: dict[str, tuple[str | None, Callable[..., xr.Dataset]]] = {
    "qc:screen_radial_velocity": (None, lambda chain: chain["screened"]),
    "vad:fit_vad": ("wind", lambda chain: chain["wind"]),
    "structure:azimuth_structure_function": (None, lambda chain: chain["sf"]),
    "epsilon/__init__:estimate_epsilon": ("turbulence", lambda chain: chain["turbulence"]),
    "stare:stare_product": ("stare", _stare),
    "wind_records:wind_record_product": (
        "wind_record",
        _wind_record("zephir", "Wind10_999@Y2024_M06_D01.ZPH.csv"),
    ),
    "dbs:dbs_statistics": ("dbs", _dbs),
    "sonic_sf:structure_function_types": (
        "sf",
        lambda: stages.structure_function_types(
            cwproc.read(SAMPLES / "sonic" / "meteo2_2024_06_01_1200.txt")
        ),
    ),
    "sonic_turbulence:sonic_turbulence": ("sonic_turbulence", _sonic_turbulence),
    "doppler_lidar:doppler_lidar_product": ("doppler_lidar", _doppler_lidar),
    "snr_correction:correct_snr": (None, _correct_snr),
    "lidar_sonic:compare_lidar_sonic": ("lidar_sonic", _compare),
}


def test_every_described_stage_is_checked_here():
    assert decorated_stages() == set(OUTPUTS)


def _unitless_allowed(name: str, var: xr.Variable) -> bool:
    """A datetime, a flag, a count or a text label may have no ``units`` (CF 3.1)."""
    return var.dtype.kind in "MOUS" or "flag" in name or name.startswith("n_")


@pytest.mark.parametrize("stage", sorted(OUTPUTS))
def test_stage_output_has_units_and_long_names(stage, scan_chain):
    product, make = OUTPUTS[stage]
    out = (
        make(scan_chain)
        if stage.split(":")[0] in ("qc", "vad", "structure", "epsilon/__init__")
        else make()
    )
    if product in INTERMEDIATE_VARIABLES:
        table = {**VARIABLES, **INTERMEDIATE_VARIABLES[product]}
    else:
        table = VARIABLES if product is None else product_table(product)
    missing = []
    for name, var in out.variables.items():
        attrs = var.attrs
        if "long_name" not in attrs:
            missing.append(f"{name}: no long_name")
            continue
        if "units" not in attrs and not _unitless_allowed(str(name), var):
            missing.append(f"{name}: no units")
        meta = table.get(str(name))
        assert meta is not None, f"{stage}: {name} is not declared"
        assert attrs["long_name"] == meta.long_name, name
        if meta.units is not None and var.dtype.kind != "M":
            assert attrs["units"] == meta.units, name
    assert missing == [], f"{stage}: " + "; ".join(missing)


def test_the_decorator_keeps_the_stage_signature_and_recorded_attributes(scan_chain):
    import inspect

    from cwproc.stages.vad import fit_vad

    assert fit_vad.__name__ == "fit_vad" and fit_vad.__module__ == "cwproc.stages.vad"
    assert "min_rays" in inspect.signature(fit_vad).parameters
    wind = scan_chain["wind"]
    assert wind["u"].attrs["units"] == "m s-1"
    assert "least squares" in wind["u"].attrs["method"]  # what the stage did stays
    assert wind["qc_flag"].attrs["flag_meanings"].split()[0] == "too_few_rays"
