"""Notebook views of a real run: figures, the HTML summary and the (time x UT) dataset."""

import json

import numpy as np
import pandas as pd
import pytest
from matplotlib.collections import PolyCollection

from leolink.io.notebook import ResultViews, dense
from report_helpers import make_run


class _Result(ResultViews):
    """What leolink.run() returns, read back from a run folder."""

    def __init__(self, out):
        self.trace = pd.read_csv(out / "trace.csv")
        self.events = pd.read_csv(out / "events.csv")
        self.summary = json.loads((out / "summary.json").read_text())
        self.satellites = pd.read_csv(out / "satellites.csv")
        self.codebook = json.loads((out / "codebook.json").read_text())


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    return _Result(make_run(tmp_path_factory.mktemp("paper")))


def test_plot_sinr_draws_the_trace_of_each_chosen_ut(result):
    fig = result.plot_sinr(ut_ids=[1, 5])
    axes = [ax for ax in fig.axes if ax.get_title(loc="left")]
    assert [ax.get_title(loc="left") for ax in axes] == ["UT 1", "UT 5"]
    rows = result.trace[result.trace["ut_id"] == 5].sort_values("time_s")
    snr_line = axes[1].get_lines()[0]
    np.testing.assert_array_equal(snr_line.get_xdata(), rows["time_s"].to_numpy())
    np.testing.assert_array_equal(snr_line.get_ydata(), rows["snr_db"].to_numpy())
    n_handovers = int((result.events["ut_id"] == 5).sum())
    assert len(axes[1].get_lines()) == 2 + n_handovers  # SNR, SINR and one line per handover


def test_plot_dwell_counts_complete_and_censored_dwells_of_the_summary(result):
    fig = result.plot_dwell()
    titles = [ax.get_title() for ax in fig.axes]
    dwell = result.summary["overall"]["dwell"]
    assert titles[0].endswith(f": {dwell['n_complete']}")
    assert titles[1].endswith(f": {dwell['n_censored']}")


def test_plot_map_draws_the_15_beam_cells_of_the_serving_satellite(result):
    ax = result.plot_map().axes[0]
    cells = [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert len(cells[0].get_paths()) == 15


def test_other_views_return_figures(result):
    for fig in (
        result.plot_doppler([0]),
        result.plot_angular_speed([0]),
        result.plot_cdfs(),
        result.plot_outage(),
        result.plot_timeline([0, 1]),
    ):
        assert fig.axes


def test_repr_html_shows_the_kpis(result):
    page = result._repr_html_()
    mean = result.summary["overall"]["snr_db"]["mean"]
    assert f"<td>mean SNR</td><td>{mean:.4g} dB</td>" in page


def test_dense_and_to_xarray_are_time_by_ut(result):
    t, u, snr = dense(result.trace, "snr_db")
    assert snr.shape == (120, 7) and t[0] == 0.0 and list(u) == list(range(7))
    row = result.trace[(result.trace["time_s"] == 14.0) & (result.trace["ut_id"] == 3)]
    assert snr[14, 3] == row["snr_db"].item()
    ds = result.to_xarray()
    assert ds["snr_db"].dims == ("time", "ut_id")
    assert ds["beam_id"].sel(time=14.0, ut_id=3).item() == row["beam_id"].item()


def test_to_xarray_holds_every_trace_column_with_its_type_and_units(result):
    ds, trace = result.to_xarray(), result.trace
    assert set(ds.data_vars) == set(trace.columns) - {"time_s", "ut_id", "population"}
    for column in ds.data_vars:  # pandas' own reshaping, column by column
        wide = trace.pivot(index="time_s", columns="ut_id", values=column)
        np.testing.assert_array_equal(
            ds[column].to_numpy(), wide.to_numpy().astype(ds[column].dtype)
        )
    for column in ("ut_id", "sat_id", "beam_id", "n_visible"):
        assert np.issubdtype(ds[column].dtype, np.integer), column
    assert (
        ds["snr_db"].attrs["units"] == "dB"
        and "signal-to-noise" in ds["snr_db"].attrs["description"]
    )
    assert ds["lat_deg"].attrs["units"] == "degrees_north"
    assert ds["throughput_bps"].attrs["units"] == "bit s-1"
    assert "units" not in ds["beam_id"].attrs and ds["beam_id"].attrs["description"]
    assert ds["time"].attrs["units"] == "s"
    assert ds["population"].dims == ("ut_id",)
    assert ds["population"].sel(ut_id=[0, 1, 5, 6]).to_numpy().tolist() == [
        "centre", "static", "car", "aircraft"
    ]  # fmt: skip
    assert "time_utc" not in ds.coords  # the paper's run has no UTC


def test_every_trace_column_has_units_and_a_description():
    from leolink.io.table_schemas import ENVIRONMENT_COLUMNS, TRACE_COLUMN_DOCS, TRACE_COLUMNS
    from leolink.timing import TIMING_COLUMNS

    assert set(TRACE_COLUMN_DOCS) == set(TRACE_COLUMNS + ENVIRONMENT_COLUMNS + TIMING_COLUMNS)
    assert all(description for _, description in TRACE_COLUMN_DOCS.values())


def test_to_xarray_time_utc_follows_start_utc_and_start_s():
    import leolink
    from leolink.config import load_config

    over = ["run.start_utc='2026-03-01T12:00:00Z'", "run.start_s=10.0", "run.duration_s=4.0",
            "output.plots.enabled=false"]  # fmt: skip
    res = leolink.run(load_config("configs/paper.toml", over))
    ds = res.to_xarray()
    assert ds["time"].to_numpy().tolist() == [10.0, 11.0, 12.0, 13.0]
    utc = ds["time_utc"].to_numpy()
    assert utc[0] == np.datetime64("2026-03-01T12:00:00", "ns")  # the first epoch: start_utc
    assert utc[3] - utc[0] == np.timedelta64(3, "s")
    assert len(repr(res)) <= 1000 and repr(res).startswith("<leolink.Result: 7 UTs x 4 epochs")
    assert "in memory" in repr(res) and "7 UTs x 4 epochs" in res._repr_html_()
