"""Link budget, atmospheric loss and UT fading (Sec. 2.2 and 4 of the paper)."""

from leolink.link.atmosphere import ATMOSPHERES, AtmosphereTable, atmosphere_model
from leolink.link.budget import (
    LinkBudget,
    db,
    fspl_db,
    interference_dbw,
    lin,
    noise_power_dbw,
    rss_dbw,
    sinr_lin,
    snr_db,
    spectral_efficiency_bps_hz,
    throughput_bps,
)
from leolink.link.fading import mean_rician_gain_lin, rician_gain_lin

__all__ = [
    "AtmosphereTable",
    "LinkBudget",
    "ATMOSPHERES",
    "atmosphere_model",
    "db",
    "fspl_db",
    "interference_dbw",
    "lin",
    "mean_rician_gain_lin",
    "noise_power_dbw",
    "rician_gain_lin",
    "rss_dbw",
    "sinr_lin",
    "snr_db",
    "spectral_efficiency_bps_hz",
    "throughput_bps",
]
