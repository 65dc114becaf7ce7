"""Configuration: TOML files -> frozen dataclasses, validated once at the edge.

A configuration is a TOML file with one table per section (``[instrument]``,
``[qc]``, ``[vad]``, ...). Every key is optional: missing keys take the defaults
declared below, which are the documented defaults of cwproc. Unknown keys, wrong
types and impossible values raise :class:`cwproc.errors.ConfigError` naming the
file and the dotted key. Presets live in ``cwproc/configs/*.toml`` (also reachable
as ``configs/`` at the top of the source tree) and are selected by name
(``streamline``, ``zephir300``, ``meteo2``, ...).

Stages never see these objects: :mod:`cwproc.pipeline` unpacks them into plain
typed keyword arguments.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tomllib
import types
import typing
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Literal, get_args, get_origin

from cwproc.config_products import (
    DbsConfig,
    DopplerLidarConfig,
    SonicConfig,
    ZephirConfig,
)
from cwproc.config_products import require_positive as _positive
from cwproc.dates import check_iso_dates
from cwproc.errors import ConfigError
from cwproc.physics.constants import ZEPHIR_Z_R_COEFFICIENT

# --------------------------------------------------------------------------------------
# sections
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class InstrumentConfig:
    """What made the data: the probe-volume and scan parameters the physics needs."""

    #: instrument name written to the products
    name: str = "Halo Photonics Stream Line"
    #: "pulsed" (Stream Line, WindCube), "cw" (ZephIR), "sonic" (anemometers)
    kind: Literal["pulsed", "cw", "sonic"] = "pulsed"
    #: reader to use; "auto" detects the format from the file content
    format: Literal[
        "auto",
        "hpl",
        "scan_netcdf",
        "zephir_csv",
        "windcube_sta",
        "windcube_rtd",
        "toa5",
        "tob1",
        "ghg",
        "meteo2",
        "gill",
    ] = "auto"
    #: laser wavelength (m)
    wavelength_m: float = 1.5e-6
    #: pulsed lidar: Delta_p = c sigma_p / 2 (m), Smalikho (2020) eq. 19; unset: from the
    #: instrument model (Stream Line 15.3 m, cwproc.physics.probe_lengths); set to override
    delta_p_m: float | None = None
    #: pulsed lidar: Delta_R = c T_w / 2 (m), Smalikho (2020) eq. 19; unset: each file's
    #: range gate length (Stream Line header "Range gate length (m)"; 18 m when a file has
    #: none); set to override the files
    delta_r_m: float | None = None
    #: pulsed lidar: pulse repetition frequency (Hz) for the dwell of a step-stare ray,
    #: pulses per ray / PRF; unset: from the instrument model (Stream Line 15 kHz,
    #: cwproc.physics.probe_lengths); set for another (Stream Line XR: 10000)
    prf_hz: float | None = None
    #: cw lidar: Rayleigh-range coefficient c in Z_R = c R^2 (1/m); ZephIR 0.0013
    z_r_coefficient: float = ZEPHIR_Z_R_COEFFICIENT
    #: cw lidar: beam radius a0 at the telescope (m); when set, Z_R = lambda R^2/(2 pi a0^2)
    beam_radius_m: float | None = None
    #: plausible window of the times in input files (ISO dates, UTC): a time outside is
    #: an error naming the file and line, never a product for a bogus day (issue 34.1).
    #: "" = 1995-01-01 (no file cwproc reads is older); set earlier for old archives
    earliest_date: str = ""
    #: end of that window; "" = the present plus two days (clocks a little ahead); set
    #: a later date for simulated or re-dated files. Both within 1678-01-01..2261-12-31
    #: (the span of the products' nanosecond times)
    latest_date: str = ""

    def __post_init__(self) -> None:
        check_iso_dates(self, "earliest_date", "latest_date")
        _positive(self, "wavelength_m", "z_r_coefficient")
        optional = ("delta_p_m", "delta_r_m", "prf_hz")
        _positive(self, *(n for n in optional if getattr(self, n) is not None))
        if self.beam_radius_m is not None and not self.beam_radius_m > 0:
            raise ValueError("beam_radius_m: must be > 0")


@dataclass(frozen=True)
class QCConfig:
    """Screening of radial velocities (stage ``qc``)."""

    #: minimum linear SNR (Halo intensity - 1) for a gate to be used; 0.008 = -21 dB, near
    #: where Stream Line estimates turn from Gaussian noise into uniform noise estimates
    snr_min: float = 0.008
    #: robust outlier threshold in scaled MADs (1.4826 MAD) of the residuals about a robust
    #: VAD fit per scan and gate; 4 flags ~0.2-0.4 % of good rays of 24-ray scans and
    #: catches +-20 m s-1 noise estimates; scans of fewer than 18 rays take 1.5 times it
    #: (see cwproc/stages/qc.py)
    outlier_threshold: float = 4.0

    def __post_init__(self) -> None:
        _positive(self, "outlier_threshold")
        if not self.snr_min >= 0:
            raise ValueError("snr_min: must be >= 0")


@dataclass(frozen=True)
class BackgroundConfig:
    """SNR correction of Stream Line scans with the background files (stage ``background``).

    Manninen et al. (2016); Vakkari et al. (2019). The instrument writes one
    ``Background_DDMMYY-HHMMSS.txt`` per hour beside its ``.hpl`` files; each ray is
    corrected with the latest background measured before it.
    """

    #: correct the SNR with the Background_*.txt files found (rays without one keep theirs)
    enabled: bool = True
    #: folder of the background files; "" = the folder of each .hpl file. Background
    #: files do not name their instrument: keep one instrument's files in a folder
    folder: str = ""
    #: oldest background (hours before a ray) that may correct it; the Stream Line
    #: measures one at the start of every hour
    max_age_h: float = 2.0
    #: gates nearer than this (m) are left out of the fits (outgoing pulse, near field)
    min_range_m: float = 90.0

    def __post_init__(self) -> None:
        _positive(self, "max_age_h")
        if not (math.isfinite(self.min_range_m) and self.min_range_m >= 0):
            raise ValueError("min_range_m: must be a finite number >= 0")


@dataclass(frozen=True)
class VADConfig:
    """Wind-vector fit (stage ``vad``), Smalikho (2020) eq. 1."""

    #: fewest valid rays for a fit not flagged "too few rays" (3 unknowns + 3 residual dof)
    min_rays: int = 6
    #: largest azimuth gap (deg) accepted before the fit is flagged; with a 120 deg sector
    #: missing the along-bisector RMS error grows by ~75 % (VAD accuracy paper, cwproc theory
    #: vad-errors --sector 120)
    max_gap_deg: float = 120.0
    #: homodyne cw data: direction (deg, from north, "from") used to resolve the 180 deg
    #: ambiguity when no measured reference is available
    reference_direction_deg: float | None = None
    #: residual standard deviation (m/s) above which a fit is flagged "bad fit"
    max_residual_std: float = 3.0

    def __post_init__(self) -> None:
        _positive(self, "max_residual_std")
        if self.min_rays < 3:
            raise ValueError("min_rays: must be >= 3 (three unknowns u, v, w)")
        if not 0 < self.max_gap_deg <= 360:
            raise ValueError("max_gap_deg: must be in (0, 360]")


@dataclass(frozen=True)
class TurbulenceConfig:
    """Azimuth structure function and dissipation rate (stages ``structure``, ``epsilon``)."""

    enabled: bool = True
    #: scans per block (N of Smalikho (2020) eq. 2)
    n_scans: int = 10
    #: largest azimuth lag l*dtheta (deg) of dense scans; the exact two-beam model holds
    #: at any lag, 9 deg keeps the lags of 180-360-ray scans inside the inertial range;
    #: at most 60 deg (the chord reaches the circle's radius, beyond the integral scale)
    max_lag_deg: float = 9.0
    #: fewest lags of coarse scans (24-72 rays, step-stare VADs), beyond max_lag_deg if
    #: need be (never beyond 60 deg); eq. 5 needs lags 1 and l, the fit of eq. 4 three
    min_lags: int = 3
    #: lag number l of the two-lag estimate, Smalikho (2020) eq. 5
    lag_number: int = 3
    #: spectrum model of the A-functions: "inertial" (Kolmogorov), "von_karman",
    #: "exponential" (Banakh et al. (1999) eq. 17)
    model: Literal["inertial", "von_karman", "exponential"] = "von_karman"
    #: longitudinal pulsed transfer function: "physical" (with the pi of the Gaussian term)
    #: or "printed" (Smalikho (2020) eq. 19 exactly as printed)
    pulse_transfer: Literal["physical", "printed"] = "physical"

    def __post_init__(self) -> None:
        if self.n_scans < 1:
            raise ValueError("n_scans: must be >= 1")
        if not 0 < self.max_lag_deg <= 60.0:
            raise ValueError("max_lag_deg: must be in (0, 60] (the chord reaches R' at 60 deg)")
        if self.min_lags < 2:
            raise ValueError("min_lags: must be >= 2 (Smalikho (2020) eq. 5 needs lags 1 and l)")
        if self.lag_number < 2:
            raise ValueError("lag_number: must be >= 2 (Smalikho (2020) eq. 5 needs l > 1)")


@dataclass(frozen=True)
class StareConfig:
    """Vertical-stare w statistics and eps (stage ``stare``, O'Connor et al. (2010))."""

    enabled: bool = True
    #: length of the product window of w statistics and eps (s)
    window_s: float = 300.0
    #: window T of each variance of w (s), L_1 = U T (O'Connor et al. (2010), eq. 4);
    #: the product window averages window_s / variance_window_s of them (their scatter
    #: gives the standard error)
    variance_window_s: float = 30.0
    #: fewest valid rays of a product window for eps (fewer: flag bit 2); a sparse stare
    #: needs only half the rays its window holds at its ray rate (docs/stare.md)
    min_samples: int = 20
    #: fewest rays of a variance window: T is lengthened to hold them (a ray every 25 s:
    #: T = 100 s), keeping a whole number of variance windows per window (docs/stare.md)
    min_rays_per_variance_window: int = 4
    #: w farther than this many scaled MADs from the median of its variance window is
    #: screened out (6: a Gaussian w of 20-40 rays keeps > 99.9 % of its rays)
    outlier_threshold: float = 6.0
    #: pulse repetition frequency (Hz) for the ray time pulses/PRF (Stream Line 15 kHz,
    #: XR 10 kHz)
    prf_hz: float = 15000.0
    #: a VAD wind more than this far from a window (s) is used, with flag bit 8
    max_wind_gap_s: float = 3600.0

    def __post_init__(self) -> None:
        _positive(
            self, "window_s", "variance_window_s", "prf_hz", "max_wind_gap_s", "outlier_threshold"
        )
        if self.min_samples < 3:
            raise ValueError("min_samples: must be >= 3 (variance and skewness)")
        if self.min_rays_per_variance_window < 3:
            raise ValueError("min_rays_per_variance_window: must be >= 3 (a variance)")
        if self.variance_window_s > self.window_s:
            raise ValueError("variance_window_s: must not exceed window_s")


@dataclass(frozen=True)
class OutputConfig:
    """Global attributes of the products (ACDD-1.3)."""

    institution: str = ""
    creator_name: str = ""
    creator_email: str = ""
    #: web page of the creator (person or group) and of the publishing institution
    creator_url: str = ""
    publisher_url: str = ""
    project: str = ""
    site: str = ""
    #: instrument position (decimal degrees north / east, metres above sea level); when
    #: set, the products carry ACDD geospatial attributes
    latitude: float | None = None
    longitude: float | None = None
    altitude_m: float | None = None
    #: persistent identifier of the instrument (e.g. an ePIC handle of the ACTRIS
    #: instrument PID registry); written as global attribute ``instrument_pid`` when set
    instrument_pid: str = ""
    #: serial number of the instrument, written as ``instrument_serial_number`` when set
    #: (a Stream Line's System ID is also kept as ``system_id`` when the inputs give one)
    instrument_serial_number: str = ""
    #: zlib compression level of the NetCDF variables (0 = none)
    compression_level: int = 4
    #: "cwproc": cwproc's products only; "cloudnet": also the ACTRIS Cloudnet files
    #: <unit>_doppler-lidar.nc and <unit>_doppler-lidar-wind.nc in the variable names
    #: cloudnetpy reads (``v``, ``beta``, ``uwind``, ...; docs/cloudnet.md)
    layout: Literal["cwproc", "cloudnet"] = "cwproc"
    #: write <product>.qc.json beside every product (coverage, flags, CF/ACDD, inputs refused)
    qc_report: bool = False

    def __post_init__(self) -> None:
        if not 0 <= self.compression_level <= 9:
            raise ValueError("compression_level: must be in 0..9")
        if self.latitude is not None and not -90 <= self.latitude <= 90:
            raise ValueError("latitude: must be in [-90, 90]")
        if self.longitude is not None and not -180 <= self.longitude <= 360:
            raise ValueError("longitude: must be in [-180, 360]")
        if (self.latitude is None) != (self.longitude is None):
            given = "latitude" if self.longitude is None else "longitude"
            missing = "longitude" if self.longitude is None else "latitude"
            raise ValueError(f"{given}: set {missing} too (a position needs both)")


@dataclass(frozen=True)
class SimulationConfig:
    """The virtual cw lidar and its Monte-Carlo error study (``cwproc simulate``).

    Defaults are those of Banakh et al. (1999), section 3 and its table of heights.
    """

    #: beam elevation phi (deg); Banakh et al. (1999): 30
    elevation_deg: float = 30.0
    #: duration T of one 360 deg rotation (s); Banakh et al. (1999): 7
    scan_period_s: float = 7.0
    #: measuring time t0 of one Doppler spectrum (s); Banakh et al. (1999): 0.05 (140 per scan)
    spectrum_time_s: float = 0.05
    #: velocity resolution dV of the Doppler spectra (m s-1), << the spectral width (eq. 9)
    velocity_resolution_m_s: float = 0.1
    #: spectral channels M_D (channel 0 at 0 m s-1 for the homodyne system)
    n_channels: int = 256
    #: spectra whose peak lies below this velocity are dropped (m s-1); the paper: 1
    min_peak_velocity_m_s: float = 1.0
    #: heights h of the profile (m), Banakh et al. (1999), table
    heights_m: tuple[float, ...] = (50.0, 100.0, 200.0, 300.0, 400.0, 500.0)
    #: mean wind speed U(h) (m s-1), same table
    wind_speed_m_s: tuple[float, ...] = (6.90, 7.77, 8.63, 9.14, 9.50, 9.78)
    #: standard deviation sigma_V(h) (m s-1), same table
    sigma_v_m_s: tuple[float, ...] = (1.23, 1.20, 1.15, 1.11, 1.07, 1.02)
    #: integral scale L_V(h) (m), same table (epsilon follows from eq. 19)
    outer_scale_m: tuple[float, ...] = (133.0, 200.0, 266.0, 300.0, 320.0, 333.0)
    #: direction the mean wind blows from (deg); not stated in the paper
    wind_direction_deg: float = 240.0
    #: independent realisations of the Monte-Carlo study; the paper: 1000
    realisations: int = 1000
    #: largest number of scans N averaged; the paper: 10
    max_scans: int = 10
    #: azimuth lags l = 1..max_lag of the structure-function fit; l dtheta <= 9 deg
    #: (Smalikho (2020)) allows 3 at 140 spectra per scan, and 3 gives the smallest error
    max_lag: int = 3

    def __post_init__(self) -> None:
        _positive(
            self, "elevation_deg", "scan_period_s", "spectrum_time_s", "velocity_resolution_m_s"
        )
        if not 0 < self.elevation_deg < 90:
            raise ValueError("elevation_deg: must be in (0, 90)")
        if self.spectrum_time_s >= self.scan_period_s:
            raise ValueError("spectrum_time_s: must be shorter than scan_period_s")
        n = len(self.heights_m)
        if n == 0:
            raise ValueError("heights_m: at least one height is needed")
        for name in ("wind_speed_m_s", "sigma_v_m_s", "outer_scale_m"):
            values = getattr(self, name)
            if len(values) != n:
                raise ValueError(f"{name}: needs one value per height ({n}), got {len(values)}")
            if not all(v > 0 for v in values):
                raise ValueError(f"{name}: values must be > 0")
        if not all(h > 0 for h in self.heights_m):
            raise ValueError("heights_m: values must be > 0")
        if self.n_channels < 16:
            raise ValueError("n_channels: must be >= 16")
        if self.realisations < 2:
            raise ValueError("realisations: must be >= 2")
        if self.max_scans < 1:
            raise ValueError("max_scans: must be >= 1")
        if self.max_lag < 2:
            raise ValueError("max_lag: must be >= 2 (two parameters are fitted)")
        if self.min_peak_velocity_m_s < 0:
            raise ValueError("min_peak_velocity_m_s: must be >= 0")


@dataclass(frozen=True)
class Config:
    """The whole configuration. ``source`` names the file or preset it came from."""

    instrument: InstrumentConfig = field(default_factory=InstrumentConfig)
    qc: QCConfig = field(default_factory=QCConfig)
    background: BackgroundConfig = field(default_factory=BackgroundConfig)
    vad: VADConfig = field(default_factory=VADConfig)
    turbulence: TurbulenceConfig = field(default_factory=TurbulenceConfig)
    stare: StareConfig = field(default_factory=StareConfig)
    doppler_lidar: DopplerLidarConfig = field(default_factory=DopplerLidarConfig)
    sonic: SonicConfig = field(default_factory=SonicConfig)
    zephir: ZephirConfig = field(default_factory=ZephirConfig)
    dbs: DbsConfig = field(default_factory=DbsConfig)
    output: OutputConfig = field(default_factory=OutputConfig)
    simulation: SimulationConfig = field(default_factory=SimulationConfig)
    #: reader options per format (free-form tables, validated by the reader), e.g.
    #: ``[reader.meteo2] delimiter = ","``
    reader: dict[str, dict[str, Any]] = field(default_factory=dict)
    source: str = "<defaults>"

    def to_toml(self) -> str:
        """The configuration as TOML text (what a product records as provenance)."""
        return dump_toml(self)

    @classmethod
    def preset(cls, name: str) -> Config:
        """The preset ``name`` (see :func:`preset_names`), as :func:`load_config` gives it."""
        return load_config(name)

    def replace(self, **sections: Any) -> Config:
        """A copy with some sections changed, validated as a TOML file would be.

        Parameters
        ----------
        **sections
            Section name -> a section object (``vad=VADConfig(min_rays=8)``) or a dict of
            the keys to change in that section (``vad={"min_rays": 8}``).

        Raises
        ------
        ConfigError
            Unknown section or key, wrong type or impossible value (dotted key named).
        """
        data = dataclasses.asdict(self)
        for name, value in sections.items():
            name = SECTION_ALIASES.get(name, name)  # [wind_record] is [zephir]
            if dataclasses.is_dataclass(value):
                value = dataclasses.asdict(value)
            if name in data and isinstance(data[name], dict) and isinstance(value, dict):
                data[name] = {**data[name], **value}
            else:
                data[name] = value
        modified = " (modified)"
        source = self.source if self.source.endswith(modified) else self.source + modified
        return config_from_dict(data, source=source)

    def checked(self) -> Config:
        """This configuration validated as a TOML file would be (types, choices, ranges).

        Sections built in Python check their values when made; the types and the
        choices of ``Literal`` keys (e.g. ``instrument.kind``) are checked here, by the
        same code that reads TOML files.

        Raises
        ------
        ConfigError
            The first wrong key, named with its dotted path.
        """
        return config_from_dict(dataclasses.asdict(self), source=self.source)


# --------------------------------------------------------------------------------------
# loading
# --------------------------------------------------------------------------------------

PRESET_PACKAGE = "cwproc.configs"


#: old preset names, still accepted with a warning: name -> the preset's name now
PRESET_ALIASES = {"seed000": "banakh1999"}


class PresetAliasWarning(UserWarning):
    """A preset was chosen by an old name (see :data:`PRESET_ALIASES`)."""


#: the preset each input format is processed with when no configuration is given
#: (:func:`cwproc.retrieve` with ``config=None``); a scan NetCDF file depends on the
#: instrument it states (:func:`default_preset`)
DEFAULT_PRESET_OF_FORMAT: dict[str, str] = {
    "hpl": "streamline",
    "halo_background": "streamline",
    "zephir_csv": "zephir300",
    "windcube_sta": "windcube",
    "windcube_rtd": "windcube",
    "meteo2": "meteo2",
    "toa5": "csat3",
    "tob1": "csat3",
    "ghg": "csat3",
    "gill": "csat3",
}


def default_preset(fmt: str, attrs: Mapping[str, object] | None = None) -> str:
    """The preset of an input of format ``fmt`` when no configuration is given.

    Parameters
    ----------
    fmt : str
        The input's format (``"hpl"``, ``"meteo2"``, ..., as ``[instrument] format``).
    attrs : mapping, optional
        The input's global attributes; a scan NetCDF file is a Stream Line's
        (``instrument_kind`` ``streamline`` or ``pulsed``), a ZephIR's (``instrument``
        names it) or another cw lidar's (``banakh1999``, the simulated cw lidar).

    Returns
    -------
    str
        A name of :func:`preset_names`.
    """
    if fmt in DEFAULT_PRESET_OF_FORMAT:
        return DEFAULT_PRESET_OF_FORMAT[fmt]
    attrs = attrs or {}
    kind = str(attrs.get("instrument_kind", "")).strip().lower()
    if kind == "cw":
        return "zephir300" if "zephir" in str(attrs.get("instrument", "")).lower() else "banakh1999"
    return "streamline"


def preset_names() -> list[str]:
    """Names of the configuration presets shipped with cwproc (aliases not included)."""
    files = resources.files(PRESET_PACKAGE)
    return sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".toml"))


def load_config(path_or_preset: str | os.PathLike | None = None) -> Config:
    """Load a configuration from a TOML file or a preset name.

    Parameters
    ----------
    path_or_preset : str or path, optional
        A path to a TOML file, or the name of a preset (see :func:`preset_names`).
        ``None`` gives the defaults (Stream Line).

    Returns
    -------
    Config

    Raises
    ------
    ConfigError
        File missing, TOML syntax error, unknown key, wrong type or impossible value.
    """
    if path_or_preset is None:
        return Config()
    text: str
    source: str
    candidate = Path(path_or_preset)
    if candidate.suffix == ".toml" or candidate.exists() or os.sep in str(path_or_preset):
        source = str(candidate)
        try:  # utf-8-sig: a byte-order mark (as some Windows editors write) is not text
            text = candidate.read_text(encoding="utf-8-sig")
        except OSError as exc:
            raise ConfigError(source, "-", f"cannot read: {exc.strerror or exc}") from None
        except UnicodeDecodeError:
            raise ConfigError(source, "-", "not UTF-8 text") from None
    else:
        name = str(path_or_preset)
        if name in PRESET_ALIASES:
            warnings.warn(
                f"preset '{name}' is now called '{PRESET_ALIASES[name]}' "
                "(after its paper); the old name will be removed",
                PresetAliasWarning,
                stacklevel=2,
            )
            name = PRESET_ALIASES[name]
        if name not in preset_names():
            raise ConfigError(
                f"<{name}>", "-", f"no such preset; choose one of {', '.join(preset_names())}"
            )
        source = f"<preset {name}>"
        text = resources.files(PRESET_PACKAGE).joinpath(f"{name}.toml").read_text("utf-8")
    return config_from_toml(text, source=source)


def config_from_toml(text: str, *, source: str = "<string>") -> Config:
    """Parse and validate TOML text into a :class:`Config`."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(source, "-", f"TOML syntax error: {exc}") from None
    return config_from_dict(data, source=source)


def config_from_dict(data: dict[str, Any], *, source: str = "<dict>") -> Config:
    """Validate a nested dict (as read from TOML) into a :class:`Config`."""
    data = dict(data)
    data.pop("source", None)
    _resolve_section_aliases(data, source)
    _check_moved_keys(data, source)
    _check_reader_tables(data.get("reader"), source)
    cfg = _build(Config, data, source, "")
    return dataclasses.replace(cfg, source=source)


#: another name of a section: alias -> the section's name in :class:`Config`
SECTION_ALIASES = {"wind_record": "zephir"}


def _resolve_section_aliases(data: dict[str, Any], source: str) -> None:
    """Read ``[wind_record]`` as ``[zephir]``: the section holds the QC of every wind
    record (ZephIR and WindCube), and either name is accepted (not both)."""
    for alias, name in SECTION_ALIASES.items():
        if alias not in data:
            continue
        if name in data:
            raise ConfigError(source, alias, f"the same section as [{name}]: give one of them")
        data[name] = data.pop(alias)


_SONIC_ORIENTATION_MOVED = (
    "no longer read here: the sonic's orientation (azimuth of its +x axis, degrees "
    "clockwise from north) is now [sonic] orientation_deg"
)

#: keys of older configurations that moved or went: (table, key) -> what to do instead
MOVED_KEYS: dict[tuple[str, str], str] = {
    ("instrument", "sonic_orientation_deg"): _SONIC_ORIENTATION_MOVED,
    **{
        ("reader." + fmt, "orientation_deg"): _SONIC_ORIENTATION_MOVED
        for fmt in ("toa5", "tob1", "ghg", "meteo2", "gill")
    },
    ("instrument", "homodyne"): (
        "no longer read: homodyne detection (only |V_r| measured) comes from the data, "
        "the 'homodyne' attribute of the scans (1 for ZephIR files, 0 for Halo and "
        "WindCube files, required in a scan NetCDF); remove the key"
    ),
}


def _check_moved_keys(data: dict[str, Any], source: str) -> None:
    """A key that moved or went is an error naming it and what to do (never ignored)."""
    for (table, key), message in MOVED_KEYS.items():
        section: Any = data
        for part in table.split("."):
            section = section.get(part, {}) if isinstance(section, dict) else {}
        if isinstance(section, dict) and key in section:
            raise ConfigError(source, f"{table}.{key}", message)


def _check_reader_tables(reader: Any, source: str) -> None:
    """``[reader.<format>]`` tables must name formats cwproc reads, exactly.

    A table under another name (``[reader.Meteo2]``, a typo) would be ignored silently
    and the reader run with its defaults.
    """
    if not isinstance(reader, dict):
        return
    from cwproc.io import Format

    known = sorted(f.value for f in Format)
    for name in reader:
        if name not in known:
            close = [k for k in known if k.lower() == str(name).lower()]
            hint = f" (did you mean [reader.{close[0]}]?)" if close else ""
            raise ConfigError(
                source,
                f"reader.{name}",
                f"not a format cwproc reads{hint}; known: {', '.join(known)}",
            )


def _build(cls: type, data: Any, source: str, prefix: str) -> Any:
    if not isinstance(data, dict):
        raise ConfigError(source, prefix.rstrip(".") or "-", "must be a table")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(data) - set(fields))
    if unknown:
        key = prefix + unknown[0]
        raise ConfigError(source, key, f"unknown key; known keys here: {', '.join(sorted(fields))}")
    kwargs = {}
    for name, value in data.items():
        kwargs[name] = _convert(hints[name], value, source, prefix + name)
    try:
        return cls(**kwargs)
    except ValueError as exc:
        msg = str(exc)
        key, _, problem = msg.partition(": ")
        if key in fields and problem:
            raise ConfigError(source, prefix + key, problem) from None
        raise ConfigError(source, prefix.rstrip(".") or "-", msg) from None


def _convert(tp: Any, value: Any, source: str, key: str) -> Any:
    origin = get_origin(tp)
    if dataclasses.is_dataclass(tp):
        return _build(tp, value, source, key + ".")
    if origin in (typing.Union, types.UnionType):
        args = get_args(tp)
        if value is None and type(None) in args:
            return None
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _convert(arg, value, source, key)
            except ConfigError as exc:
                errors.append(exc.problem)
        raise ConfigError(source, key, "; ".join(errors))
    if origin is Literal:
        allowed = get_args(tp)
        if value not in allowed:
            raise ConfigError(
                source, key, f"must be one of {', '.join(map(repr, allowed))}, got {value!r}"
            )
        return value
    if origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(source, key, f"must be a table, got {type(value).__name__}")
        return {str(k): v for k, v in value.items()}
    if origin in (tuple, list):
        if not isinstance(value, list | tuple):
            raise ConfigError(source, key, f"must be an array, got {type(value).__name__}")
        (item_tp, *_rest) = get_args(tp) or (Any,)
        return tuple(_convert(item_tp, v, source, f"{key}[{i}]") for i, v in enumerate(value))
    if tp is Any:
        return value
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(source, key, f"must be true or false, got {value!r}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(source, key, f"must be an integer, got {value!r}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(source, key, f"must be a number, got {value!r}")
        if not math.isfinite(value):
            raise ConfigError(source, key, f"must be finite, got {value!r}")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(source, key, f"must be a string, got {value!r}")
        return value
    raise ConfigError(source, key, f"unsupported type {tp!r}")  # a bug in cwproc, not in input


# --------------------------------------------------------------------------------------
# dumping (provenance)
# --------------------------------------------------------------------------------------


def _toml_ready(value: Any) -> Any:
    """Tuples as lists and ``None`` entries dropped, for the TOML writer."""
    if isinstance(value, dict):
        return {str(k): _toml_ready(v) for k, v in value.items() if v is not None}
    if isinstance(value, list | tuple):
        return [_toml_ready(v) for v in value]
    return value


def dump_toml(cfg: Config) -> str:
    """Write a :class:`Config` as TOML (``None`` values are omitted).

    The text is made by ``tomli_w`` (a maintained TOML writer), so any value a valid
    configuration holds -- strings with newlines or quotes, dates, quoted or nested keys
    of the ``[reader.*]`` tables -- reads back (``config_from_toml(dump_toml(c))``) to
    the same configuration; it is stored as provenance in every product.
    """
    import tomli_w

    data: dict[str, Any] = {}
    for f in dataclasses.fields(cfg):
        if f.name == "source":
            continue
        value = getattr(cfg, f.name)
        if dataclasses.is_dataclass(value):
            data[f.name] = _toml_ready(dataclasses.asdict(value))
        elif isinstance(value, dict):
            data[f.name] = _toml_ready(value)
    source = str(cfg.source).replace("\n", " ").replace("\r", " ")
    return f"# cwproc configuration (from {source})\n" + tomli_w.dumps(data)
