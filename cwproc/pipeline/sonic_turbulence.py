"""The sonic turbulence chain: read sonic files, run the stage per format and UTC day, write.

Used by ``cwproc sonic-turbulence``. Every input is read on its own (a damaged file
fails alone, with one line naming the file and the problem); the samples of the
inputs of one format and sampling rate are joined in time and
:func:`cwproc.stages.sonic_turbulence.sonic_turbulence` makes one product per UTC day,
``<format>_<YYYYMMDD>_sonic-turbulence.nc``.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc.config import Config
from cwproc.errors import CwprocError
from cwproc.io import detect_format, get_reader
from cwproc.pipeline.input_files import reader_options
from cwproc.products.catalogue import describe_product
from cwproc.products.writer import add_site_coordinates, site_attributes, write_product
from cwproc.stages.sonic_turbulence import sonic_turbulence


@dataclass
class SonicTurbulenceReport:
    """What a run wrote and what failed (one line per failure, naming the file)."""

    written: list[Path] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)
    #: why a day of readable data gave no product (no window with enough valid samples)
    notes: list[str] = field(default_factory=list)


def empty_product_note(product: xr.Dataset, unit: str) -> str | None:
    """Why ``product`` holds no statistic (every window without a variance), or None.

    A day shorter than one window, or whose windows lack valid samples, gives windows of
    missing values only: no product is written for it, and this note says why.
    """
    if np.isfinite(product["velocity_variance"].values).any():
        return None
    window = float(product.attrs.get("window_s", np.nan))
    valid = product["valid_fraction"].values
    most = float(np.nanmax(valid)) if np.isfinite(valid).any() else 0.0
    return (
        f"{unit}: no product: no window of {window:g} s holds enough valid samples "
        f"(at most {most:.0%} of a window); a shorter --window may fit the data"
    )


def _read_groups(
    files: list[Path], config: Config, report: SonicTurbulenceReport
) -> dict[tuple[str, float], list[tuple[Path, xr.Dataset]]]:
    """The readable sonic inputs grouped by (format, sampling rate rounded to 0.01 Hz)."""
    groups: dict[tuple[str, float], list[tuple[Path, xr.Dataset]]] = {}
    for path in files:
        path = Path(path)
        try:
            fmt = detect_format(path)
            ds = get_reader(fmt)(path, **reader_options(config, fmt))
            if not {"u", "v", "w"} <= set(ds.data_vars):
                raise CwprocError("not a sonic file (no u, v, w)")
        except (CwprocError, OSError, ValueError) as exc:
            text = str(exc)
            report.failures.append(text if text.startswith(str(path)) else f"{path}: {text}")
            continue
        keep = [v for v in ("u", "v", "w", "temperature", "sample_flag") if v in ds]
        key = (fmt.value, round(float(ds.attrs.get("sampling_rate_hz", np.nan)), 2))
        groups.setdefault(key, []).append((path, ds[keep]))
    return groups


def sonic_turbulence_files(
    files: list[Path],
    outdir: str | os.PathLike,
    config: Config,
    **options: object,
) -> SonicTurbulenceReport:
    """Sonic turbulence products of ``files`` in ``outdir``.

    Parameters
    ----------
    files : list of Path
        Sonic files of any format cwproc reads.
    outdir : path
        Product directory.
    config : Config
        Reader options (``[reader.<format>]``), the typing parameters (``[sonic]``,
        except its window) and the ``[output]`` site attributes.
    **options
        Keyword arguments of :func:`cwproc.stages.sonic_turbulence.sonic_turbulence`
        (``window_s``, ``despike``, ``rotation``, ``detrend``, ``height_m``,
        ``latitude_deg``).

    Returns
    -------
    SonicTurbulenceReport
    """
    report = SonicTurbulenceReport()
    groups = _read_groups(files, config, report)
    typing = dataclasses.asdict(config.sonic)
    typing.pop("window_s")
    described = describe_product("sonic_turbulence", "sonic")
    for (fmt_name, _rate), members in sorted(groups.items()):
        sonic = xr.concat([ds for _, ds in members], dim="time", combine_attrs="override").sortby(
            "time"
        )
        day = sonic["time"].dt.strftime("%Y%m%d").values
        for d in sorted(set(day)):
            try:
                product = sonic_turbulence(
                    sonic.isel(time=np.flatnonzero(day == d)), typing=typing, **options
                )
            except CwprocError as exc:
                report.failures.append(f"{fmt_name} {d}: {exc}")
                continue
            empty = empty_product_note(product, f"{fmt_name} {d}")
            if empty is not None:
                report.notes.append(empty)
                continue
            target = Path(outdir) / f"{fmt_name}_{d}_sonic-turbulence.nc"
            write_product(
                add_site_coordinates(product, config.output),
                target,
                product="sonic_turbulence",
                title=described.title,
                summary=described.summary,
                keywords=described.keywords,
                references=described.references,
                inputs=[p for p, _ in members],
                config_toml=config.to_toml(),
                extra_attrs=site_attributes(config.output),
            )
            report.written.append(target)
    return report
