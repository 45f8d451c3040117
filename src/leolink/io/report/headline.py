"""The story at the top of ``report.html``: what was run, and the figures that matter.

:func:`header_lines` names the run (scenario, config file, UTC date, leolink version, run
time) from ``summary["run"]``; :func:`headline_figures` turns ``summary["overall"]`` into
six figures in human units (Mbit/s, dB, s, per UT-minute, %, kHz), each with one sentence
saying what it is. Every number is read from the summary: the page computes nothing the
summary does not hold, so the figures and the folded tables below agree by construction.
The mean dwell is ``overall.dwell.mean_s``, the mean of the complete dwells (the one
definition; the dwell histogram's legend shows the same number).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Headline", "config_description", "fmt_si", "header_lines", "headline_figures"]


@dataclass(frozen=True)
class Headline:
    """One headline figure: ``label``, ``value`` (number and unit), ``sentence``;
    ``warn`` marks a figure that needs the reader's attention."""

    label: str
    value: str
    sentence: str
    warn: bool = False


def _get(d, *path):
    for key in path:
        d = d.get(key) if isinstance(d, dict) else None
    return d


def _num(value):
    """``value`` as a finite float, else None."""
    if value is None or isinstance(value, bool):
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def fmt_si(value, digits=3):
    """``value`` to ``digits`` significant digits, no exponent (``'-'`` when unknown)."""
    v = _num(value)
    if v is None:
        return "-"
    if v == 0.0:
        return "0"
    decimals = max(digits - 1 - int(math.floor(math.log10(abs(v)))), 0)
    return f"{v:,.{decimals}f}"


def _pct(fraction):
    f = _num(fraction)
    if f is None:
        return "-"
    return "0 %" if f == 0.0 else f"{fmt_si(100.0 * f, 2)} %"


def config_description(path):
    """First sentence of the comment block that opens a config file ('' if none)."""
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError, ValueError):
        return ""
    text = []
    for line in lines:
        if not line.startswith("#"):
            break
        text.append(line.lstrip("#").strip())
    words = " ".join(text)
    end = words.find(": ")  # the scenario's name ends at the first colon or full stop
    stop = words.find(". ")
    cut = [i for i in (end, stop) if i > 0]
    return words[: min(cut)] + "." if cut else words


def header_lines(run):
    """``(title, meta, description)`` of the page header from ``summary["run"]``."""
    scenario = run.get("scenario") or "leolink run"
    parts = []
    if run.get("config_file"):
        parts.append(f"config {run['config_file']}")
    if run.get("run_utc"):
        parts.append(str(run["run_utc"]).replace("T", " ")[:16] + " UTC")
    if run.get("leolink_version"):
        parts.append(f"leolink {run['leolink_version']}")
    n_ut, start, end = run.get("n_ut"), run.get("start_s"), run.get("end_s")
    if n_ut is not None and start is not None and end is not None:
        span = f"{n_ut:,} UTs x {end - start:g} s (epoch {run.get('epoch_s'):g} s)"
        wall = _num(run.get("wall_time_s"))
        parts.append(span + (f" simulated in {fmt_si(wall, 2)} s" if wall is not None else ""))
    return f"{scenario}: leolink run report", " · ".join(parts), run.get("description", "")


def _throughput(o):
    mean = _num(o.get("mean_throughput_bps"))
    p50 = _num(_get(o, "kpi", "throughput_bps_percentiles", "p50"))
    sentence = "Mean downlink throughput of a UT over the run (an epoch in outage counts as 0)"
    if p50 is not None:
        sentence += f"; half the UT-epochs get more than {fmt_si(p50 / 1e6)} Mbit/s"
    value = "-" if mean is None else f"{fmt_si(mean / 1e6)} Mbit/s"
    return Headline("Throughput per UT", value, sentence + ".")


def _sinr(o):
    sinr, snr = o.get("sinr_db") or {}, o.get("snr_db") or {}
    sentence = (
        f"Median SINR of the serving link over the served UT-epochs (SNR {fmt_si(snr.get('p50'))}"
        f" dB); 5 % of them are below {fmt_si(sinr.get('p5'))} dB."
    )
    return Headline("Median SINR", f"{fmt_si(sinr.get('p50'))} dB", sentence)


def _dwell(o):
    d = o.get("dwell") or {}
    n, n_cut = d.get("n_complete") or 0, d.get("n_censored") or 0
    if not n:
        return Headline(
            "Mean time in a beam",
            "-",
            f"No stay in a beam both began and ended inside the run ({n_cut:,} cut by its "
            "start or end): the run is shorter than a dwell.",
        )
    return Headline(
        "Mean time in a beam",
        f"{fmt_si(d.get('mean_s'))} s",
        f"Mean of the {n:,} complete stays in a beam (median {fmt_si(d.get('median_s'))} s); "
        f"the {n_cut:,} cut by the start or end of the run are not counted.",
    )


def _handovers(o, run):
    h, rate = o.get("handovers") or {}, _get(o, "kpi", "handover_rate_per_ut_min")
    minutes = ""
    if run.get("n_ut") and run.get("end_s") is not None:
        span_min = run["n_ut"] * (run["end_s"] - run["start_s"]) / 60.0
        minutes = f" in {span_min:,.4g} UT-minutes"
    ping_pong = _pct(_get(o, "kpi", "ping_pong_fraction"))
    return Headline(
        "Handovers",
        f"{fmt_si(rate)} per UT-minute",
        f"{h.get('beam_handover', 0):,} beam and {h.get('sat_handover', 0):,} satellite "
        f"handovers{minutes}; a ping-pong fraction of {ping_pong}.",
    )


def _service(o):
    outage = _num(o.get("outage_fraction")) or 0.0
    without = _get(o, "link", "served_without_modcod") or {}
    no_modcod, ut_s = _num(without.get("fraction")), _num(without.get("ut_s"))
    by_reason = {k: v for k, v in (o.get("outage_fraction_by_reason") or {}).items() if v}
    if outage:
        worst = max(by_reason, key=by_reason.get) if by_reason else "unspecified"
        sentence = f"Part of the UT-epochs with no service, most of it {worst.replace('_', ' ')}"
    else:
        sentence = "Every UT-epoch of the run is served"
    if no_modcod is None:
        sentence += "."
    elif no_modcod:
        sentence += (
            f"; {_pct(no_modcod)} of the served UT-time ({fmt_si(ut_s)} UT-s) closes no "
            "DVB-S2X MODCOD (negative margin): served on paper only (controller.service_metric "
            '= "modcod" counts it as outage).'
        )
    else:
        sentence += "; every served UT-epoch closes a DVB-S2X MODCOD."
    return Headline("Outage", _pct(outage), sentence, warn=bool(no_modcod) or outage > 0.05)


def _doppler(o):
    doppler, speed = _num(o.get("max_abs_doppler_hz")), o.get("max_angular_speed_deg_s")
    return Headline(
        "Largest Doppler shift",
        "-" if doppler is None else f"{fmt_si(doppler / 1e3)} kHz",
        f"Largest |Doppler| of a serving link, satellite and UT motion together; the serving "
        f"satellite moves across the sky at up to {fmt_si(speed)} deg/s.",
    )


def headline_figures(summary):
    """The six headline figures of a run summary (``summary.json``), in reading order."""
    o, run = summary.get("overall", {}), summary.get("run", {})
    return [_throughput(o), _sinr(o), _dwell(o), _handovers(o, run), _service(o), _doppler(o)]
