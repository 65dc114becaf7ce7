"""Composition of the stages: one chain of stages, used by every client.

:func:`run_unit` is the only entry: ``cwproc retrieve`` (:func:`retrieve_files`),
``cwproc batch``, ``cwproc plot`` and the Python API call it. The order of the stages of
scan data and the day's decisions live in one place, :class:`~.scan_chain.ScanChain`, which
:func:`~.stream.run_scan_chain` runs over one chunk (the whole day) or many.

Every input is read on its own (:func:`read_input`; a bad file fails
alone, with one line naming the file, the line and the problem), inputs that belong
together are grouped into *product units* (:func:`group_units`), each unit is run
(:func:`run_unit`: products, notes, failures) and its products written atomically
(:func:`write_unit_products`).

Modules
-------
``input_files``
    one input: its format, checksum and dataset; read once, read again unchanged.
``input_checks``
    whether the configuration reads an input (its format, its instrument).
``file_search``
    the inputs of a run: files named, folders searched, what is skipped and why.
``product_units``
    product units: keys, grouping inputs into units, joining their datasets.
``scan_chain``
    ``ScanChain``: the stage chain of scan data and the day's decisions, pure.
``chain``
    the stage chain of each kind of unit (scan: runs ``ScanChain`` whole; wind record,
    sonic), pure.
``probe``
    the configured lidar's probe volume, and whether it describes the scans.
``background_files``
    Stream Line background files, found and read for the SNR correction stage.
``stream``
    the executor of ``ScanChain``: a day of scans whole or chunk by chunk in bounded
    memory (the same products), and the chunks of a unit's files.
``run``
    :func:`run_unit` and :class:`UnitResult`.
``write``
    products written with provenance, all or none.
``retrieve``
    :func:`read_units` (files -> product units) and :func:`retrieve_files`: read, run
    and write a list of files.
"""

from cwproc.pipeline.chain import (
    process_scan_day,
    process_scans,
    process_sonic,
    process_wind_record,
    screened_wind,
    sf_summary_tables,
)
from cwproc.pipeline.input_checks import (
    format_mismatch,
    instrument_mismatch,
    no_input_of_format,
    other_formats_note,
)
from cwproc.pipeline.input_files import InputFile, read_input
from cwproc.pipeline.probe import probe_for, probe_from_config, probe_mismatch
from cwproc.pipeline.product_units import (
    ProductUnit,
    group_units,
    name_part,
    sonic_identity,
    sonic_span,
    unit_key,
    unit_label,
)
from cwproc.pipeline.retrieve import FoundUnits, RunReport, read_units, retrieve_files
from cwproc.pipeline.run import EXIT_FAILED, EXIT_OK, UnitResult, internal_error, run_unit
from cwproc.pipeline.scan_chain import ScanChain, count_stare_rays
from cwproc.pipeline.write import product_path, write_unit_products

__all__ = [
    "EXIT_FAILED",
    "EXIT_OK",
    "FoundUnits",
    "InputFile",
    "ProductUnit",
    "RunReport",
    "ScanChain",
    "UnitResult",
    "count_stare_rays",
    "format_mismatch",
    "group_units",
    "instrument_mismatch",
    "internal_error",
    "name_part",
    "no_input_of_format",
    "other_formats_note",
    "probe_for",
    "probe_from_config",
    "probe_mismatch",
    "process_scan_day",
    "process_scans",
    "process_sonic",
    "process_wind_record",
    "product_path",
    "read_input",
    "read_units",
    "retrieve_files",
    "run_unit",
    "screened_wind",
    "sf_summary_tables",
    "sonic_identity",
    "sonic_span",
    "unit_key",
    "unit_label",
    "write_unit_products",
]
