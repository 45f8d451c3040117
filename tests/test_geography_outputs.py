"""KPIs by latitude band (summary.json ``overall.by_latitude``) and the per-UT map files
(``[output.ut_map]``: ut_map.csv, ut_map.geojson, ut_map.png), checked against the trace
and the events recomputed by hand (pandas), with movers that cross band edges.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import leolink
from leolink.config import load_config
from leolink.io.summary.bands import BAND_DEG, band_of

CITIES = Path(__file__).parent / "data" / "cities_20.toml"
#: trace.parquet keeps the SINR as float32 (positions and times as float64): a mean of
#: its values is within a few float32 ulp of the statistics' float64 mean.
F32 = 1e-6
#: Movers starting just below a band edge, north-bound at 250 m/s (0.0022 deg/s): each
#: crosses it within ~20 s.
MOVERS = """
[[population]]
name = "crossers"
kind = "constant_velocity"
placement = "sites"
speed = "aircraft"
heading_deg = 0.0
lat_deg = [9.98, 49.99, -20.01, -0.005, 39.995]
lon_deg = [20.0, -100.0, 130.0, -30.0, 10.0]
"""


def _result(tmp_path, seconds=40.0, out=True):
    text = CITIES.read_text().replace('"cities_20.csv"', repr(str(CITIES.parent / "cities_20.csv")))
    config = tmp_path / "crossers.toml"
    config.write_text(text + MOVERS)
    sets = [f"run.duration_s={seconds}", "output.trace.enabled=true",
            "output.trace.formats=['parquet']", "output.ut_map.enabled=true"]  # fmt: skip
    return leolink.run(load_config(config, sets), tmp_path / "run" if out else None)


@pytest.fixture(scope="module")
def done(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("geo")
    res = _result(tmp)
    trace = pd.read_parquet(tmp / "run" / "trace.parquet")
    events = pd.read_csv(tmp / "run" / "events.csv")
    return res, trace, events, tmp / "run"


def test_bands_are_the_trace_binned_by_latitude(done):
    res, trace, events, _ = done
    band = np.floor((trace["lat_deg"] + 90.0) / BAND_DEG).astype(int)
    crossers = trace[trace["population"] == "crossers"].groupby("ut_id")["lat_deg"]
    crossed = np.floor((crossers.max() + 90) / 10) != np.floor((crossers.min() + 90) / 10)
    assert crossed.sum() >= 4  # most movers change band during the run
    at = trace.set_index(["ut_id", "time_s"])["lat_deg"]
    ho = events[events["kind"].isin(["beam_handover", "sat_handover"])]
    ho_band = np.floor((at.loc[list(zip(ho["ut_id"], ho["time_s"], strict=True))].to_numpy()
                        + 90.0) / BAND_DEG).astype(int)  # fmt: skip
    got = {round(b["lat_min_deg"]): b for b in res.summary["overall"]["by_latitude"]}
    assert len(got) >= 6 and len(ho) > 20
    for b, rows in trace.groupby(band):
        row = got.pop(round(-90 + 10 * b))
        assert row["lat_max_deg"] == row["lat_min_deg"] + BAND_DEG
        assert row["n_ut_epochs"] == len(rows)
        assert row["ut_minutes"] == pytest.approx(len(rows) / 60.0, rel=1e-12)
        assert row["outage_fraction"] == pytest.approx((rows["service"] == "outage").mean())
        sinr = rows["sinr_db"][np.isfinite(rows["sinr_db"])]
        if sinr.size:
            assert row["sinr_mean_db"] == pytest.approx(sinr.mean(), rel=F32)
        else:  # a band where nobody is served
            assert row["sinr_mean_db"] is None
        n_ho = int((ho_band == b).sum())
        assert row["n_handovers"] == n_ho
        assert row["handover_rate_per_ut_min"] == pytest.approx(n_ho / (len(rows) / 60.0))
    assert not got  # no band without rows


def test_band_edges():
    """A latitude on an edge is in the band above it; 90 deg in the last band."""
    assert band_of([-90.0, -80.0, -80.0 - 1e-12, 0.0, 89.9, 90.0]).tolist() == [
        0, 1, 0, 9, 17, 17]  # fmt: skip


def test_ut_map_files_hold_each_uts_values(done):
    res, trace, events, folder = done
    table = pd.read_csv(folder / "ut_map.csv")
    first = trace.sort_values(["ut_id", "time_s"]).groupby("ut_id").first()
    assert table["ut_id"].tolist() == list(range(25))
    np.testing.assert_array_equal(table["lat_deg"], first["lat_deg"])
    np.testing.assert_array_equal(table["lon_deg"], first["lon_deg"])
    n_ho = events[events["kind"].isin(["beam_handover", "sat_handover"])].groupby("ut_id").size()
    minutes = trace.groupby("ut_id").size() / 60.0
    want_rate = n_ho.reindex(range(25), fill_value=0) / minutes
    np.testing.assert_allclose(table["handover_rate_per_ut_min"], want_rate, rtol=1e-12)
    outage = trace.groupby("ut_id")["service"].apply(lambda s: (s == "outage").mean())
    np.testing.assert_allclose(table["outage_fraction"], outage, rtol=1e-12)
    sinr = trace.groupby("ut_id")["sinr_db"].apply(lambda s: s[np.isfinite(s)].mean())
    np.testing.assert_allclose(table["sinr_mean_db"], sinr, rtol=F32, equal_nan=True)
    geo = json.loads((folder / "ut_map.geojson").read_text())
    assert geo["type"] == "FeatureCollection" and len(geo["features"]) == 25
    f = geo["features"][21]  # a mover: [lon, lat] of where it started
    assert f["geometry"]["coordinates"] == [first["lon_deg"][21], first["lat_deg"][21]]
    assert f["properties"]["outage_fraction"] == pytest.approx(outage[21])
    manifest = json.loads((folder / "run.json").read_text())
    listed = json.dumps(manifest)
    assert all(name in listed for name in ("ut_map.csv", "ut_map.geojson", "ut_map.png"))
    assert (folder / "ut_map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(folder.glob("*.tmp*"))


def test_bands_in_memory_equal_the_written_ones(done, tmp_path):
    """Frames of one epoch or of a block, with or without a folder: the same bands."""
    res, _, _, _ = done
    again = _result(tmp_path, out=False)
    assert again.summary["overall"]["by_latitude"] == res.summary["overall"]["by_latitude"]
