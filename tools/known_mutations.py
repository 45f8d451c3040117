"""Re-check that the suite catches the mutations a review once found it blind to.

    python tools/known_mutations.py [--full] [--only NAME ...] [--list]

Each mutation is one source edit (issue 16: a single changed line that passed every
test). For each, the working tree's ``src``, ``tests``, ``configs``, ``examples``,
``docs`` and ``pyproject.toml`` are copied to a temporary folder, the edit is applied
there (it must match exactly once), and the tests that should see it are run with that
copy first on ``PYTHONPATH``. A mutation is *killed* when pytest fails; the script prints
the failing tests. ``--full`` runs the whole suite per mutation instead (slow: ~2 min
each). Exit status 1 when a mutation survives or an edit no longer applies.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COPIED = (
    "src",
    "tests",
    "configs",
    "examples",
    "docs",
    "analysis",
    "pyproject.toml",
    "README.md",
)


@dataclass(frozen=True)
class Mutation:
    name: str
    path: str
    old: str
    new: str
    tests: tuple[str, ...]


MUTATIONS = (
    Mutation(
        "rician_not_normalized",
        "src/leolink/sim/monitor.py",
        "rician_gain_from_draws_lin(n_lin, k, g) / mean_rician_gain_lin(n_lin, k)",
        "rician_gain_from_draws_lin(n_lin, k, g)",
        ("tests/test_fading_in_run.py",),
    ),
    Mutation(
        "non_gaussian_draws",  # same mean power E|g|^2 = 1, but |g|^2 uniform, not Exp(1)
        "src/leolink/rng.py",
        "radius = np.sqrt(-np.log(u1))",
        "radius = np.sqrt(2.0 * u1)",
        ("tests/test_rng.py", "tests/test_fading_in_run.py"),
    ),
    Mutation(
        "visibility_cone_halved",
        "src/leolink/sim/candidates/tiles.py",
        "cos_cap = np.cos(np.minimum(spread + reach + CAP_MARGIN_RAD, np.pi))",
        "cos_cap = np.cos(np.minimum(spread + reach / 2 + CAP_MARGIN_RAD, np.pi))",
        ("tests/test_candidates.py", "tests/test_tiles.py", "tests/test_trace_independent.py"),
    ),
    Mutation(
        "cap_without_the_ellipsoids_tilt",
        "src/leolink/sim/candidates/tiles.py",
        "reach = earth_central_angle_rad(min_elevation_rad - tilt, ",
        "reach = earth_central_angle_rad(min_elevation_rad, ",
        ("tests/test_tiles.py",),
    ),
    Mutation(
        "along_against_swapped",
        "src/leolink/sim/mobility/populations.py",
        '{"along_track": 0.0, "against_track": math.pi,',
        '{"along_track": math.pi, "against_track": 0.0,',
        ("tests/test_populations.py", "tests/test_trace_independent.py"),
    ),
    Mutation(
        "cross_track_flipped",
        "src/leolink/sim/mobility/populations.py",
        '"cross_track": math.pi / 2}',
        '"cross_track": -math.pi / 2}',
        ("tests/test_populations.py", "tests/test_trace_independent.py"),
    ),
    Mutation(
        "interruption_from_wrong_code",
        "src/leolink/io/summary/accumulator.py",
        'gap = columns.get("interruption_s")',
        'gap = columns.get("interruption")',
        ("tests/test_summary_of_a_run.py", "tests/test_diagnostics.py", "tests/test_recorder.py"),
    ),
    Mutation(
        "lat_lon_swapped",
        "src/leolink/sim/monitor.py",
        "lat_deg=np.degrees(mb.ut_lat_rad[j]).reshape(-1),\n"
        "            lon_deg=np.degrees(mb.ut_lon_rad[j]).reshape(-1),",
        "lat_deg=np.degrees(mb.ut_lon_rad[j]).reshape(-1),\n"
        "            lon_deg=np.degrees(mb.ut_lat_rad[j]).reshape(-1),",
        ("tests/test_trace_independent.py",),
    ),
    Mutation(
        "doppler_rate_sign",
        "src/leolink/kinematics.py",
        "return -k * v_sat, k * v_ut, -k * rho_dot, -k * rho_ddot, rho_dot, angular",
        "return -k * v_sat, k * v_ut, -k * rho_dot, k * rho_ddot, rho_dot, angular",
        ("tests/test_trace_independent.py", "tests/test_kinematics.py"),
    ),
    Mutation(
        "fspl_at_twice_the_frequency",
        "src/leolink/engine/__init__.py",
        '"fspl_db": fspl_db(rho, self.params.freq_hz) * nan,',
        '"fspl_db": fspl_db(rho, 2 * self.params.freq_hz) * nan,',
        ("tests/test_trace_independent.py",),
    ),
    Mutation(
        "angular_speed_in_rad_s",
        "src/leolink/engine/__init__.py",
        '"angular_speed_deg_s": np.degrees(kin["angular_speed_rad_s"]) * nan,',
        '"angular_speed_deg_s": kin["angular_speed_rad_s"] * nan,',
        ("tests/test_trace_independent.py",),
    ),
    Mutation(
        "doppler_sat_ut_swapped",
        "src/leolink/engine/__init__.py",
        '"doppler_sat_hz": kin["doppler_sat_hz"] * nan,\n'
        '                "doppler_ut_hz": kin["doppler_ut_hz"] * nan,',
        '"doppler_sat_hz": kin["doppler_ut_hz"] * nan,\n'
        '                "doppler_ut_hz": kin["doppler_sat_hz"] * nan,',
        ("tests/test_trace_independent.py",),
    ),
    Mutation(
        "best_beam_loop_takes_the_minimum",  # the compiled loop (numba) of Links.best_beam
        "src/leolink/engine/links.py",
        "if v > best_db[p] or np.isnan(v):",
        "if v < best_db[p] or np.isnan(v):",
        ("tests/test_links_contracts.py",),
    ),
    Mutation(
        "dirichlet_loop_off_by_one_beam",  # the compiled loops' kernels of a direction
        "src/leolink/antenna/array.py",
        "g, near = subtracted_gain(trig, coef[:, j], n)",
        "g, near = subtracted_gain(trig, coef[:, j - 1], n)",
        ("tests/test_array_kernels.py",),
    ),
    Mutation(
        "kernel_screens_every_ut_against_its_caps_first_satellite",
        "src/leolink/engine/screening.py",
        "d, rho2, _, se = _pair_link(frames, u, j)",
        "d, rho2, _, se = _pair_link(frames, u, cap_start[group[u]])",
        ("tests/test_tiles.py",),
    ),
    Mutation(
        "screening_bound_without_grating_lobes",
        "src/leolink/engine/screening.py",
        "d = np.minimum(d, 2.0 - np.maximum(u - beam_u[0], beam_u[-1] - u))",
        "d = d",
        ("tests/test_search.py",),
    ),
    Mutation(
        "dwell_histogram_reads_a_missing_key",
        "src/leolink/io/plots.py",
        'complete = summary["overall"]["dwell"]["complete_s"]',
        'complete = summary["overall"]["dwell"].get("dwell_times_s", [])',
        ("tests/test_plots.py",),
    ),
    # Issue 12 (handover triggers, RLF): each killed when it was added.
    Mutation(
        "trigger_filter_on_undetected_cells",
        "src/leolink/sim/handover/trigger_run.py",
        "filt, meas = l3_update(filt, t_s, sample, self.l3)",
        "filt, meas = l3_update(filt, t_s, axis.values(table), self.l3)\n"
        "            meas = np.where(usable, meas, np.nan)",
        ("tests/test_trigger_run.py",),
    ),
    Mutation(
        "search_floor_3_db_high",
        "src/leolink/sim/candidates/search.py",
        "return np.minimum(np.maximum(reach * factor, floor_lin), reach)",
        "return np.minimum(np.maximum(reach * factor, floor_lin * 2.0), reach)",
        ("tests/test_search.py",),
    ),
    Mutation(
        "rlf_leaves_the_serving_cell",
        "src/leolink/sim/monitor.py",
        "state.controller, events, dwells = self.rlf.merge(",
        "_, events, dwells = self.rlf.merge(",
        ("tests/test_handover_wiring.py",),
    ),
)


#: Issue 15/16 (link figures, scan loss, panel orientation, the 3GPP budgets): each killed
#: by the tests named (checked when they were written).
MUTATIONS += (
    Mutation(
        "scan_exponent_halved",
        "src/leolink/antenna/terminal.py",
        "0.5 * np.pi - np.asarray(elevation_rad, float), panel.element_exponent\n",
        "0.5 * np.pi - np.asarray(elevation_rad, float), panel.element_exponent / 2\n",
        ("tests/test_terminal_scan_loss.py",),
    ),
    Mutation(
        "scan_angle_is_elevation",
        "src/leolink/antenna/terminal.py",
        "0.5 * np.pi - np.asarray(elevation_rad, float), panel.element_exponent\n",
        "np.asarray(elevation_rad, float), panel.element_exponent\n",
        ("tests/test_terminal_scan_loss.py",),
    ),
    Mutation(
        "element_on_diffuse_too",
        "src/leolink/antenna/terminal.py",
        "return los + 1.0 / self.rician_k\n\n"
        '    def pattern_lin(self, du_x, du_y):\n        """Linear gain towards a direction '
        "``(du_x, du_y)`` off the beam, in",
        "return (los + 1.0 / self.rician_k) * _element_lin(self, elevation_rad)\n\n"
        '    def pattern_lin(self, du_x, du_y):\n        """Linear gain towards a direction '
        "``(du_x, du_y)`` off the beam, in",
        ("tests/test_terminal_scan_loss.py",),
    ),
    Mutation(
        "tilt_away_from_x",
        "src/leolink/antenna/panel.py",
        "n = np.sin(tilt) * h + np.cos(tilt) * up",
        "n = -np.sin(tilt) * h + np.cos(tilt) * up",
        ("tests/test_terminal_scan_loss.py",),
    ),
    Mutation(
        "motion_heading_swapped",
        "src/leolink/antenna/panel.py",
        "np.arctan2(east, north), fallback_rad",
        "np.arctan2(north, east), fallback_rad",
        ("tests/test_terminal_scan_loss.py",),
    ),
    Mutation(
        "esn0_without_rolloff",
        "src/leolink/link/acm.py",
        "esn0 = ratio_db + 10.0 * np.log10(1.0 + p.rolloff)",
        "esn0 = ratio_db",
        ("tests/test_link_figures_in_run.py",),
    ),
    Mutation(
        "margin_sign",
        "src/leolink/link/acm.py",
        '"margin_db": esn0 - p.threshold_db',
        '"margin_db": p.threshold_db - esn0',
        ("tests/test_link_figures_in_run.py",),
    ),
    Mutation(
        "cn0_bandwidth_twice",
        "src/leolink/link/acm.py",
        '"cn0_dbhz": snr_db + 10.0 * np.log10(p.bandwidth_hz)',
        '"cn0_dbhz": snr_db + 10.0 * np.log10(2 * p.bandwidth_hz)',
        ("tests/test_link_figures_in_run.py",),
    ),
    Mutation(
        "modcod_ignores_margin",
        "src/leolink/link/acm.py",
        "return ratio_db, esn0, select_modcod(esn0, p.implementation_margin_db)",
        "return ratio_db, esn0, select_modcod(esn0, 0.0)",
        ("tests/test_link_figures_in_run.py",),
    ),
    Mutation(
        "modcod_strict_threshold",
        "src/leolink/link/modcod.py",
        'x, side="right") - 1',
        'x, side="left") - 1',
        ("tests/test_link_figures_in_run.py",),
    ),
    Mutation(
        "acm_not_scaled_in_handover",
        "src/leolink/link/acm.py",
        "eta * p.symbol_rate_baud * served_fraction",
        "eta * p.symbol_rate_baud",
        ("tests/test_link_figures_in_run.py",),
    ),
    Mutation(
        "sinr_service_ignored",
        "src/leolink/sim/service_link.py",
        '        elif self.metric == "sinr":',
        '        elif self.metric == "never":',
        ("tests/test_link_figures_in_run.py",),
    ),
    Mutation(
        "budget_other_losses_dropped",
        "src/leolink/link/budget.py",
        "atm_db + other_loss_db, loss_fs_db",
        "atm_db, loss_fs_db",
        ("tests/test_3gpp_budgets.py",),
    ),
    Mutation(
        "noise_figure_at_antenna_temp",
        "src/leolink/link/figures.py",
        "return np.asarray(antenna_temp_k, dtype=float) + reference_temp_k * (f_lin - 1.0)",
        "return np.asarray(antenna_temp_k, dtype=float) * f_lin",
        ("tests/test_3gpp_budgets.py",),
    ),
    Mutation(
        "density_without_peak_gain",
        "src/leolink/app/scenario.py",
        "return eirp - peak_gain_dbi + link.cable_loss_db",
        "return eirp + link.cable_loss_db",
        ("tests/test_3gpp_budgets.py",),
    ),
    Mutation(
        "aperture_radius_for_diameter_unused_gain",
        "src/leolink/app/reports.py",
        '"gain_tx_db": gain_tx,',
        '"gain_tx_db": gain_tx - 0.2,',
        ("tests/test_3gpp_budgets.py",),
    ),
    Mutation(
        "engine_other_loss_ignored",
        "src/leolink/engine/__init__.py",
        "k_db = params.ptx_dbw - params.cable_loss_db - params.other_loss_db - self.noise_dbw",
        "k_db = params.ptx_dbw - params.cable_loss_db - self.noise_dbw",
        ("tests/test_3gpp_budgets.py", "tests/test_link_figures_in_run.py"),
    ),
    Mutation(
        "panel_normal_ignored_in_engine",
        "src/leolink/engine/__init__.py",
        "rx_db = rows_gain_db(self.terminal, el_rx, rows, self._rx_groups)",
        "rx_db = rows_gain_db(self.terminal, elevation, rows, self._rx_groups)",
        ("tests/test_terminal_scan_loss.py",),
    ),
    Mutation(
        "screening_ignores_panel_normal",
        "src/leolink/engine/screening.py",
        "    if ut_normal is not None:  # the gain sees",
        "    if ut_normal is None:  # the gain sees",
        ("tests/test_search.py",),
    ),
)


def _copy_tree(dest: Path) -> None:
    for name in COPIED:
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, dest / name, ignore=shutil.ignore_patterns("__pycache__"))
        elif src.exists():
            shutil.copy2(src, dest / name)


def _apply(tree: Path, m: Mutation) -> None:
    path = tree / m.path
    text = path.read_text()
    if text.count(m.old) != 1:
        raise SystemExit(f"{m.name}: the edit matches {text.count(m.old)} times in {m.path}")
    path.write_text(text.replace(m.old, m.new))


def check(m: Mutation, full: bool) -> tuple[bool, list[str]]:
    """Apply ``m`` in a temporary copy and run its tests: (killed, failing test ids)."""
    with tempfile.TemporaryDirectory(prefix=f"mut-{m.name}-") as tmp:
        tree = Path(tmp)
        _copy_tree(tree)
        _apply(tree, m)
        env = dict(os.environ, PYTHONPATH=str(tree / "src"), PYTHONDONTWRITEBYTECODE="1")
        env.pop("MPLBACKEND", None)
        args = [sys.executable, "-m", "pytest", "-q", "-rf", "-p", "no:cacheprovider", "-x"]
        if not full:
            args += list(m.tests)
        proc = subprocess.run(args, cwd=tree, env=env, capture_output=True, text=True)
        failed = re.findall(r"^FAILED (\S+)", proc.stdout, flags=re.M)
        return proc.returncode != 0, failed


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="run the whole suite per mutation")
    ap.add_argument("--only", nargs="*", default=None, help="names of mutations to check")
    ap.add_argument("--list", action="store_true", help="list the mutations and exit")
    args = ap.parse_args(argv)
    chosen = [m for m in MUTATIONS if not args.only or m.name in args.only]
    if args.list:
        for m in chosen:
            print(f"{m.name:38s} {m.path}")
        return 0
    survived = 0
    for m in chosen:
        killed, failed = check(m, args.full)
        survived += not killed
        verdict = "killed by " + (failed[0] if failed else "an error") if killed else "SURVIVED"
        print(f"{m.name:38s} {verdict}", flush=True)
    print(f"{len(chosen) - survived} of {len(chosen)} mutations killed")
    return 1 if survived else 0


if __name__ == "__main__":
    raise SystemExit(main())
