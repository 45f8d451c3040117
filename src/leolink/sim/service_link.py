"""What the link monitor adds to the engine's serving-link columns: service on SINR, link figures.

Kept apart from :mod:`leolink.sim.processes` so that the monitor's own code stays small: the
figures are a vectorized post-processing of the engine's per-UT outputs
(:func:`leolink.link.acm.link_figure_columns`), applied where the trace frame is assembled.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink.link.acm import LinkFigureParams, link_figure_columns, link_modcod
from leolink.sim.handover.controller import SERVICE_OUTAGE

__all__ = ["ServiceLink"]


@dataclasses.dataclass(frozen=True)
class ServiceLink:
    """How the monitor judges and describes a serving link beyond the engine's columns.

    ``figures``: the parameters of the link figures added to every row
    (:func:`~leolink.link.acm.link_figure_columns`).
    ``metric`` (``controller.service_metric``): ``"snr"`` judges service as the controller
    does (on SNR, the paper); ``"sinr"`` also counts a served row whose SINR is below
    ``sinr_threshold_db`` as an outage; ``"modcod"`` a served row on which no MODCOD of the
    table closes (:func:`~leolink.link.acm.link_modcod`: Es/N0 of ``[modcod] metric``
    against each threshold plus ``implementation_margin_db``). Such rows are outages for
    ``below_threshold``; the beams and the events stay the controller's (on SNR).
    """

    figures: LinkFigureParams
    sinr_threshold_db: float | None = None
    metric: str = "snr"

    def service(self, codes, cols):
        """Trace service codes: the controller's, with the rows that fail the service
        metric turned to outage (``cols``: the serving-link columns, ``snr_db``, ``sinr_db``)."""
        served = codes != SERVICE_OUTAGE
        if self.metric == "modcod":
            low = served & (link_modcod(cols["snr_db"], cols["sinr_db"], self.figures) < 0)
        elif self.metric == "sinr":
            with np.errstate(invalid="ignore"):
                low = served & ~(cols["sinr_db"] >= self.sinr_threshold_db)
        else:
            return codes
        return np.where(low, SERVICE_OUTAGE, codes).astype(codes.dtype)

    def add_figures(self, cols, served):
        """Add the link figures; ``throughput_bps``/``se_bps_hz`` follow the model."""
        p = self.figures
        fig = link_figure_columns(cols["snr_db"], cols["sinr_db"], cols["gain_tx_db"], p, served)
        cols.update(fig, throughput_shannon_bps=cols["throughput_bps"])
        if p.throughput_model == "dvbs2x":
            cols["throughput_bps"] = fig["throughput_dvbs2x_bps"]
            cols["se_bps_hz"] = fig["throughput_dvbs2x_bps"] / p.bandwidth_hz
