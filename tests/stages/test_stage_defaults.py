"""The keyword defaults of the stage functions are the ``streamline`` preset's values.

A notebook calling ``fit_vad(scans)`` gets what ``cwproc retrieve`` (default preset
``streamline``) does; the mapping of configuration fields to arguments is that of
``cwproc.pipeline`` (``screened_wind`` and ``process_scans``).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable

import pytest

from cwproc.config import load_config
from cwproc.stages.qc import screen_radial_velocity
from cwproc.stages.structure import azimuth_structure_function
from cwproc.stages.vad import fit_vad

PRESET = load_config("streamline")

#: (stage function, argument, configuration value it takes in the pipeline)
MAPPING = [
    (screen_radial_velocity, "snr_min", PRESET.qc.snr_min),
    (screen_radial_velocity, "outlier_threshold", PRESET.qc.outlier_threshold),
    (fit_vad, "min_rays", PRESET.vad.min_rays),
    (fit_vad, "max_gap_deg", PRESET.vad.max_gap_deg),
    (fit_vad, "reference_direction_deg", PRESET.vad.reference_direction_deg),
    (fit_vad, "max_residual_std", PRESET.vad.max_residual_std),
    (azimuth_structure_function, "n_scans", PRESET.turbulence.n_scans),
    (azimuth_structure_function, "max_lag_deg", PRESET.turbulence.max_lag_deg),
    (azimuth_structure_function, "min_lags", PRESET.turbulence.min_lags),
]


@pytest.mark.parametrize(
    ("function", "argument", "preset_value"),
    MAPPING,
    ids=[f"{f.__name__}-{a}" for f, a, _ in MAPPING],
)
def test_default_is_the_streamline_preset_value(
    function: Callable[..., object], argument: str, preset_value: object
) -> None:
    parameter = inspect.signature(function).parameters[argument]
    assert parameter.kind is inspect.Parameter.KEYWORD_ONLY
    assert parameter.default == preset_value
    assert type(parameter.default) is type(preset_value)


@pytest.mark.parametrize("function", [screen_radial_velocity, fit_vad, azimuth_structure_function])
def test_homodyne_defaults_to_the_dataset(function: Callable[..., object]) -> None:
    """``homodyne=None`` reads the data's attribute; the configuration has no homodyne
    setting that could override a homodyne input."""
    assert inspect.signature(function).parameters["homodyne"].default is None
    assert not hasattr(PRESET.instrument, "homodyne")


def test_every_keyword_with_a_default_is_covered() -> None:
    """A new tunable keyword gets a preset value and a row above (or is structural)."""
    structural = {"homodyne"}
    covered = {(f, a) for f, a, _ in MAPPING}
    for function in (screen_radial_velocity, fit_vad, azimuth_structure_function):
        for name, parameter in inspect.signature(function).parameters.items():
            if parameter.default is inspect.Parameter.empty or name in structural:
                continue
            assert (function, name) in covered, f"{function.__name__}({name}=...)"
