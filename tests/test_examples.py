"""The notebook examples of ``docs/examples/`` run as they are (issue 33).

``docs/examples/stages.py`` (jupytext percent format) runs each stage on the shipped
samples; this test executes it in a fresh folder and checks what it shows: the two
sample files read as one record give 12 wind profiles, the ``xr.concat`` trap is
refused with the message that names ``cwproc.read``, every stage output printed has
units, and the files it writes exist. (``first_day.py`` is run by ``tests/test_api.py``.)
"""

from __future__ import annotations

import runpy
from pathlib import Path

import xarray as xr

EXAMPLES = Path(__file__).resolve().parents[1] / "docs" / "examples"


def test_stages_example_runs_and_shows_what_it_says(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    ns = runpy.run_path(str(EXAMPLES / "stages.py"))
    out = capsys.readouterr().out
    assert int(ns["scans"]["scan"].max()) + 1 == 12
    assert ns["wind"].sizes["time"] == 12
    assert ns["refused"].startswith("fit_vad: scan 0 holds rays of 12:00:00-12:00:35 and ")
    assert "join the files with cwproc.read([...])" in ns["refused"]
    assert ns["refused"] in out
    for name in ("screened", "wind", "sf", "turbulence", "zephir", "windcube", "dbs", "types"):
        ds = ns[name]
        assert isinstance(ds, xr.Dataset), name
        for var in ds.data_vars.values():
            assert "long_name" in var.attrs, (name, var.name)
    assert ns["turbulence"]["epsilon"].attrs["units"] == "m2 s-3"
    assert "[m2 s-3] turbulent kinetic energy dissipation rate" in out
    assert ns["result"]["wind"].sizes["time"] == 12
    assert any("preset streamline" in note for note in ns["result"].all_notes())
    written = sorted(p.name for p in (tmp_path / "stages_products").glob("*.nc"))
    assert written == sorted(p.name for p in ns["written"])
    assert len(written) == 3


def test_the_ipynb_holds_the_cells_of_the_script():
    """``docs/examples/stages.ipynb`` (``tools/percent_to_ipynb.py``) is the script's cells,
    in order, with their printed outputs: rerun the tool when the script changes."""
    import json
    import sys

    sys.path.insert(0, str(EXAMPLES.parents[1] / "tools"))
    from percent_to_ipynb import percent_cells

    notebook = json.loads((EXAMPLES / "stages.ipynb").read_text())
    assert notebook["nbformat"] == 4
    cells = [(c["cell_type"], "".join(c["source"])) for c in notebook["cells"]]
    assert cells == percent_cells((EXAMPLES / "stages.py").read_text())
    printed = "".join(
        "".join(o.get("text", [])) for c in notebook["cells"] for o in c.get("outputs", [])
    )
    assert "join the files with cwproc.read([...])" in printed
