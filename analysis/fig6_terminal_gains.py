"""Fig. 6: gain of the user-terminal antennas.

(a) perfect alignment: the 24 x 24 leaky-wave (CRLH-LW) panel vs its leakage factor, with
its threshold ``coth(a/2)^2`` (infinitely large panel); the 24 x 24 UPA's 27.6 dB
(``N + 1/K``, K = 10); the Kymeta metasurface vs elevation, leolink's ``33 + 1.2 * 10
log10(sin el)`` beside the paper's printed ``33 - 1.2 * 10 log10(sin el)`` (erratum: it
rises at low elevation).
(b) misalignment (Monte Carlo, error uniform in [0, e], random direction): mean and
minimum gain, UPA and leaky wave. The paper: the minimum "becomes critical above 4 deg";
the 24-element array's first null is at ``asin(2/24) = 4.78 deg``.
(c) b-bit phase quantization of the UPA weights, analog vs hybrid (two RF chains);
the analog loss is checked against ``-20 log10(sinc(pi / 2^b))`` (uniform phase error).

Run: ``python analysis/fig6_terminal_gains.py [--fast] [--out DIR]``.
"""

from __future__ import annotations

import sys

import numpy as np
from _common import figure, parse_args, report, save

from leolink.antenna.impairments import misalignment_gain_db, quantization_loss_db
from leolink.antenna.terminal import LeakyWave, Metasurface, UPATerminal

N_UT = 24
RICIAN_K = 10.0
LEAKAGE = 0.05  # configs/paper.toml
SEED = 20201
PEAK_DB, ROLLOFF = 33.0, 1.2


def explicit_leaky_gain_db(n, leakage):
    """Boresight gain of the n x n tapered panel from its weights: |sum w|^2 / sum |w|^2."""
    w = np.exp(-leakage * np.arange(n))
    return 2.0 * 10.0 * np.log10(np.sum(w) ** 2 / np.sum(w**2))


def panel_a(ax_l, ax_e, numbers):
    a = np.logspace(-3, 0.5, 200)
    lw_db = np.array([LeakyWave(N_UT, N_UT, x).gain_db(np.pi / 2) for x in a])
    threshold_db = 20.0 * np.log10(1.0 / np.tanh(a / 2.0))
    upa_db = float(UPATerminal(N_UT, N_UT, RICIAN_K).gain_db(np.pi / 2))
    ax_l.semilogx(a, lw_db, label=f"leaky wave {N_UT}x{N_UT}")
    ax_l.semilogx(a, threshold_db, "--", label="threshold coth(a/2)^2 (N -> inf)")
    ax_l.axhline(upa_db, color="tab:green", label=f"UPA {N_UT}x{N_UT}: {upa_db:.2f} dB")
    ax_l.set_ylim(0, 45)
    ax_l.set_xlabel("leakage factor a [Np/element]")
    ax_l.set_ylabel("gain [dBi]")
    ax_l.set_title("(a) gain, perfect alignment")
    el = np.radians(np.linspace(5.0, 90.0, 171))
    ax_e.plot(np.degrees(el), Metasurface(PEAK_DB, ROLLOFF).gain_db(el), label="Kymeta (leolink)")
    paper_db = PEAK_DB - ROLLOFF * 10.0 * np.log10(np.sin(el))
    ax_e.plot(np.degrees(el), paper_db, ":", label="Kymeta, paper's printed sign")
    ax_e.axhline(upa_db, color="tab:green", label="UPA")
    ax_e.set_xlabel("elevation [deg]")
    ax_e.set_title("(a) metasurface vs elevation")
    for ax in (ax_l, ax_e):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    lw = LeakyWave(N_UT, N_UT, LEAKAGE)
    numbers.update(
        {
            "upa_gain_db": upa_db,
            "paper_upa_gain_db": 27.6,
            "upa_gain_closed_form_db": 10.0 * np.log10(N_UT**2 + 1.0 / RICIAN_K),
            f"leaky_wave_gain_db_at_a_{LEAKAGE}": float(lw.gain_db(np.pi / 2)),
            f"leaky_wave_gain_db_at_a_{LEAKAGE}_explicit_weights": explicit_leaky_gain_db(
                N_UT, LEAKAGE
            ),
            f"leaky_wave_threshold_db_at_a_{LEAKAGE}": 20.0 * np.log10(1 / np.tanh(LEAKAGE / 2)),
            "metasurface_db_at_el_30_leolink": float(Metasurface().gain_db(np.radians(30.0))),
            "metasurface_db_at_el_30_paper_formula": PEAK_DB
            - ROLLOFF * 10 * np.log10(np.sin(np.radians(30.0))),
        }
    )


def _first_below(err_deg, gain_db, level_db):
    below = np.flatnonzero(gain_db < level_db)
    return float(err_deg[below[0]]) if below.size else None


def panel_b(ax, n_trials, step_deg, numbers):
    rng = np.random.default_rng(SEED)
    err = np.arange(0.0, 10.0 + 1e-9, step_deg)
    for term, name, colour in (
        (UPATerminal(N_UT, N_UT, RICIAN_K), "UPA", "tab:green"),
        (LeakyWave(N_UT, N_UT, LEAKAGE), "leaky wave", "tab:blue"),
    ):
        s = misalignment_gain_db(term, err, n_trials, rng, distribution="uniform")
        ax.plot(err, s.mean_db, color=colour, label=f"{name}: mean")
        ax.plot(err, s.min_db, "--", color=colour, label=f"{name}: minimum")
        key = name.replace(" ", "_")
        numbers[f"{key}_misalignment_mean_db_at_10_deg"] = float(s.mean_db[-1])
        numbers[f"{key}_min_10db_below_peak_from_deg"] = _first_below(
            err, s.min_db, s.min_db[0] - 10.0
        )
    null_deg = float(np.degrees(np.arcsin(2.0 / N_UT)))
    ax.axvline(null_deg, color="grey", linestyle=":", label=f"first null {null_deg:.2f} deg")
    ax.axvline(4.0, color="tab:red", linestyle=":", label="paper: critical > 4 deg")
    numbers["upa_first_null_deg"] = null_deg
    ax.set_xlabel("max pointing error e [deg] (uniform in [0, e])")
    ax.set_ylabel("gain [dBi]")
    ax.set_title("(b) gain under misalignment")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)


def panel_c(ax, n_trials, numbers):
    bits = np.arange(1, 9)
    analog, hybrid = quantization_loss_db(N_UT, N_UT, bits, n_trials, np.random.default_rng(SEED))
    theory = -20.0 * np.log10(np.sinc(1.0 / 2.0**bits))  # np.sinc(x) = sin(pi x)/(pi x)
    ax.semilogy(bits, analog, "o-", label="analog")
    ax.semilogy(bits, hybrid, "s-", label="hybrid (2 RF chains)")
    ax.semilogy(bits, theory, "k:", label="analog theory -20 log sinc(pi/2^b)")
    ax.set_xlabel("phase-shifter bits b")
    ax.set_ylabel("mean gain loss [dB]")
    ax.set_title("(c) gain loss under phase quantization")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    numbers.update(
        {
            "quantization_bits": bits,
            "analog_loss_db": analog,
            "hybrid_loss_db": hybrid,
            "analog_loss_theory_db": theory,
            "hybrid_better_than_analog_all_bits": bool(np.all(hybrid < analog)),
        }
    )


def main(argv=None):
    args = parse_args(argv, __doc__)
    numbers = {}
    fig, axes = figure(1, 4, figsize=(17.0, 4.2))
    panel_a(axes[0, 0], axes[0, 1], numbers)
    fast = args.fast
    panel_b(axes[0, 2], 400 if fast else 4000, 0.5 if fast else 0.1, numbers)
    panel_c(axes[0, 3], 60 if fast else 600, numbers)
    pngs = [save(fig, args.out, "fig6_terminal_gains.png")]
    report(args.out, "fig6_terminal_gains", numbers, pngs)
    return numbers


if __name__ == "__main__":
    sys.exit(0 if main() is not None else 1)
