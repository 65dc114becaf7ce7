"""Averaged tables (fluxes, 1-30 min statistics) given as sonic data: refused once, in one
line that says what they are and what to give instead (issue 32)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.errors import InputFileError
from cwproc.io.averaged import averaged_table_reason
from cwproc.io.campbell import read_toa5
from cwproc.io.campbell_tob1 import read_tob1
from cwproc.io.sonic_samples import sonic_dataset

SAMPLE = Path(__file__).resolve().parents[2] / "sample_data" / "sonic"
FLUX_NAMES = ["Fc_molar", "LE", "H", "Tau", "u_star", "Ux", "Uy", "Uz", "Ts"]


def _q(fields: list[str]) -> str:
    return ",".join(f'"{f}"' for f in fields)


def write_easyflux_tob1(path: Path, n: int = 48) -> Path:
    """A TOB1 of 30-min EasyFlux-style results (two days would be 96 records)."""
    names = ["SECONDS", "NANOSECONDS", "RECORD", *FLUX_NAMES]
    units = ["SECONDS", "NANOSECONDS", "RN", "umol/m^2/s", "W/m^2", "W/m^2", "kg/m/s^2"]
    units += ["m/s", "m/s", "m/s", "m/s", "degC"]
    header = [
        _q(["TOB1", "6843", "CR3000", "6843", "CR3000.Std.31", "CPU:EasyFlux.CR3", "1", "Flux"]),
        _q(names),
        _q(units),
        _q(["", "", ""] + ["Avg"] * len(FLUX_NAMES)),
        _q(["ULONG", "ULONG", "ULONG"] + ["IEEE4"] * len(FLUX_NAMES)),
    ]
    dtype = np.dtype([("s", "<u4"), ("n", "<u4"), ("r", "<u4")] + [(c, "<f4") for c in FLUX_NAMES])
    rec = np.zeros(n, dtype=dtype)
    start = (np.datetime64("2024-06-01T00:30") - np.datetime64("1990-01-01T00:00")).astype(int)
    rec["s"] = start * 60 + 1800 * np.arange(n)
    rec["r"] = np.arange(n)
    for c in FLUX_NAMES:
        rec[c] = 1.0 + 0.1 * np.sin(np.arange(n))
    path.write_bytes(("\r\n".join(header) + "\r\n").encode("ascii") + rec.tobytes())
    return path


def test_easyflux_tob1_given_to_sf_type_is_one_line(tmp_path):
    path = write_easyflux_tob1(tmp_path / "TOB1_6843.Flux.dat", n=96)  # two days
    res = CliRunner().invoke(main, ["sf-type", str(path), "-o", str(tmp_path / "o")])
    errors = [line for line in res.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, res.output
    assert "an averaged table" in errors[0] and "Avg of Ux, Uy, Uz" in errors[0]
    assert "fluxes Fc_molar, LE, H, Tau" in errors[0]
    assert "give the raw 10-20 Hz wind samples instead" in errors[0]
    assert "lags" not in res.output
    assert "1 failure(s)" in res.output


def test_toa5_of_averages(tmp_path):
    lines = (SAMPLE / "TOA5_999.ts_data_2024_06_01_1200.dat").read_text().split("\n")
    lines[3] = lines[3].replace('"Smp"', '"Avg"')
    path = tmp_path / "TOA5_999.stats.dat"
    path.write_text("\n".join(lines))
    with pytest.raises(InputFileError, match=r"averaged table \(statistics: Avg of Ux, Uy, Uz"):
        read_toa5(path)


def test_the_samples_are_not_refused():
    assert read_toa5(SAMPLE / "TOA5_999.ts_data_2024_06_01_1200.dat").sizes["time"] > 1000
    assert read_tob1(SAMPLE / "TOB1_999.ts_data_2024_06_01_1200.dat").sizes["time"] > 1000


@pytest.mark.parametrize(("step_s", "refused"), [(0.05, False), (1.0, False), (60.0, True)])
def test_any_logger_with_a_record_a_minute_or_less_often(step_s, refused):
    """The generic rule of every sonic reader: a record every minute or more is statistics."""
    n = 50
    time = np.datetime64("2024-06-01T00:00") + (np.arange(n) * step_s * 1e9).astype(
        "timedelta64[ns]"
    )
    wind = {k: np.zeros(n) for k in "uvw"}
    build = lambda: sonic_dataset(  # noqa: E731
        "x.txt", time, wind, np.zeros(n), np.zeros(n), instrument="i", frame="f"
    )
    if refused:
        with pytest.raises(InputFileError, match="1-min statistics: a record every 1 min"):
            build()
    else:
        assert build().sizes["time"] == n


def test_reason_is_empty_for_samples():
    assert averaged_table_reason(names=["Ux"], processing=["Smp"], wind_fields=["Ux"]) == ""
