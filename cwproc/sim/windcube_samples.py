"""The WindCube samples of ``sample_data/`` (``cwproc.sim.sample_data`` writes them).

``windcube/``: the wind records of the shared profile as the ``.sta`` generations v1,
v2.1 (``NA`` values) and v2.1 one-minute ``.stdsta`` (the v2 file is written by
:func:`cwproc.sim.sample_data.write_windcube_sta`); ``windcube_rtd/``: lines of sight of
the virtual WindCube (:mod:`cwproc.sim.windcube`) in the v2.1, v2 and v1 ``.rtd``
layouts, the ``.sta`` of the same 10 min and the truth.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from cwproc.sim.output import fresh_folder, write_truth
from cwproc.sim.specs import WindRecordSpec
from cwproc.sim.windcube import (
    WindCubeSpec,
    instrument_statistics,
    rtd_truth,
    simulate_dbs,
    windcube_field,
    write_rtd,
    write_sta,
)


def wind_record_statistics(
    spec: WindRecordSpec, rec: dict[str, np.ndarray], interval_s: int = 600
) -> dict[str, np.ndarray]:
    """The records ``rec`` of ``spec`` (``cwproc.sim.sample_data._wind_records``) as the
    statistics :func:`cwproc.sim.windcube.write_sta` writes (stamps at the end of each
    interval of ``interval_s``)."""
    heights = np.asarray(spec.heights_m)
    shape = rec["speed"].shape
    t0 = np.datetime64(spec.start, "s")
    return {
        "time": t0 + np.timedelta64(interval_s, "s") * (np.arange(shape[0]) + 1),
        "speed": rec["speed"],
        "std": rec["std"],
        "min": np.maximum(rec["min"], 0.0),
        "max": rec["max"],
        "direction": rec["direction"],
        "w": rec["w"],
        "w_std": np.full(shape, 0.1),
        "cnr": np.broadcast_to(-12.0 - 0.02 * heights, shape),
        "cnr_min": np.broadcast_to(-14.0 - 0.02 * heights, shape),
        "availability": np.full(shape, 100.0),
    }


def with_missing_values(stats: dict[str, np.ndarray], every: int = 7) -> dict[str, np.ndarray]:
    """``stats`` with every ``every``-th value of each per-height variable missing (NaN),
    at shifting heights: the gaps a WF 2.x ``.sta`` writes as ``NA``, ``-`` or nothing."""
    out = dict(stats)
    for j, key in enumerate(k for k in stats if k != "time"):
        values = np.array(stats[key], dtype=float)
        flat = values.reshape(-1)
        flat[(j + 3) % every :: every * 5] = np.nan
        out[key] = values
    return out


def write_windcube_variants(
    spec: WindRecordSpec, rec: dict[str, np.ndarray], folder: str | os.PathLike
) -> list[Path]:
    """The records of ``spec`` as the other WindCube ``.sta`` generations: v1 (software
    3.x, ``HeaderLength``, short names), v2.1 (WF 2.x: ``ScanAngle (°)=NA`` and missing
    values written ``NA``, ``-`` or nothing) and v2.1 one-minute statistics (``.stdsta``)."""
    folder = Path(folder)
    day = "_".join(spec.start[:10].split("-"))
    heights = np.asarray(spec.heights_m)
    ten = wind_record_statistics(spec, rec)
    return [
        write_sta(
            ten, heights, folder / f"WLS7-099_{day}__00_00_00.sta", "v1", scan_angle_deg=30.0
        ),
        write_sta(
            with_missing_values(ten),
            heights,
            folder / f"WLS71999_{day}__00_00_00.sta",
            "v2.1",
            missing_tokens=("NA", "-", ""),
        ),
        write_sta(
            wind_record_statistics(spec, rec, interval_s=60),
            heights,
            folder / f"WLS71999_{day}__06_00_00.stdsta",
            "v2.1",
        ),
    ]


def write_windcube_rtd_samples(
    folder: str | os.PathLike, truth_path: str | os.PathLike
) -> list[Path]:
    """Simulated WindCube ``.rtd`` files in the v2.1, v2 and v1 layouts, the v2.1 ``.sta``
    of the same 10 min (the virtual instrument's own statistics) and the truth JSON."""
    folder = fresh_folder(folder, "*.rtd")
    spec = WindCubeSpec()
    field = windcube_field(spec)
    ds = simulate_dbs(spec, field=field)
    written = [write_rtd(ds, spec, folder / "WLS71999_2024_06_01__00_00_00.rtd", "v2.1")]
    written.append(
        write_sta(
            instrument_statistics(ds, 600.0),
            ds["height"].values,
            folder / "WLS71999_2024_06_01__00_00_00.sta",
            "v2.1",
        )
    )
    short = WindCubeSpec(start="2024-06-01T00:10:00", duration_s=120.0)
    written.append(
        write_rtd(
            simulate_dbs(short, field=field),
            short,
            folder / "WLS7-999_2024_06_01__00_10_00.rtd",
            "v2",
        )
    )
    v1 = WindCubeSpec(start="2024-06-01T00:12:00", duration_s=120.0, vertical_beam=False)
    written.append(
        write_rtd(
            simulate_dbs(v1, field=field), v1, folder / "WLS7-099_2024_06_01__00_12_00.rtd", "v1"
        )
    )
    written.append(write_truth(truth_path, rtd_truth(spec, field, ds)))
    return written
