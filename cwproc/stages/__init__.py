"""Processing stages: ``f(ds: xarray.Dataset, *, params) -> xarray.Dataset``, no I/O.

The main stage of each module is reachable here by name (``cwproc.stages.fit_vad``),
and each module as ``cwproc.stages.<module>``; both are imported when first used
(PEP 562), so importing one stage does not import the others. Their keyword
arguments default to the values of the instrument presets.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = [
    "StareOptions",
    "azimuth_structure_function",
    "correct_snr",
    "estimate_epsilon",
    "fit_vad",
    "parameter_statistics",
    "screen_radial_velocity",
    "split_stares",
    "stare_product",
    "structure_function_types",
    "type_occurrence",
    "wind_record_product",
]

#: public name -> the stage module that defines it
_HOMES = {
    "screen_radial_velocity": "qc",
    "correct_snr": "snr_correction",
    "fit_vad": "vad",
    "azimuth_structure_function": "structure",
    "estimate_epsilon": "epsilon",
    "split_stares": "stare",
    "stare_product": "stare",
    "StareOptions": "stare",
    "structure_function_types": "sonic_sf",
    "type_occurrence": "sonic_sf_tables",
    "parameter_statistics": "sonic_sf_tables",
    "wind_record_product": "wind_records",
}

#: the stage modules, reachable as attributes before they are imported
_MODULES = (
    "epsilon",
    "qc",
    "snr_correction",
    "sonic_sf",
    "sonic_sf_tables",
    "stare",
    "structure",
    "vad",
    "wind_records",
)


def __getattr__(name: str) -> Any:
    """Import a stage function or module on first use (PEP 562)."""
    if name in _MODULES:
        return importlib.import_module(f"{__name__}.{name}")
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{home}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__) | set(_MODULES))
