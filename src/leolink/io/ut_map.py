"""Per-UT values on the globe (``[output.ut_map]``): ``ut_map.csv``, ``ut_map.geojson`` and
the world map ``ut_map.png`` (shown in ``report.html``).

One row (one GeoJSON point feature) per UT, from the run's per-UT statistics
(:meth:`leolink.io.summary.accumulator.SummaryAccumulator.per_ut_table`): ``ut_id``,
``lat_deg``, ``lon_deg`` (where the UT was at its first recorded epoch),
``handover_rate_per_ut_min`` (beam and satellite handovers per minute of the UT),
``outage_fraction`` and ``sinr_mean_db`` (mean of its finite SINR values in dB). Missing
values are empty in the CSV and ``null`` in the GeoJSON. The files are written atomically
once ``summary.json`` is (memory: the per-UT columns, whatever the run length).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from leolink.io.atomic import atomic_file, write_csv_atomic, write_json_atomic

__all__ = ["MAP_COLUMNS", "UtMapSink", "ut_map_columns", "write_ut_map"]

#: The columns of ``ut_map.csv`` (and the properties of each GeoJSON feature).
MAP_COLUMNS = ("ut_id", "lat_deg", "lon_deg", "handover_rate_per_ut_min", "outage_fraction",
               "sinr_mean_db")  # fmt: skip
#: What the world map shows: column, caption, colour map.
_PANELS = (
    ("handover_rate_per_ut_min", "handovers per UT-minute", "viridis"),
    ("outage_fraction", "outage fraction", "viridis"),
    ("sinr_mean_db", "mean SINR [dB]", "plasma"),
)


def ut_map_columns(per_ut, epoch_s):
    """The map's columns of a per-UT table (dict of arrays, one row per UT).

    ``handover_rate_per_ut_min`` is the table's KPI column where it has one, else the
    UT's beam and satellite handovers over its recorded minutes (``n_epochs x epoch_s``).
    """
    cols = {k: np.asarray(per_ut[k]) for k in ("ut_id", "lat_deg", "lon_deg")}
    rate = per_ut.get("handover_rate_per_ut_min")
    if rate is None:
        with np.errstate(invalid="ignore", divide="ignore"):
            minutes = np.asarray(per_ut["n_epochs"], float) * epoch_s / 60.0
            rate = np.asarray(per_ut["n_handovers_total"], float) / minutes
    cols["handover_rate_per_ut_min"] = np.asarray(rate, float)
    cols["outage_fraction"] = np.asarray(per_ut["outage_fraction"], float)
    cols["sinr_mean_db"] = np.asarray(per_ut["sinr_mean_db"], float)
    return cols


def _geojson(cols):
    """A FeatureCollection of one point per UT (GeoJSON, RFC 7946: [lon, lat])."""
    props = [k for k in MAP_COLUMNS if k not in ("lat_deg", "lon_deg")]
    values = {k: cols[k].tolist() for k in (*props, "lat_deg", "lon_deg")}
    features = [
        {
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": [values["lon_deg"][i],
                                                          values["lat_deg"][i]]},
            "properties": {k: values[k][i] for k in props},
        }
        for i in range(len(values["ut_id"]))  # output formatting only
    ]  # fmt: skip
    return {"type": "FeatureCollection", "features": features}


def world_map(cols):
    """The figure of ``ut_map.png``: one world map per value, a point per UT."""
    from leolink.io.report.maps import draw_base, new_figure

    extent = (-180.0, 180.0, -90.0, 90.0)
    fig, _ = new_figure(extent, width_in=9.0)
    fig.clear()
    fig.set_size_inches(9.0, 13.0)
    ok = np.isfinite(cols["lat_deg"]) & np.isfinite(cols["lon_deg"])
    size = float(np.clip(4000.0 / max(ok.sum(), 1), 1.0, 30.0))
    for i, (key, caption, cmap) in enumerate(_PANELS):
        ax = fig.add_axes((0.08, 0.69 - 0.315 * i, 0.8, 0.28))
        draw_base(ax, extent)
        dots = ax.scatter(cols["lon_deg"][ok], cols["lat_deg"][ok], c=cols[key][ok], s=size,
                          cmap=cmap, linewidths=0, zorder=3)  # fmt: skip
        fig.colorbar(dots, ax=ax, shrink=0.8, label=caption)
        ax.set_title(f"{caption}, per UT", fontsize=10)
    return fig


def write_ut_map(per_ut, epoch_s, out_dir):
    """Write ``ut_map.csv``, ``ut_map.geojson`` and ``ut_map.png`` into ``out_dir``
    (each atomically); returns their paths."""
    import pandas as pd

    out_dir = Path(out_dir)
    cols = ut_map_columns(per_ut, epoch_s)
    csv = write_csv_atomic(pd.DataFrame({k: cols[k] for k in MAP_COLUMNS}), out_dir / "ut_map.csv")
    geojson = write_json_atomic(out_dir / "ut_map.geojson", _geojson(cols))
    png = out_dir / "ut_map.png"
    with atomic_file(png) as f:
        world_map(cols).savefig(f, format="png", dpi=90)
    return [csv, geojson, png]


class UtMapSink:
    """The ``[output.ut_map]`` sink: writes the map files once the summary is final
    (:meth:`after_run`); it keeps nothing from the stream (the summary accumulator has
    the per-UT statistics)."""

    def __init__(self, out_dir, summary):
        self.out_dir, self.summary, self.files = Path(out_dir), summary, []
        self.epoch_s = 1.0

    def start(self, info):
        self.epoch_s, self.files = float(info.epoch_s), []

    def epoch(self, frame):
        """Nothing: the per-UT statistics are the summary accumulator's."""

    block = epoch

    def finish(self, final):
        """Nothing until the summary is written."""

    def after_run(self, summary, config_text):
        """Write the files; returns their paths."""
        self.files = write_ut_map(self.summary.per_ut_table(), self.epoch_s, self.out_dir)
        return self.files

    def abort(self):
        """Nothing to clean up: the files are written atomically, last."""
