"""cwproc: Doppler wind lidar and sonic anemometer processing.

Readers for real instrument files (Halo Stream Line ``.hpl``, ZephIR and WindCube
exports, sonic anemometer logs), pure processing stages on xarray Datasets, and
CF-1.10 NetCDF products: wind profiles, the turbulence dissipation rate corrected
for volume averaging and wind transport, structure-function types, and a virtual
lidar for planning experiments.

The public names below (``__all__``) are what a notebook needs; ``docs/api.md`` lists
them with their signatures. They are imported when first used (PEP 562), so that
``import cwproc`` and ``cwproc --help`` stay fast::

    import cwproc

    result = cwproc.retrieve("sample_data/streamline", "streamline")
    result["wind"]

Join the files of a record with ``cwproc.read([...])`` or ``cwproc.concat_scans``, not
``xarray.concat`` (each file numbers its scans from 0; the stages refuse the mixture).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from cwproc._version import __version__

if TYPE_CHECKING:  # what the lazy names are, for type checkers and editors
    from cwproc import stages
    from cwproc.api import Retrieval, UnitProducts, read, retrieve, write
    from cwproc.config import (
        BackgroundConfig,
        Config,
        InstrumentConfig,
        OutputConfig,
        QCConfig,
        SimulationConfig,
        SonicConfig,
        StareConfig,
        TurbulenceConfig,
        VADConfig,
        ZephirConfig,
        config_from_toml,
        load_config,
        preset_names,
    )
    from cwproc.errors import ConfigError, CwprocError, InputFileError
    from cwproc.io.scan_join import concat_scans

__all__ = [
    "BackgroundConfig",
    "Config",
    "ConfigError",
    "CwprocError",
    "InputFileError",
    "InstrumentConfig",
    "OutputConfig",
    "QCConfig",
    "Retrieval",
    "SimulationConfig",
    "SonicConfig",
    "StareConfig",
    "TurbulenceConfig",
    "UnitProducts",
    "VADConfig",
    "ZephirConfig",
    "__version__",
    "concat_scans",
    "config_from_toml",
    "load_config",
    "preset_names",
    "read",
    "retrieve",
    "stages",
    "write",
]

#: public name -> the module that defines it (``stages`` is the subpackage itself)
_HOMES = {
    "read": "cwproc.api",
    "retrieve": "cwproc.api",
    "write": "cwproc.api",
    "Retrieval": "cwproc.api",
    "UnitProducts": "cwproc.api",
    "Config": "cwproc.config",
    "InstrumentConfig": "cwproc.config",
    "QCConfig": "cwproc.config",
    "BackgroundConfig": "cwproc.config",
    "VADConfig": "cwproc.config",
    "TurbulenceConfig": "cwproc.config",
    "StareConfig": "cwproc.config",
    "SonicConfig": "cwproc.config",
    "ZephirConfig": "cwproc.config",
    "OutputConfig": "cwproc.config",
    "SimulationConfig": "cwproc.config",
    "load_config": "cwproc.config",
    "config_from_toml": "cwproc.config",
    "preset_names": "cwproc.config",
    "CwprocError": "cwproc.errors",
    "InputFileError": "cwproc.errors",
    "ConfigError": "cwproc.errors",
    "stages": "cwproc.stages",
    "concat_scans": "cwproc.io.scan_join",
}


def __getattr__(name: str) -> Any:
    """Import a public name on first use (PEP 562)."""
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'cwproc' has no attribute {name!r}")
    module = importlib.import_module(home)
    value = module if name == "stages" else getattr(module, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
