"""The stage functions' keyword defaults are the values of the instrument presets
(issue 16): a notebook calling a stage without spelling out every threshold gets what
``cwproc retrieve -c <preset>`` uses."""

from __future__ import annotations

import dataclasses
import inspect
from types import ModuleType

import pytest

from cwproc.config import load_config
from cwproc.physics import sonic_fits
from cwproc.stages import sonic_sf, stare, wind_records

#: parameter name -> dotted key of the configuration it comes from, per module and preset
SONIC = {
    **{f.name: f"sonic.{f.name}" for f in dataclasses.fields(load_config("meteo2").sonic)},
    "min_points": "sonic.min_fit_points",
    "r_norm": "sonic.normalisation_lag_m",
}
STARE = {
    **{f.name: f"stare.{f.name}" for f in dataclasses.fields(load_config("streamline").stare)},
    "max_gap_s": "stare.max_wind_gap_s",
    "threshold": "stare.outlier_threshold",
    "snr_min": "qc.snr_min",
    "delta_p_m": "instrument.delta_p_m",
    "delta_r_m": "instrument.delta_r_m",
}
ZEPHIR = {
    "min_packets": "zephir.min_packets",
    "max_rain_percent": "zephir.max_rain_percent",
    "z_r_coefficient": "instrument.z_r_coefficient",
}

CASES = [
    (sonic_sf, "meteo2", SONIC),
    (sonic_fits, "meteo2", SONIC),
    (stare, "streamline", STARE),
    (wind_records, "zephir300", ZEPHIR),
]


def preset_value(preset: str, dotted: str) -> object:
    section, key = dotted.split(".")
    return getattr(getattr(load_config(preset), section), key)


def public_callables(module: ModuleType) -> list[tuple[str, object]]:
    """Functions and dataclasses defined in ``module`` whose names do not start with _."""
    return [
        (name, obj)
        for name, obj in vars(module).items()
        if not name.startswith("_")
        and (inspect.isfunction(obj) or inspect.isclass(obj))
        and obj.__module__ == module.__name__
    ]


@pytest.mark.parametrize(
    ("module", "preset", "table"), CASES, ids=lambda c: getattr(c, "__name__", None)
)
def test_every_configurable_parameter_defaults_to_the_preset(module, preset, table):
    checked = []
    for name, obj in public_callables(module):
        for param in inspect.signature(obj).parameters.values():
            if param.name not in table:
                continue
            where = f"{module.__name__}.{name}({param.name})"
            assert param.default is not inspect.Parameter.empty, f"{where} has no default"
            expected = preset_value(preset, table[param.name])
            assert param.default == expected, f"{where} = {param.default!r}, {preset}: {expected!r}"
            assert type(param.default) is type(expected), where
            checked.append(where)
    assert len(checked) >= {"meteo2": 4, "streamline": 10, "zephir300": 4}[preset], checked


def test_the_main_stages_have_the_defaults_named():
    """The parameters a notebook leaves out: spelled out here so none goes unnoticed."""
    sf = inspect.signature(sonic_sf.structure_function_types).parameters
    assert {p for p in sf if p != "sonic"} == {
        f.name for f in dataclasses.fields(load_config("meteo2").sonic)
    }
    record = inspect.signature(wind_records.wind_record_product).parameters
    assert set(ZEPHIR) <= set(record)
    assert inspect.signature(stare.stare_product).parameters["options"].default is None
    assert {f.name for f in dataclasses.fields(stare.StareOptions)} <= set(STARE)
