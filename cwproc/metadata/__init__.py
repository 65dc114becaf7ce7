"""The one metadata table: names, units, flags and citations of every variable.

Every variable cwproc reads or writes is declared once, as a
:class:`~cwproc.metadata.canonical.VarMeta`:

* :mod:`cwproc.metadata.canonical`: the canonical input datasets (scan, wind record,
  sonic) the readers return, attached on read (:func:`cwproc.io.schema.with_canonical_attrs`);
* :mod:`cwproc.metadata.products`: the product variables, :data:`VARIABLES` (every
  variable) and the per-product differences (:data:`PRODUCT_VARIABLES`), with
  :mod:`cwproc.metadata.l1` (the Doppler lidar L1 product),
  :mod:`cwproc.metadata.sonic` (the sonic turbulence product) and
  :mod:`cwproc.metadata.dbs` (the DBS statistics of WindCube lines of sight) kept
  apart for size.

The package sits below the stages (beside :mod:`cwproc.io`), so a stage's output
carries units and long names as soon as it is made: each public stage function is
decorated with :func:`described`, which attaches the declarations of its product to
the dataset it returns. Stage code itself never writes a declared attribute
(``tests/stages/test_no_metadata_in_stages.py``); the writer applies the same table
again (:func:`apply_metadata`), so what a notebook sees is what the file holds.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from typing import Any, ParamSpec, TypeVar

import xarray as xr

from cwproc.metadata.canonical import (
    DATASET_VARIABLES,
    DECLARED_ATTRS,
    SCAN_VARIABLES,
    SONIC_VARIABLES,
    WIND_RECORD_VARIABLES,
    DatasetKind,
    VarMeta,
    attach_attrs,
)
from cwproc.metadata.products import (
    INTERMEDIATE_VARIABLES,
    PRODUCT_VARIABLES,
    PRODUCTS,
    VARIABLES,
    apply_metadata,
    attach_declared,
    product_table,
    undeclared_variables,
)

__all__ = [
    "DATASET_VARIABLES",
    "DECLARED_ATTRS",
    "INTERMEDIATE_VARIABLES",
    "PRODUCTS",
    "PRODUCT_VARIABLES",
    "SCAN_VARIABLES",
    "SONIC_VARIABLES",
    "VARIABLES",
    "WIND_RECORD_VARIABLES",
    "DatasetKind",
    "VarMeta",
    "apply_metadata",
    "attach_attrs",
    "described",
    "product_table",
    "undeclared_variables",
]

P = ParamSpec("P")
R = TypeVar("R")


def described(product: str | None) -> Callable[[Callable[P, R]], Callable[P, R]]:
    """Decorator: the datasets a stage function returns carry the declared attributes.

    Parameters
    ----------
    product : str or None
        The product whose declarations apply (one of :data:`PRODUCTS`, e.g. ``"wind"``
        for :func:`cwproc.stages.fit_vad`: its ``qc_flag`` bits and citations); an
        intermediate dataset of :data:`INTERMEDIATE_VARIABLES` (``"dbs"``: the DBS
        statistics of WindCube lines of sight); or ``None`` for another intermediate
        dataset (screened scans, the lidar structure function): the declarations of
        :data:`VARIABLES`, every variable's.

    Returns
    -------
    callable
        The decorator. The wrapped function keeps its name, module, docstring and
        signature (:func:`functools.wraps`); a returned :class:`xarray.Dataset` (or
        each one of a returned tuple) gets ``units``, ``long_name`` and the other
        declared attributes of its variables (:func:`apply_metadata`; flag values and
        masks as lists of int, which the writer types as CF asks); attributes that
        record what the stage did (method, parameters) are kept. Anything else is
        returned as it is.

    Raises
    ------
    CwprocError
        ``product`` is not one of :data:`PRODUCTS` (when the decorator is applied, at
        import).
    """
    if product in INTERMEDIATE_VARIABLES:
        table = {**VARIABLES, **INTERMEDIATE_VARIABLES[product]}
    else:
        table = VARIABLES if product is None else product_table(product)

    def decorate(func: Callable[P, R]) -> Callable[P, R]:
        @functools.wraps(func)
        def stage(*args: P.args, **kwargs: P.kwargs) -> R:
            return _described(func(*args, **kwargs), table)

        return stage

    return decorate


def _described(value: Any, table: Mapping[str, VarMeta]) -> Any:
    """``value`` with the declared attributes of ``table`` on its datasets."""
    if isinstance(value, xr.Dataset):
        return attach_declared(value, table, flag_arrays=False)
    if type(value) is tuple:
        return tuple(_described(v, table) if isinstance(v, xr.Dataset) else v for v in value)
    return value
