"""Result sets: per-process files, directories, '+' groups, duplicates and bad files."""

from __future__ import annotations

import json

import pytest

from b2d_data.eval.results import EvalInputError, expand_result_argument, load_result_argument, load_result_set
from b2d_data.format import leaderboard as lb


def test_directory_and_plus_forms_read_the_same_records(synthetic_run):
    from_dir = load_result_argument(synthetic_run.run_dir)
    joined = load_result_argument("+".join(str(p) for p in synthetic_run.files), name="joined")
    assert from_dir.name == "agent_run" and joined.name == "joined"
    assert [r.route_id for r in from_dir.records] == [r.route_id for r in joined.records]
    assert len(from_dir.records) == 7 and from_dir.duplicates == []


def test_directory_files_sorted_naturally_and_merged_json_skipped(tmp_path):
    for name in ("eval_10.json", "eval_2.json", "merged.json"):
        (tmp_path / name).write_text("{}")
    files, from_directory = expand_result_argument(tmp_path)
    assert [p.name for p in files] == ["eval_2.json", "eval_10.json"] and from_directory


def test_duplicates_keep_the_last_record_and_are_reported(synthetic_run, tmp_path):
    later = synthetic_run.records["101"]
    later.scores = lb.Scores.compose(40, 1.0)
    extra = tmp_path / "rerun.json"
    lb.write_results(lb.LeaderboardResults(records=[later], progress=[1, 1]), extra)
    result_set = load_result_set([*synthetic_run.files, extra], "with-rerun")
    assert len(result_set.records) == 7 and result_set.records_read == 8
    kept = {r.route_id: r for r in result_set.records}["RouteScenario_101_rep0"]
    assert kept.scores.score_route == 40  # the last file given wins
    (dup,) = result_set.duplicates
    assert dup.route == "101" and dup.kept.startswith(str(extra)) and len(dup.occurrences) == 2
    with pytest.raises(EvalInputError, match="route 101"):
        load_result_set([*synthetic_run.files, extra], "strict", strict=True)


def test_explicit_file_that_is_not_leaderboard_json_is_an_error(tmp_path):
    bad = tmp_path / "ability.json"
    bad.write_text(json.dumps({"Overtaking": 0.2}))
    with pytest.raises(lb.LeaderboardFormatError, match="ability.json: no '_checkpoint' object"):
        load_result_argument(bad)


def test_directory_skips_non_leaderboard_files(synthetic_run):
    (synthetic_run.run_dir / "eval_0_ability.json").write_text(json.dumps({"Overtaking": 0.2}))
    result_set = load_result_argument(synthetic_run.run_dir)
    assert len(result_set.records) == 7
    assert [p.name for p, _ in result_set.skipped_files] == ["eval_0_ability.json"]


def test_missing_path_is_named(tmp_path):
    with pytest.raises(EvalInputError, match="nope.json: no such result file"):
        load_result_argument(tmp_path / "nope.json")
