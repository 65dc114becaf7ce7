"""The figure of a quicklook: its size, colour maps, pyplot, and the PNG it is saved to.

Every quicklook is :data:`FIGSIZE` inches at :data:`DPI` dots per inch (a few wide ones
set their own size). Colour maps are perceptually uniform and readable with
colour-vision deficiencies (cividis, viridis; RdBu_r for signed quantities); missing
data are drawn on the grey :data:`MISSING` background, never as zeros. A picture with
nothing to draw (every value missing) is refused with a :class:`ProductError` naming
the reason (:func:`refuse_empty`); a product of one time step is drawn as profiles
(:func:`one_time_step`).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc.errors import ProductError
from cwproc.io.netcdf import remove_stale_temporaries, umask_mode

#: figure size in inches and resolution of every quicklook
FIGSIZE = (10.0, 6.0)
DPI = 100

SEQUENTIAL = "cividis"
SEQUENTIAL_LOG = "viridis"
DIVERGING = "RdBu_r"
#: background of time-height panels: where a value is missing (also white of RdBu_r)
MISSING = "0.8"


def pyplot():
    """matplotlib.pyplot on the Agg backend (no display), imported on first use."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _units(da: xr.DataArray) -> str:
    """`` (units)`` of ``da`` for a label; nothing for none or dimensionless ``1``."""
    units = da.attrs.get("units", "")
    return f" ({units})" if units and units != "1" else ""


def axis_label(da: xr.DataArray, fallback: str) -> str:
    """``long_name (units)`` of ``da``, ``fallback`` for a missing long name."""
    return str(da.attrs.get("long_name", fallback)) + _units(da)


def all_missing(da: xr.DataArray) -> bool:
    """Whether ``da`` holds no finite value."""
    return not np.isfinite(np.asarray(da.values, dtype=float)).any()


def refuse_empty(ds: xr.Dataset, names: tuple[str, ...], kind: str) -> None:
    """Refuse to draw a picture whose variables hold no finite value."""
    if all(all_missing(ds[n]) for n in names):
        raise ProductError(
            f"cannot draw '{kind}': {' and '.join(names)} "
            f"{'holds' if len(names) == 1 else 'hold'} no finite value "
            "(every estimate of the product is missing)"
        )


def one_time_step(ds: xr.Dataset) -> bool:
    """Whether ``ds`` has one time step (drawn as profiles, not time-height)."""
    return "time" in ds.dims and ds.sizes["time"] == 1


def time_text(ds: xr.Dataset) -> str:
    """The first time of ``ds`` to the minute, as ``YYYY-MM-DDTHH:MM UTC``."""
    return np.datetime_as_string(ds["time"].values.ravel()[0], unit="m") + " UTC"


def save_png(fig, out: str | os.PathLike) -> Path:
    """Save a figure as PNG through a temporary file, then close it."""
    plt = pyplot()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(out.parent)  # of a plot killed earlier
    tmp = None
    try:  # an unpredictable name created exclusively: no planted symlink is followed
        fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
        with os.fdopen(fd, "wb") as fh:
            fig.savefig(fh, dpi=DPI, format="png")
        os.chmod(tmp, umask_mode())
        os.replace(tmp, out)
    except OSError as exc:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        raise ProductError(f"{out}: cannot write picture: {exc.strerror or exc}") from None
    finally:
        plt.close(fig)
    return out
