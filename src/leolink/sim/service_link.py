"""What the link monitor adds to the engine's serving-link columns: service on SINR, link figures.

Kept apart from :mod:`leolink.sim.processes` so that the monitor's own code stays small: the
figures are a vectorized post-processing of the engine's per-UT outputs
(:func:`leolink.link.acm.link_figure_columns`), applied where the trace frame is assembled.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink.link.acm import LinkFigureParams, link_figure_columns
from leolink.sim.handover.controller import SERVICE_OUTAGE

__all__ = ["ServiceLink"]


@dataclasses.dataclass(frozen=True)
class ServiceLink:
    """How the monitor judges and describes a serving link beyond the engine's columns.

    ``figures``: the parameters of the link figures added to every row
    (:func:`~leolink.link.acm.link_figure_columns`).
    ``sinr_threshold_db``: None judges service as the controller does (on SNR, the paper);
    a number also counts a served row whose SINR is below it as an outage
    (``below_threshold``). The beams and the events stay the controller's (on SNR).
    """

    figures: LinkFigureParams
    sinr_threshold_db: float | None = None

    def service(self, codes, sinr_db):
        """Trace service codes: the controller's, with low-SINR rows turned to outage."""
        if self.sinr_threshold_db is None:
            return codes
        with np.errstate(invalid="ignore"):
            low = (codes != SERVICE_OUTAGE) & ~(sinr_db >= self.sinr_threshold_db)
        return np.where(low, SERVICE_OUTAGE, codes).astype(codes.dtype)

    def add_figures(self, cols, served):
        """Add the link figures; ``throughput_bps``/``se_bps_hz`` follow the model."""
        p = self.figures
        fig = link_figure_columns(cols["snr_db"], cols["sinr_db"], cols["gain_tx_db"], p, served)
        cols.update(fig, throughput_shannon_bps=cols["throughput_bps"])
        if p.throughput_model == "dvbs2x":
            cols["throughput_bps"] = fig["throughput_dvbs2x_bps"]
            cols["se_bps_hz"] = fig["throughput_dvbs2x_bps"] / p.bandwidth_hz
