"""Test layout by cost: tests/unit (in-process, under 1 s each), tests/integration
(processes and the bus, the CLI in-process, longer physics) and tests/system (the `bench`
command run as a subprocess end to end: demo, up/down, the CLI's files and signals, the
built wheel in a clean virtual environment). Markers come from the path, so `-m unit` /
`-m integration` / `-m system` select them (PyBaMM's conftest does the same). Tests
listed in `SLOW` (over ~5 s) are also marked `slow`: `-m "not slow"` skips them. The
helpers (`log_frames`, `bus_helpers`, the minimal node) serve every folder."""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).resolve().parent / "data"
for _helpers in ("unit", "integration"):        # helper modules shared across the folders
    if str(ROOT / "tests" / _helpers) not in sys.path:
        sys.path.insert(0, str(ROOT / "tests" / _helpers))

# Tests whose run (setup + call) took over ~5 s on the 2-core development VM under load
# (pytest --durations); re-measured under a load average of
# 10-20 (the whole suite 26 min 52 s instead of ~3 min 40 s; 24 min 32 s at load 7-12):
# the tests over ~30 s there were added. A file marks all its tests, "file::test" one test and all its parameter
# sets.
SLOW: tuple[str, ...] = (
    "tests/integration/test_calibrate_other_lead.py",
    "tests/integration/test_rig_classify.py",
    "tests/integration/test_rig_update.py",
    "tests/integration/test_calibrate_no_alias.py",
    "tests/integration/test_gap_cli_status.py",
    "tests/integration/test_bus_faults.py::test_ecu_killed_mid_run_lockstep_plant_holds_still",
    "tests/integration/test_bus_faults.py::test_plant_killed_mid_run_ecu_stops_with_a_clear_error_and_a_complete_log",
    "tests/integration/test_bus_run.py::test_bench_decode_writes_csv_and_parquet",
    "tests/integration/test_bus_run.py::test_lockstep_bus_run_equals_in_process",
    "tests/integration/test_bus_run.py::test_python_can_logger_captures_and_cantools_decodes",
    "tests/integration/test_figures_api.py",
    "tests/integration/test_fleet.py::test_ingest_killed_mid_way_resumes_without_loss_or_duplicates",
    "tests/integration/test_fleet.py::test_synth_ingest_status_report_export",
    "tests/integration/test_flight_bus.py",
    "tests/integration/test_gap_diagnose.py::test_each_effect_alone_is_found",
    "tests/integration/test_gap_diagnose.py::test_effect_outside_the_library_is_unexplained",
    "tests/integration/test_hub_bad_client.py",
    "tests/integration/test_hums_figures.py",
    "tests/integration/test_hums_rul.py::test_scoring_leaves_matplotlib_settings_alone",
    "tests/integration/test_indie_generate.py::test_gap_bench_on_the_independent_generator_smoke",
    "tests/integration/test_indie_controller.py::test_the_own_controller_is_identified_and_closes_the_model_loop",
    "tests/integration/test_indie_node.py",
    "tests/integration/test_logs_damaged.py::test_decode_counts_the_damage",
    "tests/integration/test_logs_damaged.py::test_gap_noise_free_log_with_a_lost_sync_has_no_significant_gap",
    "tests/integration/test_logs_damaged.py::test_hums_report_bridges_counts_and_keeps_the_intact_numbers",
    "tests/integration/test_minimal_node.py::test_encoder_resolution_from_the_flag",
    "tests/integration/test_minimal_node.py::test_gap_excitation_load_needs_the_load_objects",
    "tests/integration/test_minimal_node.py::test_realtime_run_reports_what_is_missing_and_completes",
    "tests/integration/test_rig_calibrate.py::test_cli_calibrate_then_gap_finds_a_localised_resistance",
    "tests/integration/test_rig_calibrate.py::test_unknown_cascade_gains_recovered_at_25_hz",
    "tests/integration/test_rig_hums_report.py::test_calibrate_writes_the_baseline_when_above_the_floor",
    "tests/integration/test_usage_bus.py",
    "tests/integration/test_workers_chunks.py",
    "tests/integration/test_usage_campaign.py::test_mini_campaign_runs_to_failure_and_scores_every_method",
    "tests/integration/test_prognosis.py::test_particle_filter_recovers_a_known_wear_coefficient",
    "tests/integration/test_usage_cli.py::test_usage_per_run_and_per_actuator",
    "tests/integration/test_workers_dask.py",
    "tests/system/test_bus_cli.py::test_run_without_bench_up_starts_and_stops_its_own_bus_and_plant",
    "tests/system/test_bus_cli.py::test_up_status_run_down",
    "tests/system/test_cli.py::test_reproduce_end_to_end",
    "tests/system/test_demo.py",
    "tests/system/test_ecu_reliability.py::test_a_disk_filling_up_during_the_run_fails_it_clearly",
    "tests/system/test_ecu_reliability.py::test_a_second_ecu_is_refused_and_the_first_run_stays_clean",
    "tests/system/test_ecu_reliability.py::test_a_stalled_ecu_is_not_a_silent_success",
    "tests/system/test_gap_cli.py::test_gap_bench_smoke",
    "tests/system/test_gap_cli.py::test_import_calibrate_gap",
    "tests/system/test_hums_cli.py::test_report_is_self_contained_with_a_verdict",
    "tests/system/test_hums_cli.py::test_sweep_writes_json_rows",
    "tests/system/test_hums_live.py::test_watch_reports_every_period_like_the_log",
    "tests/system/test_rig_cli.py",
    "tests/system/test_state_runlogs.py::test_runs_leave_no_files_behind",
    "tests/system/test_updown_state.py::test_corrupt_hub_record_in_status_and_down",
    "tests/system/test_updown_state.py::test_corrupt_hub_record_in_up_and_run",
    "tests/system/test_updown_state.py::test_down_never_signals_the_process_of_a_stale_hub_record",
    "tests/system/test_updown_state.py::test_two_concurrent_ups_start_one_hub_and_one_plant",
    "tests/system/test_updown_state.py::test_up_ignores_a_stale_plant_record_of_a_reused_pid",
    "tests/system/test_wheel.py",
)


def pytest_configure(config: pytest.Config) -> None:  # noqa: ARG001
    """A child process inherits an ignored SIGINT, and then python-can's logger and
    `bench log` started by a test never stop on the SIGINT the test sends them (they hung).
    pytest-xdist's workers ignore SIGINT, and so does a suite started in the background
    of a non-interactive shell: the suite's process gets Python's handler back (its
    children then start with the default)."""
    if (os.environ.get("PYTEST_XDIST_WORKER")
            or signal.getsignal(signal.SIGINT) is signal.SIG_IGN):
        signal.signal(signal.SIGINT, signal.default_int_handler)


def _is_slow(nodeid: str) -> bool:
    return any(nodeid == s or nodeid.startswith((s + "::", s + "[")) for s in SLOW)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        parts = Path(str(item.fspath)).parts
        if "unit" in parts:
            item.add_marker(pytest.mark.unit)
        elif "integration" in parts:
            item.add_marker(pytest.mark.integration)
        elif "system" in parts:
            item.add_marker(pytest.mark.system)
        if _is_slow(item.nodeid):
            item.add_marker(pytest.mark.slow)
    # the longest files first: pytest-xdist's loadfile hands files out in this order, so
    # the system tests (minutes each) no longer start last and leave one worker alone at
    # the end; a stable sort keeps each file's tests together and in order
    rank = {"system": 0, "integration": 1}
    items.sort(key=lambda it: next((rank[p] for p in Path(str(it.fspath)).parts
                                    if p in rank), 2))
