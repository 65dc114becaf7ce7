"""cwproc: Doppler wind lidar and sonic anemometer processing.

Readers for real instrument files (Halo Stream Line ``.hpl``, ZephIR and WindCube
exports, sonic anemometer logs), pure processing stages on xarray Datasets, and
CF-1.10 NetCDF products: wind profiles, the turbulence dissipation rate corrected
for volume averaging and wind transport, structure-function types, and a virtual
lidar for planning experiments.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("cwproc")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.1.0+unknown"

__all__ = ["__version__"]
