"""Mutation scores of the physics and simulator modules, one module at a time (mutmut 3).

    python tools/mutation_scores.py [MODULE ...] [--keep DIR] [--children N] [--root TREE]
    python tools/mutation_scores.py MODULE ... --keep DIR --again   # survivors only
    python tools/mutation_scores.py --compiled [MODULE ...] [--keep DIR]  # the numba loops
    python tools/mutation_scores.py --jitable [MODULE ...] [--keep DIR]   # their physics
    python tools/mutation_scores.py MODULE --functions F,G  # only these functions' mutants

For each module (default: all of :data:`MODULES`) the working tree is copied to a
scratch folder, ``[tool.mutmut]`` there is set to mutate only that module and to select
only the fast tests that cover it (:data:`MODULES`), and ``mutmut run`` is started; the
killed / survived / timeout counts of ``mutmut export-cicd-stats`` are printed as one
Markdown table row per module (docs/testing.md keeps the table). Mutants that no
selected test reaches count as survivors ("no tests"). Slow (minutes per module on two
cores): not part of .ci/run. ``--keep DIR`` keeps the scratch folders, so that
``cd DIR/<module> && mutmut browse`` (or ``mutmut show NAME``) lists the survivors.

``--compiled`` scores the compiled loops instead (:data:`COMPILED`: the functions decorated
``@compiled.jit``, which the runs above never execute, as they set ``LEOLINK_JIT=0``). mutmut
skips every decorated function, so the scratch copy of the module loses the loops'
``@compiled.jit`` lines; the run sets ``LEOLINK_JIT=1`` (callers take the loops) and
``NUMBA_DISABLE_JIT=1`` (numba's ``njit`` gives the Python function: what the decorator
would give, so the loops' source runs as Python, through mutmut's trampolines), and only
the loops' mutants are run and counted.

``--jitable`` scores the physics functions the loops call (:data:`JITABLE`: those decorated
``@compiled.jitable``, which no run above mutates, being decorated). ``jitable`` returns the
function itself, so the scratch copy loses those decorator lines and nothing else changes;
the run is the numpy path (``LEOLINK_JIT=0``: the numpy callers call the same functions on
arrays), and only those functions' mutants are run and counted.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MUTMUT = [sys.executable, "-m", "mutmut"]

ENGINE_TESTS = ["tests/test_engine.py", "tests/test_search.py", "tests/test_trace_independent.py"]
SIM_RUN_TESTS = [
    "tests/test_simulation.py",
    "tests/test_summary_of_a_run.py",
    "tests/test_trace_independent.py",
]
#: The block frames (sim/streams.py BlockFrame, deliver; the monitor's flush): every output
#: file of three runs by block and by epoch, and the frames against what they mean.
BLOCK_TESTS = ["tests/test_block_frames.py", "tests/test_block_frame_contracts.py"]
_COMPILED_IDS = (
    "test_end_of_service_equals_a_brute_force_scan_every_epoch",
    "test_satellite_ends_alone_stay_exact_without_per_cell_look_ahead",
    "test_t1_hands_over_lead_s_before_the_serving_satellite_stops_serving",
)
TRIGGER_RUN_WIRING = [
    "tests/test_handover_wiring.py::test_d1_references_are_the_beams_ground_centres",
    "tests/test_handover_wiring.py::test_a_negative_cell_offset_keeps_the_trigger_policies_"
    "off_that_satellite",
]
TRIGGER_RUN_DESELECT = [
    *(f"--deselect=tests/test_service_time.py::{name}[compiled]" for name in _COMPILED_IDS),
    "--deselect=tests/test_measurement_model.py::test_defaults_are_todays_run_and_rsrp_shifts_"
    "thresholds_by_the_re_noise",
    "--deselect=tests/test_measurement_model.py::test_a_satellite_whose_smtc_window_misses_"
    "every_instant_is_never_a_target",
]
#: module -> the fast tests that exercise it (the whole suite would cost ~2 min per mutant
#: batch; these run in seconds).
MODULES = {
    # The engine package, file by file; its compiled loops (numba) are scored by --compiled
    # (COMPILED): every run here sets LEOLINK_JIT=0, so the numpy
    # reference path is what is measured.
    # serve_pairs' paths that the engine files above never take: active beams' lit
    # beams, tilted panels and a given ENU, fading, other satellites' interference.
    "engine/__init__": [
        *ENGINE_TESTS,
        "tests/test_engine_contracts.py",
        "tests/test_active_beams.py",
        "tests/test_terminal_scan_loss.py",
        "tests/test_fading_in_run.py",
        "tests/test_link_figures_in_run.py",
    ],
    "engine/links": [*ENGINE_TESTS, "tests/test_links_contracts.py"],
    # The re-steered beams' bound (sat_id), which the engine files above never take.
    "engine/screening": [
        *ENGINE_TESTS,
        "tests/test_steering.py::test_screening_bound_holds_for_re_steered_beams",
    ],
    "kinematics": ["tests/test_kinematics.py", "tests/test_trace_independent.py"],
    "geometry": [
        "tests/test_geometry.py",
        "tests/test_mobility.py",
        "tests/test_trace_independent.py",
    ],
    "orbit": [
        "tests/test_orbit.py",
        "tests/test_orbit_contracts.py",
        "tests/test_validation.py",
        "tests/test_trace_independent.py",
    ],
    "antenna/array": [
        "tests/test_array.py",
        "tests/test_array_contracts.py",
        "tests/test_array_kernels.py",
        "tests/test_trace_independent.py",
    ],
    "antenna/codebook": ["tests/test_codebook.py", "tests/test_trace_independent.py"],
    "antenna/codebook_design": ["tests/test_codebook_design.py"],
    "antenna/aperture": ["tests/test_aperture.py", "tests/test_link_figures.py"],
    "antenna/element": [
        "tests/test_element.py",
        "tests/test_panel_contracts.py",
        "tests/test_terminal_scan_loss.py",
    ],
    "antenna/footprint": ["tests/test_footprint.py"],
    "antenna/impairments": ["tests/test_impairments.py"],
    "antenna/panel": [
        "tests/test_panel_contracts.py",
        "tests/test_terminal.py",
        "tests/test_terminal_scan_loss.py",
    ],
    "antenna/response": ["tests/test_response.py", "tests/test_precoder.py"],
    "antenna/terminal": [
        "tests/test_terminal.py",
        "tests/test_terminal_contracts.py",
        "tests/test_terminal_scan_loss.py",
        "tests/test_impairments.py",
        "tests/test_trace_independent.py",
    ],
    "link/budget": ["tests/test_budget.py", "tests/test_trace_independent.py"],
    "link/fading": ["tests/test_fading.py", "tests/test_fading_in_run.py"],
    # the environments' channel state (issue 45: environments) and the trigger run's look-ahead
    "link/channel_state": ["tests/test_channel_state.py", "tests/test_environment_tracker.py"],
    "sim/handover/service_time": ["tests/test_service_time.py", "tests/test_trigger_run.py"],
    # The percentile histograms (the summary's statistics and the KPIs' dwell percentiles):
    # by hand (test_histograms.py, test_kpi.py) and through the summary's parts.
    "sim/histograms": [
        "tests/test_histograms.py",
        "tests/test_kpi.py",
        "tests/test_summary_stats.py",
        "tests/test_summary_parts.py",
    ],
    "rng": ["tests/test_rng.py", "tests/test_fading_in_run.py"],
    # The controller's own tests (hand-built sequences, the scalar reference of
    # test_controller_contracts.py) and the run tests (resumed events, interruptions, the
    # dwells' and events' columns through the sinks); the 45 s chunk-size check adds no
    # path of its own.
    "sim/controller": [
        "tests/test_controller.py",
        "tests/test_controller_contracts.py",
        "tests/test_simulation.py",
        "--deselect=tests/test_simulation.py::test_same_seed_same_trace_whatever_the_chunk_size",
    ],
    # The step's event and dwell tables (moved out of sim/handover/controller.py on 2026-12-02).
    "sim/event_tables": [
        "tests/test_controller.py",
        "tests/test_controller_contracts.py",
    ],
    # The recording of a run (the former sim/recorder.py): trace frames and the deferred
    # recording (sim/monitor.py), the policy step per epoch (sim/decide.py).
    # Every path of the monitor: RLF per epoch (test_handover_wiring), links on the true
    # states (test_ephemeris_error), fading, environments (blocked outages), active beams
    # and beam sharing, other satellites and the SINR service threshold, the warm-up's
    # censored dwells. The slowest checks that add no path of their own are left out.
    "sim/monitor": [
        *SIM_RUN_TESTS,
        "tests/test_handover_wiring.py",
        "tests/test_ephemeris_error.py",
        "tests/test_fading_in_run.py",
        "tests/test_environment_in_run.py",
        "tests/test_active_beams.py",
        "tests/test_link_figures_in_run.py",
        "tests/test_monitor_contracts.py",
        *BLOCK_TESTS,
        "tests/test_cli.py::test_warmup_epochs_are_not_recorded_and_cut_dwells_are_censored",
        "--deselect=tests/test_simulation.py::test_same_seed_same_trace_whatever_the_chunk_size",
        "--deselect=tests/test_handover_wiring.py::test_kpis_equal_the_trace_and_events_recomputed",
        "--deselect=tests/test_environment_in_run.py::test_scintillation_twice_is_refused",
    ],
    "sim/streams": [*BLOCK_TESTS, "tests/test_simulation.py"],
    "sim/decide": [*SIM_RUN_TESTS, "tests/test_environment_floor.py"],
    "sim/processes": [
        "tests/test_candidates.py",
        "tests/test_simulation.py",
        "tests/test_trace_independent.py",
        "tests/test_fading_in_run.py",
    ],
    "sim/populations": ["tests/test_populations.py", "tests/test_trace_independent.py"],
    "io/tables": [
        "tests/test_recorder.py",
        "tests/test_tables_contracts.py",
        "tests/test_simulation.py",
    ],
    # The summary package (the former io/summary.py), file by file: the parts by hand
    # (test_summary_parts.py), then the runs' summaries that reach them.
    # (the runs of test_summary_of_a_run.py and test_recorder.py, 10-30 s a mutant, reach
    # the same paths as the two epochs-by-hand files)
    "io/summary/accumulator": [
        "tests/test_summary_accumulator.py",
        "tests/test_summary_parts.py",
    ],
    "io/summary/stats": [
        "tests/test_summary_stats.py",
        "tests/test_summary_parts.py",
        "tests/test_summary_of_a_run.py",
    ],
    "io/summary/records": [
        "tests/test_summary_parts.py",
        "tests/test_recorder.py",
        "tests/test_summary_of_a_run.py",
    ],
    "io/summary/environment": ["tests/test_summary_parts.py"],
    "io/summary/bands": ["tests/test_summary_parts.py", "tests/test_geography_outputs.py"],
    "io/summary/link": ["tests/test_summary_parts.py", "tests/test_block_frame_contracts.py"],
    "io/summary/kpi": ["tests/test_summary_parts.py"],
    # Issue 45: the physics modules added or changed in the round before it.
    "geodesy": ["tests/test_geodesy.py", "tests/test_visibility.py"],
    "ephemeris_error": ["tests/test_ephemeris_error.py", "tests/test_ephemeris_error_params.py"],
    "link/precoder": [
        "tests/test_precoder.py",
        "tests/test_precoder_params.py",
        "tests/test_active_beams.py",
    ],
    "link/figures": ["tests/test_figures.py", "tests/test_link_figures.py"],
    "antenna/steering": ["tests/test_steering.py", "tests/test_engine_contracts.py"],
    # The handover modules of issue 45's list: the trigger conditions (3GPP and NTN), RLF,
    # the KPIs; then the beam scheduler and the environments.
    # The sparse-vs-dense check of test_trigger_run.py (8-16 s a mutant) compares two
    # callers of the same conditions: it adds no path of triggers.py.
    "sim/handover/triggers": [
        "tests/test_triggers.py",
        "tests/test_triggers_contracts.py",
        "tests/test_trigger_run.py",
        "tests/test_handover.py",
        "tests/test_handover_config.py",
        "--deselect=tests/test_trigger_run.py::test_sparse_tables_choose_exactly_as_the_dense_axis",
    ],
    "sim/handover/triggers_ntn": [
        "tests/test_triggers.py",
        "tests/test_triggers_contracts.py",
        "tests/test_handover.py",
        "tests/test_service_time.py",
    ],
    "sim/handover/rlf": ["tests/test_rlf.py", "tests/test_handover_wiring.py"],
    # test_procedure.py reaches the MRO classes through whole runs (minutes per mutant
    # under load); test_kpi.py has them by hand.
    "sim/handover/kpi": ["tests/test_kpi.py"],
    "sim/beams/scheduler": ["tests/test_scheduler.py", "tests/test_active_beams.py"],
    # The selectors, the hopping cycle and the chains by hand (test_beams.py), in a run
    # (test_active_beams.py).
    "sim/beams/active": [
        "tests/test_beams.py",
        "tests/test_beams_by_hand.py",
        "tests/test_active_beams.py",
    ],
    # (the compiled-vs-numpy check needs numba's loops, which LEOLINK_JIT=0 turns off)
    "sim/environment": [
        "tests/test_environment_tracker.py",
        "tests/test_environment_in_run.py",
        "--deselect=tests/test_environment_in_run.py::test_compiled_loops_and_numpy_agree_"
        "with_environments",
    ],
    # The trigger policies' run state (sparse tables onto the local axis, the epoch's
    # fields, the target): the sparse-vs-dense check, the hand-placed geometries, the
    # numpy ids of the compiled/numpy pairs (LEOLINK_JIT=0), two runs of the wiring. The
    # whole runs (test_trigger_floor.py, the other wiring and measurement-model runs: 2-40
    # s a mutant) reach the same paths through the simulator.
    "sim/handover/trigger_run": [
        "tests/test_trigger_run.py",
        "tests/test_trigger_run_geometry.py",
        "tests/test_service_time.py",
        "tests/test_measurement_model.py",
        *TRIGGER_RUN_WIRING,
        *TRIGGER_RUN_DESELECT,
    ],
    # The local axes of the trigger run (union's keys and puts, values, remap): the
    # axis by hand against scans (test_trigger_run.py) and the run state's geometries.
    "sim/handover/local_axis": [
        "tests/test_trigger_run.py",
        "tests/test_trigger_run_geometry.py",
        *TRIGGER_RUN_WIRING,
    ],
    "sim/handover/trigger_policies": [
        "tests/test_handover_config.py",
        "tests/test_trigger_run_geometry.py",
        "tests/test_trigger_policies_entry.py",
        *TRIGGER_RUN_WIRING,
        "tests/test_measurement_model.py::test_defaults_are_todays_run_and_rsrp_shifts_"
        "thresholds_by_the_re_noise",
    ],
    # The TR 38.811 tables and formulas, by hand and against the tables (the in-run tests
    # reach them through whole runs, minutes per mutant).
    "link/environment": ["tests/test_environment.py"],
    # The numba switch itself: the splits by hand (test_compiled.py), the environment's
    # words and refusals (test_bad_inputs.py's, refused before any run).
    "compiled": [
        "tests/test_compiled.py",
        "tests/test_bad_inputs.py::test_validate_and_run_refuse_a_bad_environment_alike",
        "tests/test_bad_inputs.py::test_threads_are_capped_at_the_cpus",
        "tests/test_bad_inputs.py::test_jit_words",
    ],
}
#: Issue 45: module -> (its compiled loops, the fast tests that run them with an
#: independent expectation: the numpy path, hand-placed geometry or a brute-force scan).
#: Every test runs the loops (LEOLINK_JIT=1), as plain Python (NUMBA_DISABLE_JIT=1): small
#: runs only.
COMPILED = {
    "sim/environment": (
        ("_advance_rows",),
        [
            "tests/test_environment_tracker.py",
            "tests/test_environment_in_run.py",
            # (60 s a mutant as Python: other satellites' paths, a path of its own)
            "--deselect=tests/test_environment_in_run.py::test_interfering_satellites_paths_"
            "keep_their_own_states",
        ],
    ),
    "engine/links": (
        ("_snr_rows", "_best_beam_rows", "_pair_rows"),
        [
            "tests/test_links_contracts.py",
            # numba's loops divide by zero silently, Python's warn (the test's point)
            "--deselect=tests/test_links_contracts.py::test_snr_in_db_of_a_null_kernel_is_"
            "minus_inf_without_a_warning",
        ],
    ),
    "link/environment": (
        ("_table_rows",),
        ["tests/test_environment.py::test_link_table_values_are_the_single_lookups_bit_for_bit"],
    ),
    "engine/screening": (
        ("_screen_rows", "_ragged_rows"),
        [
            "tests/test_links_contracts.py::test_compiled_screening_agrees_with_numpy",
            "tests/test_links_contracts.py::test_ragged_screening_is_the_dense_screening_of_"
            "each_pair",
        ],
    ),
    "sim/candidates/search": (
        ("_window_rows", "_link_window_rows"),
        [
            "tests/test_search.py::test_compiled_window_gives_the_numpy_windows_entries",
            "tests/test_search.py::test_window_from_kernels_gives_the_window_of_the_snr_matrix",
        ],
    ),
    "sim/candidates/table": (("_slot_rows", "_best_rows"), ["tests/test_candidate_table.py"]),
    # The controller's hand-built sequences and its scalar reference, both paths.
    "sim/handover/controller": (
        ("_rules_rows",),
        ["tests/test_controller.py", "tests/test_controller_contracts.py"],
    ),
    # The binary search against a scan of each row, and the mapping both ways.
    "sim/handover/local_axis": (
        ("_slot_rows",),
        [
            "tests/test_trigger_run.py::test_local_axis_finds_each_satellites_slot_as_a_scan_"
            "of_its_row",
            "tests/test_trigger_run.py::test_local_axis_maps_cells_both_ways_and_carries_"
            "values_by_satellite",
        ],
    ),
    "sim/mobility/models": (("_great_circle_rows",), ["tests/test_mobility.py"]),
    "sim/handover/service_time": (("_first_failures_loop",), ["tests/test_service_time.py"]),
    # The Dirichlet rows against the numpy product and the array factor's own properties.
    "antenna/array": (("_dirichlet_rows",), ["tests/test_array_kernels.py"]),
    "engine/__init__": (
        ("_serve_rows",),
        [
            "tests/test_links_contracts.py::test_compiled_serving_columns_agree_with_numpy",
            "tests/test_engine_contracts.py",
        ],
    ),
}
#: Issue 45: module -> (its ``@compiled.jitable`` physics functions, the fast tests that reach
#: them on the numpy path with an independent expectation). The functions that only the
#: compiled loops call (beam_snr_db, _pair_db, kernels_of_direction, _screen_pair) are
#: called directly, on scalars, by tests/test_jitable_physics.py.
JITABLE_TESTS = "tests/test_jitable_physics.py"
JITABLE = {
    "antenna/array": (
        ("ula_gain", "dirichlet_trig", "subtracted_gain", "kernels_of_direction"),
        [*MODULES["antenna/array"], JITABLE_TESTS],
    ),
    "link/budget": (
        ("fspl_db", "sinr_lin", "spectral_efficiency_bps_hz", "throughput_bps"),
        [*MODULES["link/budget"], JITABLE_TESTS],
    ),
    "kinematics": (("_dot", "_norm2_of_difference", "kinematics_terms"), MODULES["kinematics"]),
    # (the engine's azimuth column: test_links_contracts.py builds lines of sight at known
    # azimuths)
    "geometry": (
        ("azimuth_in_frame_deg", "azimuth_on_sphere_deg", "azimuth_of_deg"),
        [*MODULES["geometry"], "tests/test_links_contracts.py", JITABLE_TESTS],
    ),
    "link/channel_state": (
        (
            "pair_key",
            "pair_innovations",
            "ar1_step",
            "ar1_weights",
            "ar1_mix",
            "ray_offset_en_m",
            "ray_moved_m",
        ),
        ["tests/test_channel_state.py", "tests/test_environment_tracker.py", JITABLE_TESTS],
    ),
    "sim/environment": (
        ("look_angles_rad", "sine_of_elevation", "elevation_rad", "link_enu"),
        [*MODULES["sim/environment"], JITABLE_TESTS],
    ),
    "rng": (("mix64", "uniform_of", "complex_normal_of"), [*MODULES["rng"], JITABLE_TESTS]),
    "engine/screening": (
        ("_envelope", "_screen_pair", "_pair_link", "_pair_code", "_pair_bound"),
        [*MODULES["engine/screening"], JITABLE_TESTS],
    ),
    "engine/links": (("beam_snr_db", "_pair_db"), [JITABLE_TESTS]),
    "sim/handover/controller": (
        ("_rules",),
        ["tests/test_controller.py", "tests/test_controller_contracts.py"],
    ),
    "sim/mobility/models": (("great_circle_state",), ["tests/test_mobility.py", JITABLE_TESTS]),
}
#: Tests that assert the compiled loops run (``compiled.use``): left out of every mode but
#: ``--compiled`` (``LEOLINK_JIT=0``), where they fail whatever the mutant.
NEEDS_LOOPS = [
    "--deselect=tests/test_environment_tracker.py::test_compiled_loop_keeps_the_numpy_states_at_"
    "the_mask_and_in_empty_slots",
    "--deselect=tests/test_environment_tracker.py::test_compiled_loop_steps_each_field_with_its_"
    "own_correlation_distance",
    "--deselect=tests/test_links_contracts.py::test_a_pair_exactly_at_the_mask_is_visible",
    "--deselect=tests/test_links_contracts.py::test_ragged_screening_is_the_dense_screening_of_"
    "each_pair[True]",
]
#: Per mode: the table of module -> (functions, tests) whose functions alone are mutated,
#: and the decorator lines the scratch copy loses above them (mutmut skips a decorated
#: function). The default mode (the numpy path, :data:`MODULES`) mutates the whole file.
NAMED = {
    "compiled": (COMPILED, ("@compiled.jit", "@leolink.compiled.jit")),
    "jitable": (JITABLE, ("@compiled.jitable", "@leolink.compiled.jitable")),
}
COPIED = ("src", "tests", "configs", "examples", "docs", "tools", "analysis", "README.md")
#: Only the paper-pass scenario of tests/test_trace_independent.py per mutant (the three
#: others cost 3x more; their columns are the same code paths, with the Earth rotating).
FAST = "not walker_rotating and not tle_rotating and not moving_rotating"
#: The ``compiled`` case of the ``compiled_and_numpy`` fixture (tests/conftest.py) asserts that
#: the loops run: under ``LEOLINK_JIT=0`` (every mode but ``--compiled``) it is left out, as
#: its ``numpy`` case is that path ("[compiled]", "[compiled-...]", "[...-compiled]").
NOT_COMPILED_CASE = " and not [compiled and not compiled]"


def _patterns(module: str, mode: str, functions: tuple[str, ...] = ()) -> list[str]:
    """mutmut's names (fnmatch) of the mutants of ``module``'s functions named by ``mode``'s
    table (:data:`NAMED`), and of ``functions`` (functions or methods, by name: mutmut
    writes ``x_f`` and ``xǁClassǁf``)."""
    dotted = "leolink." + module.removesuffix("/__init__").replace("/", ".")
    named = NAMED[mode][0][module][0] if mode in NAMED else ()
    return [f"{dotted}.*x_{fn}__mutmut_*" for fn in named] + [
        f"{dotted}.{key}__mutmut_*" for fn in functions for key in (f"x_{fn}", f"xǁ*ǁ{fn}")
    ]


def _undecorate(path: Path, decorators: tuple[str, ...], functions: tuple[str, ...]) -> None:
    """Drop the decorator line (one of ``decorators``) above each of ``functions`` in
    ``path`` (mutmut leaves decorated functions alone). ``jitable`` returns the function,
    and under ``NUMBA_DISABLE_JIT=1`` so does ``jit``: nothing else changes."""
    lines = path.read_text().splitlines(keepends=True)
    kept = [
        line
        for i, line in enumerate(lines)
        if not (
            line.strip() in decorators
            and i + 1 < len(lines)
            and lines[i + 1].startswith(tuple(f"def {f}(" for f in functions))
        )
    ]
    if len(lines) - len(kept) != len(functions):
        raise SystemExit(f"{path}: expected {len(functions)} functions {functions} under "
                         f"{' or '.join(decorators)}")  # fmt: skip
    path.write_text("".join(kept))


def _tests(module: str, root: Path, mode: str) -> list[str]:
    """``module``'s tests that exist in ``root`` ("--..." items are pytest options)."""
    listed = NAMED[mode][0][module][1] if mode in NAMED else MODULES[module]
    return [t for t in listed
            if t.startswith("-") or (root / t.split("::")[0]).exists()]  # fmt: skip


def _env(mode: str) -> dict:
    # One run per test, not per module: mutmut credits each check (tests/scopes.py).
    env = dict(os.environ, LEOLINK_FIXTURE_SCOPE="function", LEOLINK_JIT="0")
    if mode == "compiled":  # the loops, as Python: what @compiled.jit gives without numba
        env.update(LEOLINK_JIT="1", NUMBA_DISABLE_JIT="1")
    return env


def _statuses(dest: Path, env: dict, pats: list[str]) -> dict[str, str]:
    """mutant name -> status (``killed``, ``survived``, ``no_tests``, ``not_checked``,
    ...) of the mutants of ``dest`` whose names match one of ``pats`` (``mutmut
    results``)."""
    listed = subprocess.run([*MUTMUT, "results", "--all", "true"], cwd=dest,
                            capture_output=True, text=True, env=env, check=True).stdout  # fmt: skip
    out = {}
    for line in listed.splitlines():
        name, _, status = line.strip().rpartition(": ")
        if any(fnmatch.fnmatch(name, p) for p in pats):
            out[name] = status.replace(" ", "_")
    return out


def _count(statuses: dict[str, str]) -> dict:
    s = {"total": len(statuses)}
    for status in statuses.values():
        s[status] = s.get(status, 0) + 1
    return s


def _named_stats(dest: Path, module: str, mode: str, env: dict) -> dict:
    """killed / survived / ... counts of the named functions' mutants only."""
    return _count(_statuses(dest, env, _patterns(module, mode)))


def _config(module: str, tests: list[str], mode: str) -> str:
    k, deselect = (FAST, []) if mode == "compiled" else (FAST + NOT_COMPILED_CASE, NEEDS_LOOPS)
    lines = [
        "[tool.mutmut]",
        'source_paths = ["src"]',
        f'only_mutate = ["src/leolink/{module}.py"]',
        f"pytest_add_cli_args_test_selection = {json.dumps([*tests, '-k', k, *deselect])}",
        'pytest_add_cli_args = ["-p", "no:cacheprovider"]',
        f"also_copy = {json.dumps([c for c in COPIED if c != 'src'])}",
        "mutate_only_covered_lines = false",
    ]
    return "\n".join(lines) + "\n"


def _prepare(dest: Path, module: str, root: Path = ROOT, mode: str = "numpy") -> None:
    dest.mkdir(parents=True)
    for name in COPIED:
        src = root / name
        if src.is_dir():
            shutil.copytree(src, dest / name, ignore=shutil.ignore_patterns("__pycache__"))
        elif src.exists():
            shutil.copy2(src, dest / name)
    text = (root / "pyproject.toml").read_text()
    head, sep, _ = text.partition("[tool.mutmut]")
    if sep:  # drop the repository's own section (it mutates every listed module at once)
        rest = _.split("\n[", 1)
        head = head + ("[" + rest[1] if len(rest) > 1 else "")
    # an older tree may lack some files
    tests = _tests(module, root, mode)
    if all(t.startswith("-") for t in tests):  # (no file: pytest would run the whole suite)
        raise SystemExit(f"{module}: none of its tests is in {root}")
    (dest / "pyproject.toml").write_text(head.rstrip() + "\n\n" + _config(module, tests, mode))
    if mode in NAMED:
        table, decorators = NAMED[mode]
        _undecorate(dest / "src" / "leolink" / f"{module}.py", decorators, table[module][0])


def score(module: str, workdir: Path, children: int, root: Path = ROOT,
          mode: str = "numpy", functions: tuple[str, ...] = ()) -> dict:  # fmt: skip
    dest = workdir / module.replace("/", "_")
    _prepare(dest, module, root, mode)
    # The whole file, on the numpy path (LEOLINK_JIT=0); --compiled and --jitable: only the
    # mutants of their functions; --functions: only (or also) those.
    env = _env(mode)
    names = _patterns(module, mode, functions) if mode in NAMED or functions else []
    subprocess.run([*MUTMUT, "run", "--max-children", str(children), *names], cwd=dest,
                   check=False, stdout=subprocess.DEVNULL, env=env)  # fmt: skip
    if names:
        return _count(_statuses(dest, env, names))
    return _stats(dest, module, env, mode)


def _stats(dest: Path, module: str, env: dict, mode: str) -> dict:
    """mutmut's counts of the folder ``dest``: the named functions' mutants only in the
    modes of :data:`NAMED`."""
    if mode in NAMED:
        return _named_stats(dest, module, mode, env)
    subprocess.run([*MUTMUT, "export-cicd-stats"], cwd=dest, check=True,
                   stdout=subprocess.DEVNULL)  # fmt: skip
    return json.loads((dest / "mutants" / "mutmut-cicd-stats.json").read_text())


def again(module: str, workdir: Path, children: int, root: Path = ROOT,
          mode: str = "numpy", functions: tuple[str, ...] = ()) -> dict:  # fmt: skip
    """Re-run the mutants of a kept folder (``--keep``) that its run did not kill
    (survived, no tests, not checked) with ``root``'s tests now.

    Tests are only added between the runs, so a killed mutant stays killed; mutmut
    re-collects which tests reach each function, so the new tests take part. The counts
    are the statuses read before the re-run, those of the re-run mutants replaced (mutmut
    resets every verdict when the test selection changes, so the statuses after it would
    show the mutants killed before as not checked)."""
    dest = workdir / module.replace("/", "_")
    for tests in (dest / "tests", dest / "mutants" / "tests"):
        shutil.rmtree(tests, ignore_errors=True)
        shutil.copytree(root / "tests", tests, ignore=shutil.ignore_patterns("__pycache__"))
    head = (dest / "pyproject.toml").read_text().split("[tool.mutmut]")[0]
    tests = _tests(module, root, mode)
    (dest / "pyproject.toml").write_text(head.rstrip() + "\n\n" + _config(module, tests, mode))
    env = _env(mode)
    pats = _patterns(module, mode, functions) if mode in NAMED or functions else ["*"]
    before = _statuses(dest, env, pats)
    names = [n for n, status in before.items()
             if status in ("survived", "no_tests", "not_checked")]  # fmt: skip
    if not names:  # (no names: mutmut would run every mutant)
        return _count(before)
    subprocess.run([*MUTMUT, "run", "--max-children", str(children), *names], cwd=dest,
                   check=False, stdout=subprocess.DEVNULL, env=env)  # fmt: skip
    after = _statuses(dest, env, pats)
    return _count({**before, **{n: after[n] for n in names}})


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("modules", nargs="*", default=None)
    ap.add_argument("--keep", type=Path, default=None, help="keep the scratch folders here")
    ap.add_argument("--children", type=int, default=1, help="parallel mutant runs")
    ap.add_argument("--root", type=Path, default=ROOT, help="tree to score (default: this one)")
    again_help = "re-run the mutants the --keep folders' runs did not kill, with the tests now"
    ap.add_argument("--again", action="store_true", help=again_help)
    modes = ap.add_mutually_exclusive_group()
    compiled_help = "score the compiled loops (COMPILED) as Python, not the numpy path"
    modes.add_argument("--compiled", dest="mode", action="store_const", const="compiled",
                       default="numpy", help=compiled_help)  # fmt: skip
    jitable_help = "score only the @compiled.jitable physics functions (JITABLE), numpy path"
    modes.add_argument("--jitable", dest="mode", action="store_const", const="jitable",
                       help=jitable_help)  # fmt: skip
    functions_help = ("only the mutants of these functions or methods (comma-separated "
                      "names; with --compiled or --jitable: these too)")  # fmt: skip
    ap.add_argument("--functions", default="", help=functions_help)
    args = ap.parse_args(argv)
    functions = tuple(f for f in args.functions.split(",") if f)
    args.modules = args.modules or list(NAMED[args.mode][0] if args.mode in NAMED else MODULES)
    work = args.keep or Path(tempfile.mkdtemp(prefix="leolink-mutmut-"))
    print("| module | mutants | killed | survived | no tests | timeout | not checked | score |")
    print("|---|---|---|---|---|---|---|---|")
    for m in args.modules:
        s = (again if args.again else score)(m, work, args.children, args.root, args.mode,
                                             functions)  # fmt: skip
        total = s.get("total", 0)
        killed = s.get("killed", 0) + s.get("timeout", 0) + s.get("segfault", 0)
        pct = 100.0 * killed / total if total else float("nan")
        kinds = ("killed", "survived", "no_tests", "timeout", "not_checked")
        cells = [m, total, *(s.get(k, 0) for k in kinds)]
        print("| " + " | ".join(map(str, cells)) + f" | {pct:.1f} % |", flush=True)
    if args.keep is None:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
