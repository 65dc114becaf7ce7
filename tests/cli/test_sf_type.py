"""``cwproc sf-type`` and ``cwproc simulate sonic`` end to end."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.io.netcdf import read_product
from cwproc.metadata.products import undeclared_variables


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim")
    res = CliRunner().invoke(
        main, ["simulate", "sonic", "-o", str(out), "--type", "2", "--hours", "1", "--seed", "5"]
    )
    assert res.exit_code == 0, res.output
    return out


def test_simulate_sonic_writes_meteo2_and_truth(simulated):
    files = sorted(simulated.glob("*.txt"))
    assert len(files) == 1
    assert files[0].read_text().startswith("# cwproc meteo2 v1")
    truth = json.loads((simulated / "meteo2_sim_type2_truth.json").read_text())
    assert truth["sf_type"] == 2 and truth["seed"] == 5 and truth["hours"] == 1.0


def test_sf_type_product_tables_and_damaged_file(simulated, tmp_path):
    good = sorted(simulated.glob("*.txt"))[0]
    bad = tmp_path / "damaged.txt"
    lines = good.read_text().splitlines(keepends=True)
    lines[40] = lines[40].replace(",", ",?", 1)
    bad.write_text("".join(lines[:300]))
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["sf-type", str(good), str(bad), "-o", str(out), "-c", "meteo2"])
    assert res.exit_code == 1
    errors = [ln for ln in res.output.splitlines() if ln.startswith("error:")]
    bad_value = lines[40].split(",")[1]
    assert errors == [f"error: {bad}:41: column 'u': '{bad_value}' is not a number"]
    (product,) = out.glob("meteo2_*_20140601_sf.nc")  # named after the station's folder
    sf = read_product(product)
    assert undeclared_variables(sf) == []
    assert sf.sizes["window"] == 6 and list(sf["component"].values) == [
        "longitudinal",
        "transverse",
        "vertical",
    ]
    assert np.mean(sf["sf_type"].values == 2) >= 0.95
    assert sf["sf_a2"].attrs["units"] == "1" and sf["r_max"].attrs["units"] == "m"
    assert "Gladkikh" in sf.attrs["references"] and good.name in sf.attrs["input_files"]
    assert "[sonic]" in sf.attrs["cwproc_config"]
    occ = pd.read_csv(out / "sf_type_occurrence.csv", index_col=0)
    assert occ.loc["longitudinal", "windows"] == 6
    assert occ.loc["longitudinal", "type2_pct"] == pytest.approx(
        100 * np.mean(sf["sf_type"].sel(component="longitudinal").values == 2), abs=0.01
    )
    stats = pd.read_csv(out / "sf_parameters.csv")
    assert set(stats.columns) == {"type", "component", "parameter", "count", "mean", "median"}
    assert "Table 2" in res.output and "Tables 3-5" in res.output


def test_real_toa5_is_typed(real_data, tmp_path):
    src = real_data / "sonic" / "TOA5_6843.ts_Above_2012_06_07_1245.dat"
    res = CliRunner().invoke(main, ["sf-type", str(src), "-o", str(tmp_path), "-q", "-c", "csat3"])
    assert res.exit_code == 0, res.output
    sf = read_product(tmp_path / "toa5_6843_20120607_sf.nc")  # station 6843 of the header
    # the complete window is typed for every component, and the local slope at r_N of
    # the horizontal components is inertial-range-like (2/3 within 0.15)
    full = sf.isel(window=1)
    assert np.all(full["sf_type"].values > 0)
    for comp in ("longitudinal", "transverse"):
        c = full.sel(component=comp)
        slope = float(c[{1: "sf_mu", 2: "sf_a1", 3: "sf_d1"}[int(c["sf_type"])]])
        assert slope == pytest.approx(2 / 3, abs=0.15)
    # 12:45:00.05-13:00:00 at 20 Hz: windows 12:40 (5 min, skipped), 12:50 (complete,
    # analysed) and 13:00 (its first sample only, skipped)
    assert sf.sizes["window"] == 3
    assert list(sf["window_flag"].values) == [1, 0, 1]
    assert sf["valid_fraction"].values[1] == pytest.approx(1.0)
    assert 0.5 < float(sf["mean_horizontal_wind"][1]) < 5.0
    assert sf.attrs["instrument"].startswith("Campbell Scientific CSAT3")


def test_product_has_no_cf_high_priority_failures(simulated, tmp_path, compliance):
    config = tmp_path / "site.toml"
    config.write_text(
        '[output]\ninstitution = "IAO SB RAS"\ncreator_name = "A. Sonic"\n'
        'project = "test"\nlatitude = 56.48\nlongitude = 85.05\naltitude_m = 160.0\n'
    )
    res = CliRunner().invoke(
        main, ["sf-type", str(simulated), "-o", str(tmp_path), "-q", "-c", str(config)]
    )
    assert res.exit_code == 0, res.output
    (product,) = tmp_path.glob("meteo2_*_20140601_sf.nc")
    high, acdd = compliance(product)
    assert high == []
    # ACDD wants a standard_name on every variable; CF has none for the fitted SF
    # coefficients and lags (23 of them), which caps the score near 0.79
    assert acdd >= 0.75


def test_directory_input_skips_unreadable_files(simulated, tmp_path):
    d = tmp_path / "in"
    shutil.copytree(simulated, d)
    res = CliRunner().invoke(main, ["sf-type", str(d), "-o", str(tmp_path / "o"), "-q"])
    assert res.exit_code == 0, res.output
    assert len(list((tmp_path / "o").glob("meteo2_*_20140601_sf.nc"))) == 1
