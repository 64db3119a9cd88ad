"""Shared pytest hooks: a private default runs directory for every test, and the tally of
the fault-injection sweep (``make faults``)."""

from __future__ import annotations

from collections import Counter
from typing import Any

import pytest

#: The longest tests of the suite (each ≥ 11 s of one core, ``pytest --durations=0`` on two idle
#: cores, 2026-12-06): whole trainings interrupted and resumed, sweeps and pools killed, the wheel
#: installed outside the checkout, reports of many controllers. They carry the ``slow`` mark, so
#: ``make test`` (what a contributor runs before each commit) leaves them to ``make test-slow``,
#: which CI runs after it; every module they exercise keeps faster tests in ``make test``.
LONG_TESTS = frozenset(
    {
        "tests/test_contact.py::test_stability_limit_bounds_the_engine",
        "tests/test_faults.py::test_a_table_of_another_shape_is_named_in_one_line[numbers as text]",
        "tests/test_faults.py::test_a_table_of_another_shape_is_named_in_one_line[a directory]",
        "tests/test_per_arm_td3.py::test_train_checkpoint_and_evaluate_a_per_arm_run[False-full]",
        "tests/test_contact_evaluation.py::test_report_has_contact_section",
        "tests/test_robustness.py::test_robustness_table_nominal_rows_equal_evaluate",
        "tests/test_evaluate.py::test_old_metrics_tables_without_action_columns_stay_valid",
        "tests/test_mirror.py::test_train_a_mirror_replay_run[sbx]",
        "tests/test_spec.py::test_experiment_file_of_shipped_run_gives_its_hash[ddpg-sbx-1e6-seed0]",
        "tests/test_per_arm_td3.py::test_own_arm_actors_see_only_their_arm_and_the_target",
        "tests/test_train.py::test_interrupt_and_resume[ppo-sb3]",
        "tests/test_faults.py::test_resume_keeps_started_the_killed_sessions_step_and_every_env_step",
        "tests/test_episodes.py::test_an_sbx_policy_and_its_independent_pair_run_in_batches",
        "tests/test_bounded_actor.py::test_the_penalty_pulls_saturated_actions_back",
        "tests/test_confirmation.py::test_independent_arms_are_confirmed_in_their_own_scene",
        "tests/test_faults.py::test_ctrl_c_during_many_random_episodes_keeps_the_finished_ones",
        "tests/test_faults.py::test_resume_without_its_checkpoints_refuses_and_changes_nothing[a file]",
        "tests/test_episodes.py::test_a_batch_of_episodes_equals_each_episode_alone[contact]",
        "tests/test_contact.py::test_matches_pyelastica_rod_rod_contact[defaults]",
        "tests/test_target_actor.py::test_a_training_model_acts_with_its_target_actor_inside_and_its_own_after[sbx]",
        "tests/test_target_actor.py::test_a_training_model_acts_with_its_target_actor_inside_and_its_own_after[sb3]",
        "tests/test_target_actor.py::test_an_exported_sbx_model_keeps_the_target_actor_it_acts_with",
        "tests/test_query.py::test_a_signal_mid_query_stops_it_with_one_line[2]",
        "tests/test_query.py::test_a_signal_mid_query_stops_it_with_one_line[15]",
        "tests/test_install.py::test_the_wheel_runs_quickstart_and_a_shipped_policy_outside_the_checkout",
        "tests/test_animate.py::test_report_html_replays_the_featured_controller_read_only",
        "tests/test_animate.py::test_two_shipped_runs_side_by_side_read_only",
        "tests/test_animate.py::test_an_html_page_plays_every_trajectory",
        "tests/test_per_arm_td3.py::test_each_critic_output_learns_its_own_arms_reward[True]",
        "tests/test_evaluate.py::test_shipped_runs_are_read_only_unless_in_place",
        "tests/test_entropy_algos.py::test_trains_evaluates_exports_and_loads_with_the_plain_class[tqc-sbx-mirror]",
        "tests/test_entropy_algos.py::test_trains_evaluates_exports_and_loads_with_the_plain_class[tqc-sb3-independent]",
        "tests/test_entropy_algos.py::test_resumes_after_an_interrupted_run[tqc-sb3]",
        "tests/test_validation.py::test_a_checkpoint_whose_episodes_all_drop_is_scored_by_its_hold",
        "tests/test_validation.py::test_independent_arms_validate_in_their_own_scene",
        "tests/test_train.py::test_interrupt_and_resume[td3-sb3]",
        "tests/test_train.py::test_interrupt_and_resume[td3-sbx]",
        "tests/test_report.py::test_a_report_of_many_controllers_draws_a_few_unless_all_figures",
        "tests/test_sweep.py::test_two_sweeps_share_a_runs_dir",
        "tests/test_report.py::test_the_command_line_chooses_the_drawn_controllers",
        "tests/test_sweep.py::test_sigterm_sweep_then_resume_with_corrupt_checkpoint",
        "tests/test_robustness.py::test_robustness_as_slurm_array_via_submitit_local",
        "tests/test_train_independent.py::test_independent_interrupt_and_resume[arm1-sigterm]",
        "tests/test_sweep.py::test_sweep_failing_job_and_siblings",
        "tests/test_robustness.py::test_robustness_in_worker_processes",
        "tests/test_train.py::test_same_seed_trains_the_same_run[td3-sbx]",
        "tests/test_transport.py::test_train_evaluate_and_report_a_transport_run",
        "tests/test_sweep.py::test_slurm_preemption_requeues_and_resumes",
        "tests/test_tune.py::test_two_workers_pull_from_one_study",
        "tests/test_report.py::test_old_metrics_tables_without_action_columns_still_build",
        "tests/test_entropy_algos.py::test_trains_evaluates_exports_and_loads_with_the_plain_class[sac-sbx]",
        "tests/test_report.py::test_old_metrics_tables_without_torque_and_clearance_columns_show_a_dash",
        "tests/test_evaluate.py::test_quickstart_reports_the_shipped_policy_beside_its_own_run",
        "tests/test_tune.py::test_interrupted_study_resumes_its_run",
        "tests/test_train.py::test_quickstart_reports_the_shipped_policy_as_it_just_measured_it",
        "tests/test_entropy_algos.py::test_trains_evaluates_exports_and_loads_with_the_plain_class[crossq-sbx-mirror]",
        "tests/test_validation.py::test_validation_leaves_training_unchanged[td3-sbx]",
        "tests/test_sweep.py::test_kill9_worker_then_resume",
        "tests/test_train_independent.py::test_independent_interrupt_and_resume[arm0-sigint]",
        "tests/test_validation.py::test_interrupted_run_validates_every_checkpoint_once",
        "tests/test_faults.py::test_resume_with_a_broken_spec_keeps_the_status[missing]",
        "tests/test_train_independent.py::test_independent_interrupt_and_resume[arm1-sigkill]",
        "tests/test_train.py::test_sigkill_then_resume",
        "tests/test_per_arm_td3.py::test_per_arm_networks_give_each_arm_its_own_actions_and_q_values",
        "tests/test_validation.py::test_validation_keeps_the_best_model_and_evaluation_uses_it",
        "tests/test_sweep.py::test_slurm_executor_via_submitit_local",
        "tests/test_faults.py::test_resume_with_a_broken_spec_keeps_the_status[latin-1]",
        "tests/test_learner_options.py::test_n_step_returns_build_sb3s_n_step_buffer",
        "tests/test_bounded_actor.py::test_train_evaluate_and_export_a_run",
        # session 22: `make test` took 622 s in a fresh-clone CI (limit 600 with set-up)
        "tests/test_engine_physics.py::test_gravity_cantilever_converges_to_timoshenko",
        "tests/test_per_arm_td3.py::test_train_checkpoint_and_evaluate_a_per_arm_run[True-full]",
        "tests/test_per_arm_td3.py::test_train_checkpoint_and_evaluate_a_per_arm_run[True-own_arm]",
        "tests/test_animate.py::test_missing_output_directories_are_created",
        "tests/test_tune.py::test_trials_are_runs_and_the_best_spec_trains",
        "tests/test_learner_options.py::test_mirror_images_are_n_step_columns_of_their_own",
        "tests/test_bounded_actor.py::test_the_actor_loss_adds_lambda_times_the_mean_square_preactivation",
        "tests/test_report.py::test_moment_peaks_read_the_old_and_the_new_table_format",
    }
)

#: what an injected fault did before softtrack handled it (``@pytest.mark.faults(kind)``)
FAULT_KINDS = ("lost", "traceback", "degraded", "held")

_tally: dict[str, Counter[str]] = {kind: Counter() for kind in FAULT_KINDS}


def _kind(item: Any) -> str | None:
    marker = item.get_closest_marker("faults") if hasattr(item, "get_closest_marker") else None
    if marker is None:
        return None
    kind = marker.args[0] if marker.args else marker.kwargs.get("kind", "held")
    if kind not in FAULT_KINDS:
        raise pytest.UsageError(f"{item.nodeid}: faults kind {kind!r}; one of {FAULT_KINDS}")
    return str(kind)


@pytest.fixture(autouse=True)
def _private_default_runs_dir(
    tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Commands run without --runs-dir write into a temporary directory, never the
    checkout's runs/; `softtrack workspace` records its floors in a temporary cache, never the
    user's ~/.cache."""
    monkeypatch.setenv("SOFTTRACK_RUNS_DIR", str(tmp_path_factory.mktemp("default-runs")))
    monkeypatch.setenv("SOFTTRACK_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))


@pytest.hookimpl(tryfirst=True)  # before -m "not slow" deselects
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        _kind(item)  # an unknown kind is a usage error at once
        if item.nodeid in LONG_TESTS:
            item.add_marker(pytest.mark.slow)


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    kind = getattr(report, "fault_kind", None)
    counted = report.when == "call" or (report.when == "setup" and not report.passed)
    if kind is not None and counted:
        _tally[kind]["failed" if report.failed else "passed" if report.passed else "skipped"] += 1


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[Any]) -> Any:
    outcome = yield
    report = outcome.get_result()
    report.fault_kind = _kind(item)


def pytest_terminal_summary(terminalreporter: Any) -> None:
    ran = sum(sum(c.values()) for c in _tally.values())
    if not ran:
        return
    failed = {kind: _tally[kind]["failed"] for kind in FAULT_KINDS}
    skipped = sum(c["skipped"] for c in _tally.values())
    terminalreporter.write_line(
        f"fault sweep: {ran} faults injected ({skipped} skipped here); still "
        f"{failed['lost']} lost, {failed['traceback']} tracebacks, {failed['degraded']} degraded, "
        f"{failed['held']} regressions among the faults that already held"
    )
