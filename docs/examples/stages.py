# %% [markdown]
# # The stages one by one, in a notebook
#
# What `cwproc retrieve` does, stage by stage, on the shipped samples: read the files,
# screen the radial velocities, fit the wind, build the azimuth structure function and
# estimate the dissipation rate; then the wind records of a ZephIR and a WindCube, the
# DBS of WindCube lines of sight, and the structure-function types of a sonic
# anemometer. Every stage output carries the units and long names of cwproc's one
# metadata table (`cwproc.metadata`), as the written files do.
#
# Every cell runs as it is: in a notebook opened at the top of the source tree
# (jupytext reads the `# %%` cells), or as `python docs/examples/stages.py` from any
# folder (it writes into the current one). `tests/test_examples.py` runs it.

# %%
from pathlib import Path

import xarray as xr

import cwproc
from cwproc import stages

try:
    SOURCE_TREE = Path(__file__).resolve().parents[2]
except NameError:  # in a notebook: opened at the top of the source tree
    SOURCE_TREE = Path.cwd()
SAMPLES = SOURCE_TREE / "sample_data"
OUT = Path("stages_products")


def describe(ds: xr.Dataset, names: list[str]) -> None:
    """Print the units and long name of some variables of a stage output."""
    for name in names:
        attrs = ds[name].attrs
        print(f"  {name:24s} [{attrs.get('units', '-')}] {attrs['long_name']}")


# %% [markdown]
# ## 1. Several files: one record, scans numbered over it
#
# The Stream Line sample is two files of six 180-ray VAD scans. `cwproc.read` takes a
# path, a glob pattern or a list of files and joins them in time order, numbering the
# scans over the whole record (`cwproc.concat_scans` does the same for datasets
# already read).

# %%
files = sorted((SAMPLES / "streamline").glob("*.hpl"))
scans = cwproc.read(files)
print(scans.sizes, "| scans:", int(scans["scan"].max()) + 1)

# %% [markdown]
# ## 2. The `xr.concat` trap, refused
#
# Every file numbers its scans from 0. `xr.concat` keeps both numberings, so a VAD
# fit would merge scan 0 of the first file with scan 0 of the second (6 wind profiles
# instead of 12) and the structure function and epsilon built on it would be wrong.
# The scan stages refuse such a dataset and say how to join the files.

# %%
glued = xr.concat([cwproc.read(f) for f in files], dim="ray")
try:
    stages.fit_vad(glued)
    refused = ""
except cwproc.CwprocError as error:
    refused = str(error)
print(refused)

# %% [markdown]
# ## 3. Screening, wind, structure function, dissipation rate
#
# The stage keywords default to the Stream Line preset
# (`cwproc/configs/streamline.toml`); the probe of `estimate_epsilon` is the Stream
# Line's (Smalikho (2020), eq. 19). The A-tables of the samples ship with cwproc, so
# this runs in seconds.

# %%
screened = stages.screen_radial_velocity(scans)
wind = stages.fit_vad(screened)
sf = stages.azimuth_structure_function(screened, wind)
turbulence = stages.estimate_epsilon(sf)
print("wind profiles:", wind.sizes["time"], "| blocks:", turbulence.sizes["time"])
describe(screened, ["radial_velocity", "qc_flag_radial"])
describe(wind, ["wind_speed", "wind_direction", "u_error"])
describe(sf, ["structure_function", "n_pairs"])
describe(turbulence, ["epsilon", "turbulence_flag"])

# %% [markdown]
# ## 4. Wind records of a ZephIR and a WindCube, and DBS of lines of sight
#
# An instrument's own averages become the wind product by `wind_record_product`
# (turbulence intensity corrected for volume averaging); the lines of sight of a
# WindCube `.rtd` file are first turned into interval statistics by `dbs_statistics`.

# %%
from cwproc.stages.dbs import dbs_statistics  # noqa: E402

zephir = stages.wind_record_product(
    cwproc.read(SAMPLES / "zephir" / "Wind10_999@Y2024_M06_D01.ZPH.csv")
)
windcube = stages.wind_record_product(
    cwproc.read(SAMPLES / "windcube" / "WLS7-999_2024_06_01__00_00_00.sta")
)
lines_of_sight = cwproc.read(SAMPLES / "windcube_rtd" / "WLS7-999_2024_06_01__00_10_00.rtd")
dbs = stages.wind_record_product(dbs_statistics(lines_of_sight))
for name, product in (("ZephIR", zephir), ("WindCube", windcube), ("WindCube DBS", dbs)):
    print(name, dict(product.sizes))
describe(zephir, ["wind_speed", "turbulence_intensity"])

# %% [markdown]
# ## 5. Structure-function types of a sonic anemometer
#
# Gladkikh et al. (2014): the structure function of each 10-min window of the
# Meteo-2 sample, and the type it takes. The keywords default to the `meteo2` preset.

# %%
sonic = cwproc.read(SAMPLES / "sonic" / "meteo2_2024_06_01_1200.txt")
types = stages.structure_function_types(sonic)
print(dict(types.sizes))
describe(types, ["sf_type", "sf_mu"])

# %% [markdown]
# ## 6. Whole chain and files, from datasets
#
# `cwproc.retrieve` also takes datasets already read; without a configuration each
# unit takes its instrument's preset, and a note says which. `cwproc.write` writes a
# retrieval, or a product made by the stages (`product=` names it).

# %%
result = cwproc.retrieve(scans)
for note in result.all_notes():
    print("note:", note)
written = cwproc.write(result, OUT) + cwproc.write(wind, OUT, product="wind")
for path in written:
    print(path)
