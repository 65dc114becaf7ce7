"""Checked instrument times (issue 17.4): implausible dates are errors naming the line."""

from pathlib import Path

import numpy as np
import pytest

from cwproc.errors import InputFileError
from cwproc.io.halo import read_hpl
from cwproc.io.timecheck import EARLIEST, check_times, epoch_seconds_to_times

SAMPLE = Path(__file__).resolve().parents[2] / "sample_data" / "streamline"


def test_plausible_times_pass_and_nat_is_left_to_the_reader():
    t = np.array(["2024-06-01T00:00", "NaT", "2024-06-01T00:10"], dtype="datetime64[ns]")
    np.testing.assert_array_equal(check_times("f", t, 5), t)


@pytest.mark.parametrize("stamp", ["1755-04-23T00:00", "1990-01-01T00:00", "2200-01-01T00:00"])
def test_implausible_time_names_its_line(stamp):
    t = np.array(["2024-06-01T00:00", stamp], dtype="datetime64[ns]")
    with pytest.raises(InputFileError, match="outside the plausible range") as err:
        check_times("f.dat", t, 5)
    assert err.value.line == 6


def test_huge_counter_is_an_error_not_a_wrapped_date():
    """GHG Seconds = 99999999999999 gave a 1976 product (int64 nanoseconds wrapped)."""
    epoch = np.datetime64("1970-01-01", "ns")
    with pytest.raises(InputFileError, match="time counter") as err:
        epoch_seconds_to_times("x.data", np.array([1.7e9, 99999999999999.0]), [0, 0], epoch, 9)
    assert err.value.line == 10
    zero = np.array([0.0])  # TOB1 zero padding: the epoch itself
    with pytest.raises(InputFileError):
        epoch_seconds_to_times("x.tob", zero, [0], np.datetime64("1990-01-01", "ns"), 1)
    ok = epoch_seconds_to_times("x.data", np.array([1.7e9]), [5], epoch, 1)
    assert ok[0] == epoch + np.timedelta64(1_700_000_000_000_000_005, "ns")
    assert ok[0] > EARLIEST


def test_flipped_year_in_a_hpl_header_names_line_10(tmp_path):
    raw = next(SAMPLE.glob("*.hpl")).read_bytes()
    bad = tmp_path / "bad.hpl"
    bad.write_bytes(raw.replace(b"Start time:\t2024", b"Start time:\t1755", 1))
    with pytest.raises(InputFileError, match="plausible") as err:
        read_hpl(bad)
    assert err.value.line == 10
