"""UT environments of 3GPP TR 38.811 clause 6.6: LoS probability, shadowing, clutter, scintillation.

Tables shipped as data (``leolink/data/*.csv``, each with its source, table number and a
units row), read once through :mod:`importlib.resources` and cached:

- ``tr38811_los_probability.csv``: Table 6.6.1-1, LoS probability vs elevation;
- ``tr38811_shadowing_clutter.csv``: Tables 6.6.2-1 (dense urban), 6.6.2-2 (urban) and
  6.6.2-3 (suburban and rural): sigma_SF in LoS and NLoS and the clutter loss CL (NLoS),
  S band and Ka band;
- ``tr38811_tropospheric_scintillation.csv``: Table 6.6.6.2.1-1 (20 GHz, 99 % value).

Environments (one per UT population): ``open`` (always LoS, no shadowing, no clutter: the
paper's line-of-sight Rician link and the default), ``rural`` and ``suburban`` (both the
report's "suburban and rural" columns), ``urban``, ``dense_urban``.

leolink decisions (listed for docs/errata.md):

1. Elevation between the tabulated 10-degree angles: **linear interpolation** of every
   table, so that the channel changes smoothly as a satellite rises. TR 38.811 tabulates
   10..90 degrees only and implementations (ns-3, Simu5G) round to the nearest row; at the
   tabulated angles both agree. Below 10 degrees the 10-degree row is used (clamped), as
   the report gives nothing lower; above 90 degrees the 90-degree row.
2. Band of the tables: the report has an S-band table (2 GHz) and a Ka-band table
   (20 GHz downlink) and nothing in between. :func:`band_for_frequency` picks the band
   nearest on a logarithmic frequency scale, i.e. Ka from the geometric mean
   sqrt(2 * 20) GHz = 6.32 GHz up. So **11.45 GHz (the paper's Ku downlink) uses Ka**:
   log10(11.45/2) = 0.76 decades from S but log10(20/11.45) = 0.24 from Ka; clutter and
   shadowing are obstruction/diffraction losses that scale with the wavelength against
   the obstacles (2.6 cm at 11.45 GHz vs 1.5 cm at 20 GHz and 15 cm at 2 GHz), and the
   Earth-space clutter model of ITU-R P.2108 has K1 = 93 f^0.175, which puts 11.45 GHz 72 % of
   the way from 2 to 20 GHz. ns-3 and Simu5G cut at 13 GHz and would use S; an explicit
   ``band="s"`` or ``band="ka"`` overrides the rule.
3. Scintillation (clause 6.6.6) is a fade margin, not a random process: below 6 GHz the
   ionospheric loss of clause 6.6.6.1.4, above 6 GHz the tropospheric loss of
   Table 6.6.6.2.1-1 scaled from 20 GHz by (f / 20 GHz)^(7/12), the frequency law of
   ITU-R P.618-13 clause 2.4.1 (the antenna-averaging factor is left out, which errs on
   the side of a larger margin). At 11.45 GHz the factor is 0.722. Do not switch it on
   together with the ``itu_p618`` atmosphere model, which already contains scintillation.

References
----------
.. [1] 3GPP TR 38.811 V15.4.0 (2020-09), "Study on New Radio (NR) to support
   non-terrestrial networks", clauses 6.6.1, 6.6.2, 6.6.6.
.. [2] ITU-R P.618-13, "Propagation data and prediction methods required for the design
   of Earth-space telecommunication systems", clause 2.4.1.
.. [3] ITU-R P.2108-1, "Prediction of clutter loss", clause 3.3.
"""

import csv
import functools
import io
from importlib import resources

import numpy as np

from leolink import compiled
from leolink.errors import ConfigError

__all__ = [
    "BANDS",
    "ENVIRONMENTS",
    "KA_BAND_FROM_HZ",
    "band_for_frequency",
    "clutter_loss_db",
    "ionospheric_scintillation_db",
    "link_table_values",
    "los_probability",
    "read_table",
    "scintillation_db",
    "shadow_sigma_db",
    "tropospheric_scintillation_db",
    "validate_environment",
]

ENVIRONMENTS = ("open", "rural", "suburban", "urban", "dense_urban")
BANDS = ("s", "ka")

# Geometric mean of the report's S (2 GHz) and Ka (20 GHz downlink) bands: decision 2.
KA_BAND_FROM_HZ = float(np.sqrt(2.0e9 * 20.0e9))

# Which column/rows of the report's tables serve each environment.
_TABLE_ENVIRONMENT = {
    "rural": "suburban_rural",
    "suburban": "suburban_rural",
    "urban": "urban",
    "dense_urban": "dense_urban",
}

# Clause 6.6.6: ionospheric scintillation below 6 GHz, tropospheric above.
_IONOSPHERIC_BELOW_HZ = 6.0e9
# Clause 6.6.6.1.4: peak-to-peak fluctuation 1.1 dB at 4 GHz read from Figure 6.6.6.1.4-1
# (99 % of time), scaled as f^-1.5 and divided by sqrt(2) to give the loss, applied only
# within 20 degrees of the geomagnetic equator (0 dB at mid and high latitudes).
_PFLUC_4GHZ_DB = 1.1
_IONOSPHERIC_MAX_GEOMAGNETIC_LAT_DEG = 20.0
_TROPOSPHERIC_REF_HZ = 20.0e9
_TROPOSPHERIC_FREQ_EXPONENT = 7.0 / 12.0  # ITU-R P.618-13 clause 2.4.1, sigma ~ f^(7/12)


def read_table(name):
    """Read a shipped CSV table: ``#`` comment header, column names, units row, data.

    Parameters
    ----------
    name : str
        File name inside ``leolink/data`` (e.g. ``"tr38811_los_probability.csv"``).

    Returns
    -------
    columns : tuple of str
    units : tuple of str
    rows : tuple of tuple of str
        The data rows as text (the caller converts).
    comments : tuple of str
        The header comment lines (source, version, table number).
    """
    return _read_table_cached(name)


@functools.cache
def _read_table_cached(name):
    text = resources.files("leolink").joinpath("data", name).read_text(encoding="utf-8")
    lines = text.splitlines()
    comments = tuple(line for line in lines if line.startswith("#"))
    body = [line for line in lines if line.strip() and not line.startswith("#")]
    records = list(csv.reader(io.StringIO("\n".join(body))))
    return tuple(records[0]), tuple(records[1]), tuple(tuple(r) for r in records[2:]), comments


@functools.cache
def _los_table():
    """Table 6.6.1-1 as (elevation_deg, {table column: probability as a fraction})."""
    columns, _, rows, _ = read_table("tr38811_los_probability.csv")
    values = np.array(rows, dtype=float)
    elevation_deg = values[:, 0]
    return elevation_deg, {c: values[:, i] / 100.0 for i, c in enumerate(columns) if i > 0}


@functools.cache
def _sfcl_table():
    """Tables 6.6.2-1..3 as {(table environment, column): values over elevation_deg}."""
    columns, _, rows, _ = read_table("tr38811_shadowing_clutter.csv")
    out = {}
    for env in sorted({r[1] for r in rows}):
        sub = [r for r in rows if r[1] == env]
        out[(env, "elevation_deg")] = np.array([float(r[0]) for r in sub])
        for i, col in enumerate(columns[3:], start=3):
            out[(env, col)] = np.array([float(r[i]) for r in sub])
    return out


@functools.cache
def _troposcint_table():
    """Table 6.6.6.2.1-1 as (elevation_deg, loss_db)."""
    _, _, rows, _ = read_table("tr38811_tropospheric_scintillation.csv")
    values = np.array(rows, dtype=float)
    return values[:, 0], values[:, 1]


def validate_environment(environment):
    """Return ``environment`` if it is one of :data:`ENVIRONMENTS`, else raise ConfigError."""
    if environment not in ENVIRONMENTS:
        raise ConfigError(
            f"environment = {environment!r} is not allowed; use one of {', '.join(ENVIRONMENTS)}"
        )
    return environment


def _validate_band(band):
    if band not in BANDS:
        raise ConfigError(f"band = {band!r} is not allowed; use 's' (2 GHz) or 'ka' (20/30 GHz)")
    return band


def band_for_frequency(freq_hz, band=None):
    """Which TR 38.811 table (S or Ka band) serves a carrier frequency (decision 2).

    Parameters
    ----------
    freq_hz : float
        Carrier frequency [Hz]; TR 38.811 covers 0.5..100 GHz.
    band : {None, "s", "ka"}
        Explicit choice; ``None`` applies the rule: ``"ka"`` from
        :data:`KA_BAND_FROM_HZ` (6.32 GHz, geometric mean of 2 and 20 GHz) up, else ``"s"``.

    Returns
    -------
    str
        ``"s"`` or ``"ka"``; 11.45 GHz gives ``"ka"``.
    """
    if band is not None:
        return _validate_band(band)
    if not 0.5e9 <= freq_hz <= 100e9:
        raise ConfigError(
            f"freq_hz = {freq_hz!r} is not allowed; use 0.5e9..100e9 (TR 38.811 frequency range)"
        )
    return "ka" if freq_hz >= KA_BAND_FROM_HZ else "s"


def los_probability(elevation_deg, environment):
    """LoS probability at an elevation, TR 38.811 Table 6.6.1-1 [1].

    Linear interpolation between the tabulated 10..90 degree rows; below 10 degrees the
    10-degree value (clamped, decision 1).

    Parameters
    ----------
    elevation_deg : array_like, any shape (e.g. (n_ut, n_sat))
        Elevation of the satellite seen from the UT [deg].
    environment : str
        One of :data:`ENVIRONMENTS`; ``"open"`` gives 1 everywhere.

    Returns
    -------
    ndarray, shape of ``elevation_deg``
        Probability in [0, 1] (the table's percent / 100).
    """
    elevation_deg = np.asarray(elevation_deg, dtype=float)
    if validate_environment(environment) == "open":
        return np.ones_like(elevation_deg)
    grid_deg, columns = _los_table()
    return np.interp(elevation_deg, grid_deg, columns[_TABLE_ENVIRONMENT[environment]])


def _sfcl(elevation_deg, environment, band, quantity):
    table = _sfcl_table()
    env = _TABLE_ENVIRONMENT[environment]
    grid = table[(env, "elevation_deg")]
    return np.interp(elevation_deg, grid, table[(env, f"{_validate_band(band)}_{quantity}")])


#: The columns of Tables 6.6.2-1..3 a link reads, after Table 6.6.1-1's LoS probability.
_LINK_COLUMNS = ("sigma_sf_los_db", "sigma_sf_nlos_db", "cl_nlos_db")


def link_table_values(elevation_deg, environment, band):
    """The table values of many links of one non-open environment: :func:`los_probability`,
    :func:`shadow_sigma_db` in LoS and in NLoS and :func:`clutter_loss_db`, the same bits.

    Where the compiled loops run and the tables share their elevation grid (TR 38.811's
    10..90 degrees), one loop finds each elevation's segment once for the four columns
    and interpolates as :func:`numpy.interp` does (``slope (x - x_j) + y_j``, the slopes of
    adjacent rows, the end rows beyond the grid): ~4 lookups for the price of one.

    Parameters
    ----------
    elevation_deg : ndarray, shape (n,)
        Elevations [deg], not NaN.
    environment : str
        One of :data:`ENVIRONMENTS` but ``"open"``.
    band : {"s", "ka"}

    Returns
    -------
    tuple of 4 ndarray, shape (n,)
        LoS probability [-], sigma_SF in LoS and in NLoS [dB], clutter loss CL [dB].
    """
    el = np.ascontiguousarray(elevation_deg, dtype=float).reshape(-1)
    grid_deg, los_columns = _los_table()
    table = _sfcl_table()
    env = _TABLE_ENVIRONMENT[validate_environment(environment)]
    band = _validate_band(band)
    columns = [los_columns[env]] + [table[(env, f"{band}_{q}")] for q in _LINK_COLUMNS]
    sfcl_grid = table[(env, "elevation_deg")]
    if not (compiled.use(el.size) and np.array_equal(sfcl_grid, grid_deg)):
        grids = (grid_deg, sfcl_grid, sfcl_grid, sfcl_grid)
        return tuple(np.interp(el, g, c) for g, c in zip(grids, columns, strict=True))
    values = np.array(columns)  # (4, n_grid)
    slopes = np.diff(values, axis=1) / np.diff(grid_deg)  # numpy.interp's
    out = np.empty((len(columns), el.size))
    compiled.run_rows(_table_rows, el.size, el, grid_deg, (values, slopes), out)
    return tuple(out)


@compiled.jit
def _table_rows(x, grid, table, out, lo, hi):
    """:func:`numpy.interp` of each row of ``table = (values, slopes)`` (n_col, n_grid) at
    ``x[lo:hi]`` (not NaN) on ``grid``, into ``out[:, lo:hi]``: each segment found once."""
    values, slopes = table
    last = grid.size - 1
    for i in range(lo, hi):
        xi = x[i]
        j = 0
        while j < last and grid[j + 1] <= xi:
            j += 1
        for c in range(values.shape[0]):
            if xi <= grid[0] or j == last or grid[j] == xi:  # an end row, or a node
                out[c, i] = values[c, j]
            else:
                out[c, i] = slopes[c, j] * (xi - grid[j]) + values[c, j]


def shadow_sigma_db(elevation_deg, environment, band, los):
    """Shadow-fading standard deviation sigma_SF, TR 38.811 Tables 6.6.2-1..3 [1].

    Parameters
    ----------
    elevation_deg : array_like
        Elevation [deg]; interpolated and clamped as in :func:`los_probability`.
    environment : str
        One of :data:`ENVIRONMENTS`; ``"open"`` gives 0.
    band : {"s", "ka"}
        Table band, see :func:`band_for_frequency`.
    los : bool or array_like of bool, broadcastable to ``elevation_deg``
        Link state: the LoS or the NLoS column.

    Returns
    -------
    ndarray, broadcast shape of ``elevation_deg`` and ``los``
        sigma_SF [dB].
    """
    elevation_deg = np.asarray(elevation_deg, dtype=float)
    los = np.asarray(los, dtype=bool)
    if validate_environment(environment) == "open":
        return np.zeros(np.broadcast_shapes(elevation_deg.shape, los.shape))
    sigma_los = _sfcl(elevation_deg, environment, band, "sigma_sf_los_db")
    sigma_nlos = _sfcl(elevation_deg, environment, band, "sigma_sf_nlos_db")
    return np.where(los, sigma_los, sigma_nlos)


def clutter_loss_db(elevation_deg, environment, band):
    """Clutter loss CL of an NLoS link, TR 38.811 Tables 6.6.2-1..3 [1].

    The report applies CL in NLoS only; a LoS link has 0 dB (the caller selects).

    Parameters
    ----------
    elevation_deg : array_like
        Elevation [deg]; interpolated and clamped as in :func:`los_probability`.
    environment : str
        One of :data:`ENVIRONMENTS`; ``"open"`` gives 0.
    band : {"s", "ka"}

    Returns
    -------
    ndarray, shape of ``elevation_deg``
        CL [dB], positive (a loss).
    """
    elevation_deg = np.asarray(elevation_deg, dtype=float)
    if validate_environment(environment) == "open":
        return np.zeros_like(elevation_deg)
    return _sfcl(elevation_deg, environment, band, "cl_nlos_db")


def ionospheric_scintillation_db(freq_hz, geomagnetic_latitude_deg):
    """Ionospheric scintillation loss, TR 38.811 clause 6.6.6.1.4 [1].

    ``P_fluc(f) = P_fluc(4 GHz) (f / 4 GHz)^-1.5`` with ``P_fluc(4 GHz) = 1.1 dB``
    (Figure 6.6.6.1.4-1, 99 % of time) and loss ``P_fluc / sqrt(2)``, i.e.
    ``6.22 / f_GHz^1.5`` dB, within 20 degrees of the geomagnetic equator; 0 dB at
    higher geomagnetic latitudes (the report neglects it there; Vigo, the paper's ROI
    centre, is a mid-latitude site).

    Parameters
    ----------
    freq_hz : array_like
        Carrier frequency [Hz] (the model is meant for f < 6 GHz).
    geomagnetic_latitude_deg : array_like
        Geomagnetic (not geographic) latitude of the UT [deg].

    Returns
    -------
    ndarray, broadcast shape
        Loss [dB], >= 0.
    """
    f_ghz = np.asarray(freq_hz, dtype=float) / 1e9
    low_latitude = np.abs(geomagnetic_latitude_deg) <= _IONOSPHERIC_MAX_GEOMAGNETIC_LAT_DEG
    loss_db = _PFLUC_4GHZ_DB * (f_ghz / 4.0) ** -1.5 / np.sqrt(2.0)
    return np.where(low_latitude, loss_db, 0.0)


def tropospheric_scintillation_db(elevation_deg, freq_hz):
    """Tropospheric scintillation loss, TR 38.811 Table 6.6.6.2.1-1 [1] (decision 3).

    The table (20 GHz, Toulouse, 99 % value) interpolated in elevation and clamped as in
    :func:`los_probability`, scaled by ``(f / 20 GHz)^(7/12)`` (ITU-R P.618-13 [2]).

    Parameters
    ----------
    elevation_deg : array_like
        Elevation [deg].
    freq_hz : array_like, broadcastable
        Carrier frequency [Hz].

    Returns
    -------
    ndarray, broadcast shape
        Loss [dB], >= 0; equal to the table at 20 GHz.
    """
    grid_deg, loss_db = _troposcint_table()
    at_20ghz_db = np.interp(np.asarray(elevation_deg, dtype=float), grid_deg, loss_db)
    scale = (np.asarray(freq_hz, dtype=float) / _TROPOSPHERIC_REF_HZ) ** _TROPOSPHERIC_FREQ_EXPONENT
    return at_20ghz_db * scale


def scintillation_db(elevation_deg, freq_hz, geomagnetic_latitude_deg=None):
    """Scintillation margin of clause 6.6.6 [1]: ionospheric below 6 GHz, tropospheric above.

    Parameters
    ----------
    elevation_deg : array_like
        Elevation [deg].
    freq_hz : float
        Carrier frequency [Hz].
    geomagnetic_latitude_deg : float or array_like, optional
        Needed below 6 GHz only (:func:`ionospheric_scintillation_db`).

    Returns
    -------
    ndarray, shape of ``elevation_deg``
        Loss [dB], >= 0.
    """
    elevation_deg = np.asarray(elevation_deg, dtype=float)
    if freq_hz < _IONOSPHERIC_BELOW_HZ:
        if geomagnetic_latitude_deg is None:
            raise ConfigError(
                f"geomagnetic_latitude_deg is required for scintillation at freq_hz = "
                f"{freq_hz!r} (< 6 GHz: ionospheric, TR 38.811 clause 6.6.6.1)"
            )
        loss_db = ionospheric_scintillation_db(freq_hz, geomagnetic_latitude_deg)
        return np.broadcast_to(loss_db, elevation_deg.shape).astype(float)
    return tropospheric_scintillation_db(elevation_deg, freq_hz)
