"""``run_unit``: the one entry that turns a product unit into products.

``cwproc retrieve``, ``cwproc batch``, ``cwproc plot`` and the Python API all turn a
product unit into products by calling :func:`run_unit`; what a unit gave (products,
notes, failures and so the exit status) is therefore the same whichever client asked.
The order of the stages is :class:`cwproc.pipeline.scan_chain.ScanChain`'s (scan data) and
the ``process_*`` chains' of :mod:`cwproc.pipeline.chain` (wind records, sonic data).
"""

from __future__ import annotations

import os
import traceback
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc.config import Config
from cwproc.errors import CwprocError
from cwproc.metadata.products import product_table
from cwproc.pipeline.chain import process_sonic, process_wind_record
from cwproc.pipeline.input_files import load_item
from cwproc.pipeline.product_units import ProductUnit, concat_unit, load_unit, unit_label
from cwproc.pipeline.scan_chain import ScanChain, describe_scan_inputs
from cwproc.products.catalogue import product_kind

#: exit status of a command whose every unit succeeded
EXIT_OK = 0
#: exit status of a command of which some input or unit failed (its products were
#: still written when the others allowed it)
EXIT_FAILED = 1


@dataclass
class UnitResult:
    """What one product unit gave.

    Attributes
    ----------
    key : str
        The unit's key (:func:`cwproc.pipeline.unit_key`); products are written as
        ``<key>_<product>.nc``.
    kind : str
        ``"scan"``, ``"wind_record"`` or ``"sonic"``.
    products : dict of str to xarray.Dataset
        ``{product name: dataset}`` (``wind``, ``turbulence``, ``stare``, ``sf``), not
        yet written; empty when the unit failed.
    notes : list of str
        What the user should know that is not a failure (what each file holds, a product
        that cannot be made and why); every line names the file(s) it is about.
    failures : list of str
        One line per failure (an input damaged beyond its header, a chain that could not
        run), naming the file, the line where known, and the problem.
    screened : xarray.Dataset or None
        The QC-screened conical scans the VAD was fitted to, when asked for
        (``keep_screened``); else None.
    """

    key: str
    kind: str
    products: dict[str, xr.Dataset] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)
    screened: xr.Dataset | None = None

    @property
    def ok(self) -> bool:
        """True when nothing failed (notes are not failures)."""
        return not self.failures

    @property
    def exit_status(self) -> int:
        """:data:`EXIT_OK` when the unit succeeded, else :data:`EXIT_FAILED`."""
        return EXIT_OK if self.ok else EXIT_FAILED


def run_unit(unit: ProductUnit, config: Config, *, keep_screened: bool = False) -> UnitResult:
    """Run the stage chain of one product unit; never raises for what its data cause.

    Parameters
    ----------
    unit : ProductUnit
        The inputs of one unit (:func:`cwproc.pipeline.group_units` of
        :func:`cwproc.pipeline.read_input` items). Inputs whose data are not held are
        read here (and their checksums compared); an input damaged beyond its header is
        left out with a failure line.
    config : Config
        The configuration (a preset or a TOML file, :func:`cwproc.config.load_config`).
    keep_screened : bool
        Keep the QC-screened scans of a scan unit in ``UnitResult.screened`` (the day is
        then processed whole, not chunk by chunk).

    Returns
    -------
    UnitResult
        Products (not written; see :func:`cwproc.pipeline.write_unit_products`), notes,
        failures and the exit status they mean.

    Notes
    -----
    A scan unit runs :class:`~cwproc.pipeline.scan_chain.ScanChain` (``read ->
    background.correct_snr -> qc -> vad -> structure -> epsilon``, and ``stare`` for
    vertical rays) through :func:`cwproc.pipeline.stream.run_scan_chain`, chunk by chunk
    in bounded memory unless its chunks would decide differently from the whole day; a
    wind-record unit runs ``zephir.wind_record_product``; a sonic unit
    ``sonic_sf.structure_function_types``.
    """
    result = UnitResult(key=unit.key, kind=unit.kind)
    notes: list[str] = []
    names = unit_label(unit)
    kept: dict[str, xr.Dataset] | None = {} if keep_screened else None
    try:
        result.products = unit_products(unit, config, notes, kept=kept)
        if config.output.layout == "cloudnet" and unit.kind == "scan":
            result.products.update(cloudnet_layout(unit, result.products, config))
    except CwprocError as exc:
        result.failures.append(f"{names}: {exc}")
    except Exception as exc:  # a bug in cwproc: report it, the caller goes on
        result.failures.append(f"{names}: {internal_error(exc)}")
    result.failures.extend(unit.failures)
    empty = {
        n: empty_reason(n, ds, config, unit_kind=unit.kind) for n, ds in result.products.items()
    }
    for name in [n for n, reason in empty.items() if reason]:
        result.products.pop(name)
        notes.append(empty[name])
    own = tuple(f"{os.fspath(i.path)}: " for i in unit.inputs)
    result.notes = [n if n.startswith(own) else f"{names}: {n}" for n in notes]
    if kept:
        result.screened = kept.get("screened")
    return result


def cloudnet_layout(
    unit: ProductUnit, products: dict[str, xr.Dataset], config: Config
) -> dict[str, xr.Dataset]:
    """The ACTRIS Cloudnet files of a scan unit's products (:mod:`cwproc.products.cloudnet`)."""
    from cwproc.pipeline.input_files import held_or_identity
    from cwproc.products.cloudnet import cloudnet_products

    first = held_or_identity(unit.inputs[0]) if unit.inputs else None
    source = str(first.attrs.get("instrument", "")) if first is not None else ""
    return cloudnet_products(
        products,
        altitude_m=config.output.altitude_m,
        site=config.output.site,
        source=source or "Doppler lidar",
        near_range_m=config.doppler_lidar.near_range_m,
    )


def unit_products(
    unit: ProductUnit,
    config: Config,
    notes: list[str] | None = None,
    *,
    chunk_bytes: int | None = None,
    kept: dict[str, xr.Dataset] | None = None,
) -> dict[str, xr.Dataset]:
    """The products of one unit, ``{product name: dataset}`` (the chain of :func:`run_unit`).

    Non-fatal remarks (a product that could not be made) are appended to ``notes``.
    A scan unit is run chunk by chunk (:func:`cwproc.pipeline.stream.stream_unit`,
    identical products in bounded memory, ``chunk_bytes`` of input per chunk); a day
    whose chunks would decide differently from the whole day runs whole
    (:func:`~cwproc.pipeline.stream.run_scan_chain` with ``whole=True``), and so does a
    day whose screened scans are asked for in ``kept`` or with the L1 product.

    Raises
    ------
    CwprocError
        The chain cannot run on these data (the message says why).
    """
    if unit.kind == "scan":
        # the lidar chain, here: a sonic or wind-record command does not import it
        from cwproc.pipeline.stream import STREAM_CHUNK_BYTES, run_scan_chain, stream_unit
    # the L1 product keeps every stare ray and gate of the day: the day runs whole
    if unit.kind == "scan" and kept is None and not config.doppler_lidar.enabled:
        products = stream_unit(
            unit,
            config,
            notes,
            lambda item: load_item(item, config),
            chunk_bytes or STREAM_CHUNK_BYTES,
        )
        if products is not None:
            return products
    load_unit(unit, config)
    ds = concat_unit(unit)
    if unit.kind == "scan":
        if notes is not None:
            notes.extend(describe_scan_inputs(unit))
        from cwproc.pipeline.cross import cross_scans

        chain = ScanChain(config)
        ds, snr = chain.prepare(ds, unit, None, notes)
        if notes is not None and snr.summary:
            notes.append(snr.summary)
        cross = cross_scans(unit, config, notes)
        return run_scan_chain(chain, [ds], whole=True, notes=notes, kept=kept, cross=cross)
    if unit.kind == "wind_record":
        return process_wind_record(ds, config)
    return process_sonic(ds, config)


#: product -> (the variable that makes it, its flag variable); a product whose variable
#: is missing everywhere is not written (:func:`empty_reason`)
MAIN_VARIABLES: dict[str, tuple[str, str]] = {
    "wind": ("u", "qc_flag"),
    "turbulence": ("epsilon", "turbulence_flag"),
    "stare": ("w_mean", "stare_flag"),
    "doppler_lidar": ("snr", "doppler_lidar_flag"),
}


def empty_reason(name: str, ds: xr.Dataset, config: Config, *, unit_kind: str = "") -> str:
    """Why product ``name`` is not written: its main variable is missing everywhere.

    '' when it holds at least one value (or is not a product of :data:`MAIN_VARIABLES`).
    The note names the product, the variable and the flags that every missing value
    carries, most frequent first (e.g. a day of stares with a VAD every 15 minutes:
    every block of ``n_scans`` conical scans is partial, so no epsilon), so that no
    product of nothing but missing values reaches a user without the reason. The flags
    are read with the meanings of the unit's product (``unit_kind`` "wind_record": the
    wind-record bits, and the DBS flags of a WindCube ``.rtd`` file).
    """
    variable, flag = MAIN_VARIABLES.get(name, ("", ""))
    if variable not in ds or np.isfinite(ds[variable].values).any():
        return ""
    text = f"no {name} product written: every {variable} is missing"
    table = product_table(product_kind(name, unit_kind) if unit_kind else name)
    if "dbs_flag" in ds:
        flag = "dbs_flag"
    meta = table.get(flag)
    if flag in ds and meta is not None and meta.flag_meanings:
        meanings = str(meta.flag_meanings).split()
        values = np.nan_to_num(np.asarray(ds[flag].values, dtype=float)).astype(np.int64).ravel()
        counts = {
            m: int(np.sum(values & int(k) != 0))
            for m, k in zip(meanings, meta.flag_masks, strict=False)
        }
        seen = sorted((m for m in counts if counts[m]), key=lambda m: -counts[m])
        if seen:
            text += f" ({flag}: {', '.join(f'{m} {counts[m]}/{values.size}' for m in seen)})"
    if name == "turbulence" and "partial_block" in text:
        text += (
            f"; a block needs at least half of [turbulence] n_scans = "
            f"{config.turbulence.n_scans} consecutive conical scans"
        )
    return text


def internal_error(exc: BaseException) -> str:
    """One line for an unexpected exception: where it came from, to report as a bug."""
    frame = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
    where = f" at {Path(frame.filename).name}:{frame.lineno}" if frame else ""
    return (
        f"internal error {type(exc).__name__}{where}: {exc} "
        "(a bug in cwproc; please report it with this line)"
    )
