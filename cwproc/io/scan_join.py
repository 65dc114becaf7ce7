"""Scan segmentation: which 360 degree rotation of a conical scan each ray belongs to.

The structure function and the VAD fit of Smalikho (2020), eqs. 1-2, work on the
rays of one full rotation of the cone (azimuth theta_m = m dtheta at a fixed
elevation phi). A Stream Line writes scans in many ways: one rotation per file
(step-stare VAD), several or partial rotations per file, continuous scans with the
azimuth increasing or decreasing, wrapping at 0/360, interleaved with vertical stares.
:func:`assign_scans` recovers the rotations from the pointing angles alone;
:func:`concat_scans` joins the datasets of several files in time order first.

Method
------
The numbering itself is :mod:`cwproc.physics.scan_numbering` (numpy only): consecutive
rays at one elevation turning one way form a sweep, and the turned azimuth angle
divided by 360 deg gives the rotation; this module applies it to datasets.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.io.schema import with_canonical_attrs
from cwproc.physics.scan_numbering import scan_indices


def assign_scans(
    ds: xr.Dataset,
    *,
    max_elevation_deg: float = 89.0,
    elevation_tolerance_deg: float = 0.5,
    min_step_deg: float = 0.2,
    max_gap_s: float = 120.0,
    min_rays: int | None = None,
) -> xr.Dataset:
    """Set the ``scan(ray)`` coordinate: the index of each 360 degree rotation.

    Parameters
    ----------
    ds : xarray.Dataset
        Scan dataset with ``time``, ``azimuth`` (deg) and ``elevation`` (deg) on ``ray``.
    max_elevation_deg : float
        Rays at or above this elevation (deg) are stares, not part of a cone; 89 deg
        keeps vertical stares with inclinometer wobble (90.01) out.
    elevation_tolerance_deg : float
        Largest elevation change (deg) between consecutive rays of one cone.
    min_step_deg : float
        Smallest azimuth step (deg) of a scan; smaller steps are a stare with jitter.
    max_gap_s : float
        Largest time step (s) inside one sweep; a longer pause starts a new scan.
    min_rays : int, optional
        Shortest sweep (rays) counted as a conical scan; default 2 when the header's
        ``scan_type`` declares a conical scan (VAD, PPI, DBS), else 3 (a stepped user
        scan that visits two azimuths at one elevation is not a cone).

    Returns
    -------
    xarray.Dataset
        ``ds`` with ``scan(ray)`` (int64, 0, 1, ... in time order, -1 for rays in no
        conical scan). Method and parameters are in ``scan.attrs``.
    """
    scan, attrs = scan_indices(
        ds["time"].values,
        ds["azimuth"].values,
        ds["elevation"].values,
        scan_type=ds.attrs.get("scan_type"),
        max_elevation_deg=max_elevation_deg,
        elevation_tolerance_deg=elevation_tolerance_deg,
        min_step_deg=min_step_deg,
        max_gap_s=max_gap_s,
        min_rays=min_rays,
    )
    return ds.assign_coords(scan=("ray", scan, attrs))


def _files(ds: xr.Dataset) -> str:
    files = ds.attrs.get("source_files", [])
    if isinstance(files, str):
        files = [files]
    return ", ".join(map(str, files)) or "<unnamed dataset>"


#: spellings of the ``homodyne`` attribute (case and surrounding blanks ignored)
_HOMODYNE_WORDS = {"1": True, "true": True, "0": False, "false": False}


def parse_homodyne(value: object) -> bool:
    """The detection scheme named by a ``homodyne`` attribute value.

    A homodyne cw lidar measures only ``|V_r|`` (Banakh et al. (1999), section 3).
    Accepted: ``bool``, the integers 0 and 1 (numpy scalars and one-element arrays
    included, as NetCDF attributes come back), and the strings ``"0"``, ``"1"``,
    ``"true"``, ``"false"``. Python's ``bool("false")`` is True, which is why no caller
    may test the attribute with ``bool``.

    Parameters
    ----------
    value : object
        The attribute value.

    Returns
    -------
    bool
        True for homodyne detection.

    Raises
    ------
    ValueError
        Any other value (named in the message).
    """
    if isinstance(value, str):
        word = value.strip().lower()
        if word in _HOMODYNE_WORDS:
            return _HOMODYNE_WORDS[word]
    elif isinstance(value, (bool, int, float, np.bool_, np.number, np.ndarray)):
        array = np.asarray(value)
        if array.size == 1 and array.dtype.kind in "biuf" and array.item() in (0, 1):
            return bool(array.item())
    raise ValueError(f"homodyne is {value!r}: expected 0/1, true/false")


def is_homodyne(ds: xr.Dataset) -> bool:
    """Whether a scan dataset holds homodyne (``|V_r|`` only) data.

    Every reader sets the global attribute ``homodyne`` to the int 0 or 1; a dataset
    without it (built in memory) is heterodyne (signed ``V_r``).

    Parameters
    ----------
    ds : xarray.Dataset
        Scan dataset.

    Returns
    -------
    bool

    Raises
    ------
    CwprocError
        The attribute is not one of the spellings of :func:`parse_homodyne`; the
        message names the files of the dataset.
    """
    try:
        return parse_homodyne(ds.attrs.get("homodyne", 0))
    except ValueError as exc:
        raise CwprocError(f"scan dataset {_files(ds)}: global attribute {exc}") from None


def source_files(ds: xr.Dataset) -> list[str]:
    """The ``source_files`` global attribute of ``ds`` as a list of file names."""
    files = ds.attrs.get("source_files", [])
    if isinstance(files, str):
        files = [f.strip() for f in files.split(",") if f.strip()]
    return [str(f) for f in files]


def _check_compatible(datasets: Sequence[xr.Dataset]) -> None:
    first = datasets[0]
    ref_range = np.asarray(first.variables["range"].values, dtype=np.float64)
    for other in datasets[1:]:
        rng = np.asarray(other.variables["range"].values, dtype=np.float64)
        if rng.shape != ref_range.shape or not (
            np.array_equal(rng, ref_range) or np.allclose(rng, ref_range, rtol=0, atol=1e-3)
        ):
            raise CwprocError(
                f"cannot concatenate scans: range grids differ ({_files(first)}: "
                f"{ref_range.size} gates from {ref_range[0]:g} m; {_files(other)}: "
                f"{rng.size} gates from {rng[0] if rng.size else float('nan'):g} m)"
            )
        if is_homodyne(first) != is_homodyne(other):
            raise CwprocError(
                f"cannot concatenate scans: homodyne differs ({_files(first)}: "
                f"{first.attrs.get('homodyne')}; {_files(other)}: {other.attrs.get('homodyne')})"
            )
        for key in ("system_id", "instrument_kind"):
            a, b = first.attrs.get(key), other.attrs.get(key)
            if a is not None and b is not None and str(a) != str(b):
                raise CwprocError(
                    f"cannot concatenate scans: {key} differs ({_files(first)}: {a}; "
                    f"{_files(other)}: {b})"
                )


def concat_scans(datasets: Sequence[xr.Dataset], **assign_options: float) -> xr.Dataset:
    """Concatenate the scan datasets of several files in time order.

    Parameters
    ----------
    datasets : sequence of xarray.Dataset
        Canonical scan datasets (e.g. one per ``.hpl`` file) on the same range grid.
    **assign_options
        Passed to :func:`assign_scans`.

    Returns
    -------
    xarray.Dataset
        One dataset, rays sorted by time, rays with a time already seen dropped (the
        first occurrence is kept), ``scan`` re-assigned over the whole record,
        ``source_files`` the files of all inputs. Optional variables present in only
        some inputs (``spectral_width``, ``pitch``, ``roll``, ``beta``) are NaN for the
        rays of the others.

    Raises
    ------
    CwprocError
        No datasets, or range grids / system ids / detection (homodyne) differ; the
        message names the files.
    """
    datasets = list(datasets)
    if not datasets:
        raise CwprocError("no scan datasets to concatenate")
    _check_compatible(datasets)
    first = datasets[0]
    names: list[str] = []
    for ds in datasets:
        names.extend(str(v) for v in ds.data_vars if str(v) not in names)
    arrays = {}
    fixed = {}
    for name in names:
        # Variable level (a DataArray per file and variable costs ~0.2 ms each)
        template = next(ds.variables[name] for ds in datasets if name in ds.variables)
        dims = template.dims
        if "ray" not in dims:  # per-file constants (none in the canonical schema)
            fixed[name] = template
            continue
        parts = []
        for ds in datasets:
            if name in ds.variables:
                var = ds.variables[name]
                parts.append(np.asarray((var if var.dims == dims else var.transpose(*dims)).values))
            else:
                shape = [ds.sizes[d] for d in dims]
                parts.append(np.full(shape, np.nan, dtype=np.float64))
        arrays[name] = (dims, np.concatenate(parts, axis=dims.index("ray")), template.attrs)
    time = np.concatenate([ds.variables["time"].values for ds in datasets])
    azimuth = np.concatenate([np.asarray(ds.variables["azimuth"].values, float) for ds in datasets])
    elevation = np.concatenate(
        [np.asarray(ds.variables["elevation"].values, float) for ds in datasets]
    )
    files: list[str] = []
    for ds in datasets:
        files.extend(f for f in source_files(ds) if f not in files)
    scan_types = [str(ds.attrs.get("scan_type", "")) for ds in datasets]
    return time_sorted_scans(
        arrays,
        fixed=fixed,
        time=time,
        azimuth=azimuth,
        elevation=elevation,
        ranges=np.asarray(first["range"].values),
        attrs=joined_attrs(first.attrs, files, scan_types),
        coord_attrs={c: dict(first[c].attrs) for c in ("time", "azimuth", "elevation", "range")},
        **assign_options,
    )


def joined_attrs(
    first: dict[str, object], files: Sequence[str], scan_types: Sequence[str]
) -> dict[str, object]:
    """Attributes of concatenated scans: the first input's, with all files and scan types.

    ``source_files`` lists every file once in input order; ``scan_type`` joins the
    distinct non-empty scan types with ``"; "``.
    """
    attrs = dict(first)
    attrs["source_files"] = list(dict.fromkeys(files))
    unique = list(dict.fromkeys(str(s) for s in scan_types))
    attrs["scan_type"] = "; ".join(s for s in unique if s)
    return attrs


def time_sorted_scans(
    arrays: dict[str, tuple[tuple[str, ...], np.ndarray, dict]],
    *,
    fixed: dict[str, xr.Variable],
    time: np.ndarray,
    azimuth: np.ndarray,
    elevation: np.ndarray,
    ranges: np.ndarray,
    attrs: dict[str, object],
    coord_attrs: dict[str, dict],
    origin: np.ndarray | None = None,
    **assign_options: float,
) -> xr.Dataset:
    """One scan dataset from concatenated per-ray arrays: sorted, deduplicated, scans set.

    Parameters
    ----------
    arrays : dict
        ``name -> (dims, values, attrs)`` of the variables on ``ray`` (rays of all
        inputs one after the other). Emptied: each entry is taken out before the next
        one is reordered, so when the rays are out of order (or times repeat) the
        memory above the result is one variable's reordered copy, not all of them
        (none when they are in order: the arrays are then used as they are).
    fixed : dict of xarray.Variable
        Variables without a ``ray`` dimension, kept as they are.
    time, azimuth, elevation : ndarray
        Per-ray coordinates (datetime64; deg).
    ranges : ndarray
        Gate centres (m).
    attrs : dict
        Dataset attributes.
    coord_attrs : dict
        Attributes of the coordinates ``time``, ``azimuth``, ``elevation``, ``range``.
    origin : ndarray of int, optional
        Position of each ray in the inputs' order, when the arrays hold the rays in
        another order (e.g. files placed by start time): rays of equal time are taken
        in this order, so the result is that of the inputs' order. Default: the arrays'
        order.
    **assign_options
        Passed to :func:`assign_scans`.

    Returns
    -------
    xarray.Dataset
        Rays sorted by time (stable), rays with a time already seen dropped (the first
        occurrence is kept), ``scan`` assigned over the whole record.
    """
    order = np.argsort(time, kind="stable") if origin is None else np.lexsort((origin, time))
    sorted_time = time[order]
    keep = np.ones(order.size, dtype=bool)
    keep[1:] = sorted_time[1:] != sorted_time[:-1]
    if not keep.all():
        order = order[keep]
    identity = bool(np.array_equal(order, np.arange(time.size)))

    def pick(values: np.ndarray, axis: int = 0) -> np.ndarray:
        return values if identity else np.take(values, order, axis=axis)

    data_vars = {}
    for name in list(arrays):
        dims, values, var_attrs = arrays.pop(name)
        data_vars[name] = xr.Variable(dims, pick(values, dims.index("ray")), var_attrs)
        del values  # the caller's copy is gone too: freed before the next variable
    data_vars.update(fixed)
    coords = {
        "time": xr.Variable("ray", pick(time), coord_attrs.get("time")),
        "azimuth": xr.Variable("ray", pick(azimuth), coord_attrs.get("azimuth")),
        "elevation": xr.Variable("ray", pick(elevation), coord_attrs.get("elevation")),
        "range": xr.Variable("range", ranges, coord_attrs.get("range")),
    }
    out = xr.Dataset(data_vars, coords=coords, attrs=attrs)
    return with_canonical_attrs(assign_scans(out, **assign_options), "scan")
