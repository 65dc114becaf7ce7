"""The quicklook of docs/doppler-lidar.md: two hours of the network cycle (a VAD every
15 min, stares between them) from the virtual instrument, the stares given an aerosol
layer (SNR 1, beta about 1e-6 m-1 sr-1) that grows from 300 to 550 m over noise, and
cross-polarised pairs in the real layout (depolarisation 0.05 in the layer, 0.3 above
400 m: a dust layer on top); then
``cwproc retrieve --l1 --cross`` and ``cwproc plot --kind doppler-lidar``.

    python docs/examples/doppler_lidar_day.py docs/images/doppler_lidar.png
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.io.halo import read_hpl, write_hpl
from cwproc.sim.depol import aerosol_layer, cross_polarised


def run(*args: object) -> None:
    res = CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)
    if res.exit_code != 0:
        raise SystemExit(res.output)


def make_day(root: Path) -> tuple[Path, Path]:
    run("simulate", "lidar", "-o", root / "sim", "--scan", "mixed", "--hours", "2", "-q")
    data, cross = root / "data", root / "cross"
    data.mkdir()
    cross.mkdir()
    files = sorted((root / "sim" / "data").glob("*.hpl"))
    stares = [f for f in files if f.name.startswith("Stare")]
    for k, f in enumerate(files):
        ds = read_hpl(f)
        if f not in stares:
            write_hpl(ds, data / f.name)
            continue
        top = 300.0 + 250.0 * k / max(len(files) - 1, 1)
        co = aerosol_layer(ds, top_m=top, snr=1.0, noise_std=0.002, scale_m=60.0, seed=k)
        delta = np.where(ds["range"].values > 400.0, 0.3, 0.05)[None, :]
        write_hpl(co, data / f.name)
        write_hpl(cross_polarised(co, delta, 0.002, seed=100 + k), cross / f.name)
    return data, cross


def main_(out: Path) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        data, cross = make_day(root)
        run("retrieve", data, "-o", root / "out", "--cross", cross, "-q")
        (product,) = (root / "out").glob("*_doppler_lidar.nc")
        run("plot", product, "--kind", "doppler-lidar", "-o", out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main_(Path(sys.argv[1] if len(sys.argv) > 1 else "doppler_lidar.png"))
