"""Joining the sonic files of one instrument-day.

(:func:`cwproc.pipeline.product_units.concat_sonic`)
"""

import numpy as np
import pytest
import xarray as xr

from cwproc.errors import CwprocError
from cwproc.pipeline.product_units import concat_sonic

RATE = 10.0


def part(start_s: float, n: int, rate: float = RATE) -> xr.Dataset:
    """``n`` samples of a 10 Hz sonic from ``start_s`` s after midnight; u = the time (s)."""
    seconds = start_s + np.arange(n) / rate
    time = np.datetime64("2024-06-01", "ns") + (seconds * 1e9).astype("timedelta64[ns]")
    return xr.Dataset(
        {"u": ("time", seconds)},
        coords={"time": time},
        attrs={"sampling_rate_hz": rate, "source_file": f"part_{start_s:g}.dat"},
    )


def test_parts_in_any_order_give_the_day_in_time_order():
    first, second = part(0.0, 50), part(5.0, 50)
    in_order = concat_sonic([first, second], "day")
    reversed_ = concat_sonic([second, first], "day")
    np.testing.assert_array_equal(in_order["u"].values, np.arange(100) / RATE)
    assert in_order.indexes["time"].is_monotonic_increasing
    np.testing.assert_array_equal(reversed_["u"].values, in_order["u"].values)
    np.testing.assert_array_equal(reversed_["time"].values, in_order["time"].values)
    # the attributes are the first part's, the rate the median of the parts'
    assert in_order.attrs["source_file"] == "part_0.dat"
    assert reversed_.attrs["source_file"] == "part_5.dat"


def test_a_single_part_in_order_is_not_changed():
    one = part(0.0, 20)
    attrs = dict(one.attrs)
    out = concat_sonic([one], "day")
    out.attrs["sampling_rate_hz"] = 99.0  # the caller's dataset keeps its own
    assert one.attrs == attrs
    xr.testing.assert_identical(out.drop_attrs(), one.drop_attrs())


def test_rates_that_differ_are_refused():
    with pytest.raises(CwprocError, match="different sampling rates"):
        concat_sonic([part(0.0, 10), part(5.0, 10, rate=20.0)], "day")
