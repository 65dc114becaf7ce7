"""cwproc: Doppler wind lidar and sonic anemometer processing.

Readers for real instrument files (Halo Stream Line ``.hpl``, ZephIR and WindCube
exports, sonic anemometer logs), pure processing stages on xarray Datasets, and
CF-1.10 NetCDF products: wind profiles, the turbulence dissipation rate corrected
for volume averaging and wind transport, structure-function types, and a virtual
lidar for planning experiments.
"""

from cwproc._version import __version__

__all__ = ["__version__"]
