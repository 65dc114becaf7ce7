# %% [markdown]
# # A first day with cwproc, in Python
#
# The shipped Stream Line sample (`sample_data/streamline/`: two files of six 180-ray
# VAD scans each, from the virtual lidar) turned into a wind profile and the
# turbulence dissipation rate, step by step. Every cell runs as it is: in a notebook
# opened at the top of the source tree (jupytext reads the `# %%` cells), or as
# `python docs/examples/first_day.py` from any folder (it writes into the current one).
# A test runs it and checks that its products equal those of
# `cwproc retrieve sample_data/streamline -c streamline -o OUT`.

# %%
import dataclasses
from pathlib import Path

import matplotlib
import numpy as np

import cwproc

try:
    SOURCE_TREE = Path(__file__).resolve().parents[2]
except NameError:  # in a notebook: opened at the top of the source tree
    SOURCE_TREE = Path.cwd()
SAMPLES = SOURCE_TREE / "sample_data" / "streamline"
OUT = Path("first_day_products")

# %% [markdown]
# ## 1. One file: the canonical scan dataset
#
# `cwproc.read` recognises the format from the content and returns the dataset every
# stage works on: `radial_velocity` and `snr` per ray and range gate, with the ray's
# time, azimuth and elevation, and the header in the attributes.

# %%
scans = cwproc.read(SAMPLES / "VAD_999_20240601_120000.hpl")
print(scans.sizes)
print({name: scans[name].attrs.get("units", "?") for name in scans.variables})
print(scans.attrs["instrument"], "| scan type:", scans.attrs["scan_type"])

# %% [markdown]
# ## 2. Wind and turbulence, as `cwproc retrieve` makes them
#
# `cwproc.retrieve` groups the files into units (the scans of one instrument and day),
# runs the stages and returns the products without writing them. The preset
# `streamline` holds the Stream Line probe (Delta_p = 15.3 m, Delta_R = 18 m,
# Smalikho (2020), eq. 19) and the thresholds of every stage.

# %%
result = cwproc.retrieve(SAMPLES, "streamline")
for note in result.all_notes():
    print("note:", note)
wind = result["wind"]
turbulence = result["turbulence"]
print(wind["wind_speed"].attrs["units"], turbulence["epsilon"].attrs["units"])

# %%
good = wind["qc_flag"] == 0
profile = wind["wind_speed"].where(good).mean("time")
eps = turbulence["epsilon"].where(turbulence["turbulence_flag"] == 0)
print("mean wind speed, lowest 5 heights (m s-1):", np.round(profile.values[:5], 2))
print("median eps (m2 s-3):", float(eps.median()))

# %% [markdown]
# ## 3. A configuration built in Python
#
# The same Stream Line settings spelled out, then a stricter VAD fit. Every value
# is checked as it would be in a TOML file (a wrong key or value raises
# `cwproc.ConfigError` naming it).

# %%
config = cwproc.Config(
    instrument=cwproc.InstrumentConfig(
        name="Halo Photonics Stream Line", kind="pulsed", format="hpl", delta_p_m=15.3
    ),
    turbulence=cwproc.TurbulenceConfig(n_scans=10, lag_number=3, model="von_karman"),
)
preset = cwproc.Config.preset("streamline")
same = config == dataclasses.replace(preset, source=config.source)  # all but the source
print("equal to the streamline preset:", same)
# a stricter VAD fit: residuals above 1 m s-1 (3 by default) flag the fit
stricter = config.replace(vad={"max_residual_std": 1.0})
strict_wind = cwproc.retrieve(SAMPLES, stricter)["wind"]
print("good values:", int(good.sum()), "->", int((strict_wind["qc_flag"] == 0).sum()))

# %% [markdown]
# ## 4. The stages one by one
#
# The stages are plain functions on datasets (`cwproc.stages`); `retrieve` chains them
# with the values of the configuration.

# %%
screened = cwproc.stages.screen_radial_velocity(
    scans, snr_min=config.qc.snr_min, outlier_threshold=config.qc.outlier_threshold
)
one_file_wind = cwproc.stages.fit_vad(
    screened, min_rays=config.vad.min_rays, max_gap_deg=config.vad.max_gap_deg
)
print("scans of the first file:", one_file_wind.sizes["time"])

# %% [markdown]
# ## 5. One figure and the NetCDF files

# %%
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402 (after choosing the file-only backend)

fig, ax = plt.subplots(figsize=(4, 5))
ax.plot(profile, wind["height"], marker="o")
ax.set_xlabel("wind speed (m s-1)")
ax.set_ylabel("height (m)")
ax.set_title("Stream Line sample, mean of good VAD fits")
OUT.mkdir(exist_ok=True)
fig.savefig(OUT / "wind_profile.png", dpi=80)
plt.close(fig)

written = cwproc.write(result, OUT)
print("wrote", ", ".join(p.name for p in written))
