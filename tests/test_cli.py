"""The CLI's happy paths (``test_cli_errors.py`` has the mistakes): JSON outputs, plots,
interruption, warm-up and Earth rotation in a run."""

import json
import math

import numpy as np
import pandas as pd
import pytest

from leolink.app.run import run
from leolink.cli import main
from leolink.config import load_config
from leolink.constants import BOLTZMANN_J_K

PAPER = "configs/paper.toml"
BUDGET_KEYS = (
    "elevation_deg slant_range_m fspl_db atm_db cable_db gain_tx_db gain_rx_db "
    "rss_dbw noise_dbw snr_db"
).split()


def test_budget_json_has_every_term_and_adds_up(capsys):
    assert main(["budget", PAPER, "--elevation-deg", "70", "--json"]) == 0
    b = json.loads(capsys.readouterr().out)
    assert set(BUDGET_KEYS) <= set(b)
    # Terms recomputed from the paper's equations (Sec. 2.2), independently of leolink.
    r_e, h = 6371e3, 1300e3
    el = math.radians(70)
    rng = -r_e * math.sin(el) + math.sqrt((r_e * math.sin(el)) ** 2 + 2 * r_e * h + h * h)
    assert b["slant_range_m"] == pytest.approx(rng, rel=1e-9)
    fspl = 20 * math.log10(4 * math.pi * rng * 11.45e9 / 299_792_458.0)
    assert b["fspl_db"] == pytest.approx(fspl, abs=1e-9)
    noise = 24.1 + 10 * math.log10(BOLTZMANN_J_K) + 10 * math.log10(250e6)
    assert b["noise_dbw"] == pytest.approx(noise, abs=1e-9)
    rss = 15.0 - 0.0 + b["gain_tx_db"] - 0.017 - fspl + b["gain_rx_db"]
    assert b["rss_dbw"] == pytest.approx(rss, abs=1e-9)
    assert b["snr_db"] == pytest.approx(rss - noise, abs=1e-9)


def test_budget_below_the_mask_says_in_one_line_why_its_figures_are_nan(capsys):
    # paper.toml: constellation.min_elevation_deg = 10; a 5 deg mask serves the same UT
    assert main(["budget", PAPER, "--elevation-deg", "5", "--json"]) == 0
    b = json.loads(capsys.readouterr().out)
    nan = sorted(k for k, v in b.items() if isinstance(v, float) and math.isnan(v))
    assert nan and all(k in b["note"] for k in nan if k != "throughput_shannon_bps")
    assert "min_elevation_deg = 10 deg" in b["note"]
    assert main(["budget", PAPER, "--elevation-deg", "5"]) == 0
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and err.startswith("note: 5 deg is below") and "note" not in out
    sets = ["--set", "constellation.min_elevation_deg=5"]
    assert main(["budget", PAPER, "--elevation-deg", "5", "--json", *sets]) == 0
    b = json.loads(capsys.readouterr().out)
    assert "note" not in b and math.isfinite(b["sinr_db"]) and math.isfinite(b["margin_db"])


def test_help_is_plain_text_with_whole_sentences(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    text = capsys.readouterr().out
    assert "``" not in text and ":func:" not in text
    assert "handovers their motion forces." in text and "Exit codes:" in text
    with pytest.raises(SystemExit):
        main(["budget", "--help"])
    assert "Link budget term by term at one elevation." in capsys.readouterr().out


def test_budget_rejects_elevation_outside_range(capsys):
    assert main(["budget", PAPER, "--elevation-deg", "95"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("leolink: error: --elevation-deg = 95.0 is not allowed")


def test_codebook_json_and_plot(tmp_path, capsys):
    png = tmp_path / "beams.png"
    assert main(["codebook", PAPER, "--json", "--plot", str(png)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["oversampling"] == 1.2
    assert len(info["beams"]) == 15  # 5 x 3 RF chains, one beam each (paper Sec. 5)
    assert {"beam_id", "u_x", "u_y", "x_m", "y_m", "lat_deg", "lon_deg"} <= set(info["beams"][0])
    assert png.read_bytes()[:4] == b"\x89PNG"
    # O = 'auto' solves for as many beams as RF chains (the paper's rule).
    assert main(["codebook", PAPER, "--json", "--set", 'satellite_array.oversampling="auto"']) == 0
    auto = json.loads(capsys.readouterr().out)
    assert len(auto["beams"]) == 15
    assert 1.0996 <= auto["oversampling"] < 1.2843


def test_codebook_footprint_of_central_beam_is_the_roi_centre(capsys):
    main(["codebook", PAPER, "--json"])
    info = json.loads(capsys.readouterr().out)
    centre = [b for b in info["beams"] if b["u_x"] == 0 and b["u_y"] == 0][0]
    assert centre["lat_deg"] == pytest.approx(42.24, abs=1e-9)
    assert centre["lon_deg"] == pytest.approx(-8.72, abs=1e-9)


def test_interrupted_run_leaves_no_complete_looking_file(
    tmp_path, monkeypatch, capsys, blocks_of_64
):
    import leolink.sim.decide

    calls = {"n": 0}
    real = leolink.sim.decide.Decider.__call__

    def decide(self, *a, **k):  # once per epoch: the interrupt comes mid-run
        calls["n"] += 1
        if calls["n"] == 80:
            raise KeyboardInterrupt
        return real(self, *a, **k)

    monkeypatch.setattr(leolink.sim.decide.Decider, "__call__", decide)
    code = main(
        ["run", PAPER, "--out", str(tmp_path), "--quiet", "--set", "output.trace.chunk_rows=70"]
    )
    assert code == 130
    err = capsys.readouterr().err.strip()
    assert err.startswith("leolink: stopped by SIGINT: the run stopped ") and "\n" not in err
    # Where: the last epoch the sinks' thread had recorded (the first block of 64, or none
    # yet when the thread was still on it: both are the truth, and both are said).
    recorded = f"(epoch 64 of 120); {tmp_path} has no run.json (not a finished run)"
    assert recorded in err or "before its first recorded epoch" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_warmup_epochs_are_not_recorded_and_cut_dwells_are_censored():
    cfg = load_config(
        PAPER, ["output.plots.enabled=false", "run.warmup_s=20", "run.duration_s=100"]
    )
    cfg = cfg.model_copy(update={"population": cfg.population[:1]})
    res = run(cfg)
    assert res.trace.time_s.min() == 20.0 and len(res.trace) == 100
    assert (res.events.time_s >= 20.0).all()
    dwell = res.summary["per_ut"][0]["dwell"]
    first = dwell["censored"][0]
    # The first dwell began before recording (at 14 s): cut by the start, so censored.
    assert first["censored_start"] and first["start_s"] < 20.0
    assert dwell["complete_s"] == pytest.approx([31.0, 31.0])


def test_earth_rotation_doppler_is_the_derivative_of_the_ecef_range():
    """With Earth rotation the trace's Doppler must equal -f/c d(range)/dt of the ECEF
    ephemeris and the Earth-fixed UT (drop the -w x r term and it is off by ~3 kHz)."""
    from leolink.app.scenario import ephemeris_from_config
    from leolink.geometry import geodetic_to_ecef

    cfg = load_config(PAPER, ["output.plots.enabled=false", "earth.rotation=true"])
    res = run(cfg.model_copy(update={"population": cfg.population[:1]}))
    tr = res.trace.set_index("time_s")
    assert tr.loc[60.0, "elevation_deg"] == pytest.approx(90.0, abs=1e-6)
    eph = ephemeris_from_config(cfg)
    ut = geodetic_to_ecef(math.radians(42.24), math.radians(-8.72))
    t = np.array([0.0, 30.0, 90.0, 119.0])
    h = 1e-3  # central difference: truncation error ~ h^2/6 d3(range)/dt3, below 1 mHz
    rho = [np.linalg.norm(eph(t + d)[0][:, 0] - ut, axis=-1) for d in (h, -h)]
    expected = -11.45e9 / 299_792_458.0 * (rho[0] - rho[1]) / (2 * h)
    np.testing.assert_allclose(tr.loc[t, "doppler_hz"].to_numpy(), expected, atol=0.01)


def test_run_writes_parquet_with_flag(tmp_path):
    assert (
        main(
            [
                "run",
                PAPER,
                "--out",
                str(tmp_path),
                "--quiet",
                "--parquet",
                "--set",
                "output.plots.enabled=false",
                "--set",
                "run.duration_s=10",
            ]
        )
        == 0
    )
    pq = pd.read_parquet(tmp_path / "trace.parquet")
    csv = pd.read_csv(tmp_path / "trace.csv")
    assert len(pq) == len(csv) == 7 * 10


def test_budget_with_the_paper_atmosphere_model(capsys):
    """The tabulated atmosphere inside the engine agrees with a direct evaluation of the
    paper's 1976-standard-atmosphere integral (2 deg table: within 2e-4 relative)."""
    from leolink.link.atmosphere import paper_model_db

    assert (
        main(
            [
                "budget",
                PAPER,
                "--elevation-deg",
                "40",
                "--json",
                "--set",
                'atmosphere.model="paper"',
            ]
        )
        == 0
    )
    b = json.loads(capsys.readouterr().out)
    direct = float(paper_model_db(np.radians(40.0), 11.45e9))
    assert b["atm_db"] == pytest.approx(direct, rel=2e-4)
    assert 0.05 < b["atm_db"] < 0.2  # zenith 0.059 dB over sin(40 deg), roughly
