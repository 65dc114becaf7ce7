"""Metadata has one home (issue 16): the written products of the sample data.

The Stream Line wind product lists only its own ``qc_flag`` bits (rain belongs to the
wind records of ZephIR), no attribute cites one of cwproc's own files instead of a
paper, and every variable carries the units that ``cwproc.metadata.products``
declares for its product.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.errors import CwprocError
from cwproc.io.netcdf import read_product
from cwproc.metadata.products import (
    PRODUCT_VARIABLES,
    PRODUCTS,
    VARIABLES,
    apply_metadata,
    product_table,
)
from cwproc.products.catalogue import product_kind

SAMPLE = Path(__file__).resolve().parents[2] / "sample_data"

#: (command, input folder, configuration, unit kind) of every kind of sample product
RUNS = {
    "streamline": ("retrieve", "streamline", SAMPLE / "site.toml", "scan"),
    "zephir": ("retrieve", "zephir", "zephir300", "wind_record"),
    "windcube": ("retrieve", "windcube", "windcube", "wind_record"),
    "sonic": ("sf-type", "sonic", SAMPLE / "sonic.toml", "sonic"),
}


@pytest.fixture(scope="module")
def products(tmp_path_factory) -> dict[str, dict[str, Path]]:
    """The products of every sample folder: run -> {product file suffix: path}."""
    out: dict[str, dict[str, Path]] = {}
    for run, (command, folder, config, _kind) in RUNS.items():
        target = tmp_path_factory.mktemp(run)
        args = [command, str(SAMPLE / folder), "-c", str(config), "-o", str(target)]
        res = CliRunner().invoke(main, args)
        assert res.exit_code == 0, res.output
        files = sorted(target.glob("*.nc"))
        assert files, run
        out[run] = {p.stem.rsplit("_", 1)[1]: p for p in files}
    return out


def test_stream_line_wind_product_lists_only_its_own_flag_bits(products):
    wind = read_product(products["streamline"]["wind"])
    flag = wind["qc_flag"].attrs
    assert "rain" not in flag["flag_meanings"]
    assert flag["flag_meanings"].split() == ["too_few_rays", "azimuth_gap_too_large", "bad_fit"]
    np.testing.assert_array_equal(flag["flag_masks"], [1, 2, 4])
    # every bit the product sets is one it lists
    bits = np.bitwise_or.reduce(wind["qc_flag"].values.ravel().astype(int))
    assert bits & ~7 == 0


def test_wind_record_product_lists_rain(products):
    wind = read_product(products["zephir"]["wind"])
    assert wind["qc_flag"].attrs["flag_meanings"].split()[-1] == "rain"
    np.testing.assert_array_equal(wind["qc_flag"].attrs["flag_masks"], [1, 4, 8])


def test_no_attribute_of_a_product_cites_our_own_files(products):
    for run, files in products.items():
        for name, path in files.items():
            ds = read_product(path)
            places = [("global", ds.attrs)] + [(str(v), ds[v].attrs) for v in ds.variables]
            for where, attrs in places:
                for key, value in attrs.items():
                    if key == "history":  # the user's own command line
                        continue
                    text = str(value).lower()
                    assert "seed 0" not in text and "seed-0" not in text, (run, name, where, key)
                    assert "reference_values" not in text, (run, name, where, key)


def test_u_error_cites_the_vad_accuracy_paper(products):
    wind = read_product(products["streamline"]["wind"])
    refs = wind["u_error"].attrs["references"]
    assert "VAD scanning" in refs and "section 4" in refs


def test_every_variable_has_the_units_declared_for_its_product(products):
    for run, files in products.items():
        for name, path in files.items():
            ds = read_product(path)
            table = product_table(product_kind(name, RUNS[run][3]))
            for var in ds.variables:
                meta = table[str(var)]
                if meta.units is None:  # times: the encoding's "seconds since ..."
                    assert "since" in ds[var].encoding.get("units", ""), (run, var)
                    continue
                assert ds[var].attrs.get("units") == meta.units, (run, name, var)
                assert ds[var].attrs.get("long_name") == meta.long_name, (run, name, var)


def test_every_product_is_named_and_its_own_entries_are_declared():
    assert set(PRODUCT_VARIABLES) <= set(PRODUCTS)
    for entries in PRODUCT_VARIABLES.values():
        assert set(entries) <= set(VARIABLES)


def test_an_unknown_product_name_is_an_error_naming_it(products):
    ds = read_product(products["streamline"]["wind"])
    with pytest.raises(CwprocError, match="unknown product 'nonsense'") as err:
        apply_metadata(ds, product="nonsense")
    assert "wind_record" in str(err.value)  # and it lists the products there are


def test_the_named_product_selects_the_flag_bits_whatever_the_variables(products):
    """The same variables get the bits of the product they are said to be (no sniffing)."""
    ds = read_product(products["streamline"]["wind"])
    as_record = apply_metadata(ds, product="wind_record")["qc_flag"].attrs
    as_vad = apply_metadata(ds, product="wind")["qc_flag"].attrs
    assert as_record["flag_meanings"].split() == ["too_few_samples", "missing_value", "rain"]
    assert as_vad["flag_meanings"].split() == ["too_few_rays", "azimuth_gap_too_large", "bad_fit"]
