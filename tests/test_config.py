"""Configuration: presets load, bad keys/types/values give one clear ConfigError."""

from __future__ import annotations

import pytest

from cwproc.config import Config, config_from_toml, load_config, preset_names
from cwproc.errors import ConfigError


@pytest.mark.parametrize("name", preset_names())
def test_every_preset_loads_and_round_trips(name):
    cfg = load_config(name)
    again = config_from_toml(cfg.to_toml(), source="roundtrip")
    assert again.instrument == cfg.instrument
    assert again.turbulence == cfg.turbulence
    assert again.reader == cfg.reader


def test_defaults_are_stream_line():
    """The probe is not fixed by the defaults: Delta_R from the file, Delta_p from the
    model (Stream Line 15.3 m); 18 m only for data that give no gate length."""
    from cwproc.pipeline import probe_from_config

    cfg = Config()
    assert cfg.instrument.delta_p_m is None and cfg.instrument.delta_r_m is None
    preset = load_config("streamline").instrument
    assert (preset.delta_p_m, preset.delta_r_m) == (None, None)
    probe = probe_from_config(cfg.instrument, data_attrs={"instrument_kind": "streamline"})
    assert (probe.delta_p_m, probe.delta_r_m) == (15.3, 18.0)


@pytest.mark.parametrize(
    ("text", "key", "words"),
    [
        ("[qc]\nsnr_minn = 1", "qc.snr_minn", "unknown key"),
        ("[qc]\nsnr_min = 'high'", "qc.snr_min", "must be a number"),
        ("[instrument]\ndelta_r_m = -18.0", "instrument.delta_r_m", "> 0"),
        ("[turbulence]\nmax_lag_deg = 75", "turbulence.max_lag_deg", "60"),
        ("[turbulence]\nmodel = 'kolmogorov'", "turbulence.model", "one of"),
        ("[vad]\nmin_rays = 2.5", "vad.min_rays", "integer"),
        ("[nosuch]\na = 1", "nosuch", "unknown key"),
        ("qc = 3", "qc", "table"),
    ],
)
def test_bad_config_names_key_and_problem(text, key, words):
    with pytest.raises(ConfigError) as err:
        config_from_toml(text, source="my.toml")
    assert err.value.key == key
    assert words in err.value.problem
    assert str(err.value).startswith("my.toml: ")


def test_toml_syntax_error_names_file():
    with pytest.raises(ConfigError, match=r"bad\.toml.*TOML syntax"):
        config_from_toml("[qc\n", source="bad.toml")


def test_missing_file_and_unknown_preset(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "nope.toml")
    with pytest.raises(ConfigError, match="no such preset"):
        load_config("nosuchpreset")


def test_provenance_toml_round_trips_awkward_values():
    """Strings with newlines and quotes, dates, quoted and nested keys (issue 17.5)."""
    text = (
        '[output]\nproject = "line one\\nline \\"two\\" \\\\ end"\n'
        "[reader.toa5]\n"
        '"odd key" = 1\n'
        "stamp = 2024-06-01T00:00:00Z\n"
        "columns = { u = \"Ux\", v = 'Uy' }\n"
        "nested = { deeper = { x = [1, 2] } }\n"
    )
    cfg = config_from_toml(text, source="line\nbreak.toml")
    again = config_from_toml(cfg.to_toml(), source="again")
    assert again.output == cfg.output
    assert again.reader == cfg.reader
    assert again.reader["toa5"]["nested"] == {"deeper": {"x": [1, 2]}}


def test_old_preset_name_seed000_warns_and_loads_banakh1999():
    """The preset is named after its paper; the old file-number name still works, with a
    warning (issue 14, point 7)."""
    from cwproc.config import PresetAliasWarning

    assert "seed000" not in preset_names() and "banakh1999" in preset_names()
    with pytest.warns(PresetAliasWarning, match="now called 'banakh1999'"):
        old = load_config("seed000")
    assert old == load_config("banakh1999")


def test_cli_names_the_new_preset_when_the_old_one_is_used(tmp_path):
    from click.testing import CliRunner

    from cwproc.cli import main

    res = CliRunner().invoke(main, ["retrieve", "-c", "seed000", str(tmp_path), "-o", "x"])
    first = res.output.strip().splitlines()[0]
    assert first.startswith("warning: preset 'seed000' is now called 'banakh1999'"), res.output


@pytest.mark.parametrize("value", ["true", "false"])
def test_the_retired_homodyne_key_is_refused_by_name(value):
    """Homodyne detection is a property of the data (the scans' ``homodyne`` attribute,
    read by :func:`cwproc.io.scan_join.is_homodyne`); an ``[instrument] homodyne`` that
    nothing reads would pretend to control it."""
    with pytest.raises(ConfigError) as err:
        config_from_toml(f"[instrument]\nkind = 'cw'\nhomodyne = {value}\n", source="old.toml")
    assert err.value.key == "instrument.homodyne"
    assert "comes from the data" in err.value.problem
    assert str(err.value).startswith("old.toml: ")


def test_wind_record_is_another_name_of_the_zephir_section():
    """``[wind_record]`` (the QC of ZephIR and WindCube records) reads as ``[zephir]``;
    the provenance keeps writing ``[zephir]``, and giving both is an error naming it."""
    cfg = config_from_toml("[wind_record]\nmin_packets = 30\n", source="x.toml")
    assert cfg.zephir.min_packets == 30
    assert cfg == config_from_toml("[zephir]\nmin_packets = 30\n", source="x.toml")
    assert Config().replace(wind_record={"max_rain_percent": 10.0}).zephir.max_rain_percent == 10
    with pytest.raises(ConfigError, match="wind_record") as info:
        config_from_toml("[wind_record]\nmin_packets = 30\n[zephir]\nmin_packets = 3\n")
    assert "give one of them" in str(info.value)
