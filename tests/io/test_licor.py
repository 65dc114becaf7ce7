"""LI-COR GHG .data reader against the real fragment (FORMATS.md section 4.3)."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cwproc.errors import InputFileError
from cwproc.io import Format, detect_format
from cwproc.io.licor import read_ghg, sonic_temperature_from_sos

GHG = "sonic/head_ghg.data"

FIXTURE_CHECK = HealthCheck.function_scoped_fixture


def test_real_fragment_shape_and_values(real_data):
    ds = read_ghg(real_data / GHG)
    assert detect_format(real_data / GHG) == Format.GHG
    assert ds.sizes["time"] == 2
    # Seconds 1501691400 is 16:30Z; Date/Time 11:30 are US/Central (CDT = UTC-5)
    assert str(ds["time"].values[0]) == "2017-08-02T16:30:00.000000000"
    assert str(ds["time"].values[1]) == "2017-08-02T16:30:00.100000000"
    assert ds["u"].values == pytest.approx([0.752103, 0.781697])
    assert ds["v"].values == pytest.approx([-0.591885, -0.542902])
    assert ds["w"].values == pytest.approx([0.199506, 0.195424])
    # T_s = c^2/403 - 273.15 with c = 346.769 m/s
    assert float(ds["temperature"][0]) == pytest.approx(346.769**2 / 403 - 273.15)
    assert ds.attrs["sampling_rate_hz"] == pytest.approx(10.0)
    assert ds.attrs["ghg_timezone"] == "US/Central"
    assert ds.attrs["ghg_sn"] == "75H-2802"


def test_sos_temperature_is_physical():
    # c^2 = 403 T_s exactly (Kaimal and Gaynor 1991)
    c20 = np.sqrt(403.0 * 293.15)
    assert sonic_temperature_from_sos(np.array([c20]))[0] == pytest.approx(20.0, abs=1e-9)
    # dry air at 0 degC (331.3 m/s, gamma R_d = 401.9): the 403 constant reads 0.8 K low
    assert sonic_temperature_from_sos(np.array([331.3]))[0] == pytest.approx(-0.8, abs=0.1)


def _lines(real_data) -> list[str]:
    return (real_data / GHG).read_text().splitlines(keepends=True)


@pytest.mark.parametrize(
    ("index", "mutate", "match"),
    [
        (9, lambda s: s.replace("DATA\t", "DATX\t", 1), "start with DATA"),
        (9, lambda s: s.replace("\t0.752103", "\t0.75x2103", 1), "not a number"),
        (
            10,
            lambda s: s.replace("\t 31", "", 1) if " 31" in s else s.rsplit("\t", 1)[0] + "\n",
            "fields",
        ),
        (9, lambda s: s.replace("\t1501691400", "\t", 1), "Seconds"),
    ],
)
def test_damaged_copies_name_the_line(tmp_path, real_data, index, mutate, match):
    lines = _lines(real_data)
    lines[index - 1] = mutate(lines[index - 1])
    p = tmp_path / "g.data"
    p.write_text("".join(lines))
    with pytest.raises(InputFileError, match=match) as err:
        read_ghg(p)
    assert err.value.line == index


def test_missing_header_and_columns(tmp_path, real_data):
    lines = _lines(real_data)
    p = tmp_path / "g.data"
    p.write_text("".join(lines[:7]))
    with pytest.raises(InputFileError, match="DATAH"):
        read_ghg(p)
    p.write_text("".join(lines[:8]))
    with pytest.raises(InputFileError, match="no DATA lines"):
        read_ghg(p)
    p.write_text("".join(lines).replace("Aux 1 - U (m/s)", "Aux 1 - X (m/s)"))
    with pytest.raises(InputFileError, match="Aux 1 - U") as err:
        read_ghg(p)
    assert err.value.line == 8
    assert read_ghg(p, columns={"u": "Aux 1 - X (m/s)"}).sizes["time"] == 2


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.data())
def test_mutated_ghg_gives_dataset_or_input_file_error(tmp_path, real_data, data):
    blob = bytearray((real_data / GHG).read_bytes())
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(blob) - 1))
        blob[i] = data.draw(st.sampled_from(list(b"0123456789\t.:-\nDATx \x00")))
    p = tmp_path / "m.data"
    p.write_bytes(bytes(blob[: data.draw(st.integers(0, len(blob)))]))
    try:
        ds = read_ghg(p)
    except InputFileError:
        return
    assert isinstance(ds, xr.Dataset) and ds.sizes["time"] > 0
