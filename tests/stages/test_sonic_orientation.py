"""``[sonic] orientation_deg``: the geographic direction of the window-mean wind.

The structure-function types are taken along and across the mean wind, so they do not
depend on how the sonic is turned; the orientation (azimuth of the sonic's +x axis)
only turns the mean wind of the instrument frame into ``wind_direction``.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from cwproc.config import config_from_toml, load_config
from cwproc.errors import ConfigError
from cwproc.sim.sonic import simulate_sonic_dataset
from cwproc.stages.sonic_sf import geographic_wind_direction, structure_function_types

#: angle of the simulated mean wind from +x towards +y (degree, anticlockwise from above)
ALPHA = 30.0


@pytest.fixture(scope="module")
def sonic() -> xr.Dataset:
    return simulate_sonic_dataset(hours=1, sf_type=1, seed=4, speed=5.0, direction_deg=ALPHA)


def test_x_axis_pointing_east_and_wind_along_it_comes_from_the_west():
    assert geographic_wind_direction(np.array([2.0]), np.array([0.0]), 90.0)[0] == 270.0
    # +y is 90 degrees anticlockwise of +x: with +x east, +y points north
    assert geographic_wind_direction(np.array([0.0]), np.array([2.0]), 90.0)[0] == 180.0
    assert np.isnan(geographic_wind_direction(np.array([0.0]), np.array([0.0]), 10.0)[0])


def test_orientation_changes_only_the_wind_direction(sonic):
    north = structure_function_types(sonic, orientation_deg=0.0)
    turned = structure_function_types(sonic, orientation_deg=75.0)
    # the mean wind blows towards azimuth orientation - ALPHA, from 180 degrees beyond
    np.testing.assert_allclose(north["wind_direction"].values, 180.0 - ALPHA, atol=3.0)
    shift = np.mod(turned["wind_direction"].values - north["wind_direction"].values, 360.0)
    np.testing.assert_allclose(shift, 75.0, atol=1e-9)
    for name in north.data_vars:
        if name not in ("wind_direction", "sf_type"):  # sf_type: attrs record the parameters
            xr.testing.assert_identical(north[name], turned[name])
    np.testing.assert_array_equal(north["sf_type"].values, turned["sf_type"].values)
    assert turned.attrs["sonic_sf_parameters"]["orientation_deg"] == 75.0


def test_presets_and_sonic_config_carry_the_orientation():
    for preset in ("csat3", "meteo2"):
        assert load_config(preset).sonic.orientation_deg == 0.0
    cfg = config_from_toml("[sonic]\norientation_deg = 42.5\n")
    assert cfg.sonic.orientation_deg == 42.5


@pytest.mark.parametrize(
    ("toml", "key"),
    [
        ("[instrument]\nsonic_orientation_deg = 10.0\n", "instrument.sonic_orientation_deg"),
        ("[reader.toa5]\norientation_deg = 10.0\n", "reader.toa5.orientation_deg"),
    ],
)
def test_the_old_places_of_the_orientation_are_refused_by_name(toml, key):
    with pytest.raises(ConfigError) as err:
        config_from_toml(toml, source="old.toml")
    message = str(err.value)
    assert key in message and "[sonic] orientation_deg" in message
