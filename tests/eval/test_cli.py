"""``b2d-eval summary``: the printed table, the JSON and the PNG agree; bad input gives one line, no traceback."""

from __future__ import annotations

import json

import pytest

from b2d_data.cli.eval import main
from b2d_data.eval.report import ability_bars, plot_abilities
from b2d_data.eval.results import load_result_argument
from b2d_data.eval.summary import EvalSettings, evaluate
from b2d_data.scenarios.route_xml import read_routes

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
ABILITY_ROWS = ["Overtaking", "Merging", "Emergency_Brake", "Give_Way", "Traffic_Signs"]


def _parse_table(text: str) -> tuple[list[str], dict[str, list[str]]]:
    """Column names and label → cells of the printed table (up to the notes)."""
    lines = text.split("\n\n")[0].splitlines()
    header = lines[0].split()[1:]
    rows = {}
    for line in lines[2:]:
        cells = line.split()
        label_len = len(cells) - len(header)
        rows[" ".join(cells[:label_len])] = cells[label_len:]
    return header, rows


def _num(cell: str) -> float | None:
    return None if cell == "n/a" else float(cell)


def test_summary_two_result_sets_table_json_png_agree(synthetic_run, perfect_run, tmp_path, capsys):
    out = tmp_path / "report" / "summary.json"
    code = main([
        "summary", str(synthetic_run.run_dir), str(perfect_run), "--routes", str(synthetic_run.routes_file),
        "--metric-dir", str(synthetic_run.metric_dir), "--corrected-smoothness", "--names", "agent", "perfect",
        "--out", str(out),
    ])  # fmt: skip
    printed = capsys.readouterr().out
    assert code == 0
    data = json.loads(out.read_text())
    header, rows = _parse_table(printed)
    assert header == ["agent", "perfect"]
    sets = data["result_sets"]
    assert [s["name"] for s in sets] == header

    agent = sets[0]
    # The synthetic run worked out by hand in test_driving_score / test_abilities / test_smoothness.
    assert agent["driving_score"] == pytest.approx(62.5) and agent["success_rate"] == pytest.approx(37.5)
    assert agent["efficiency"]["value"] == pytest.approx(250 / 3)
    assert agent["smoothness"]["value"] == pytest.approx(50.0)
    assert agent["smoothness_corrected"]["value"] == pytest.approx(200 / 3)
    # Without --maps-dir the Traffic_Signs credit of route 103 cannot be checked: Traffic_Signs 0/4, mean 50.
    assert [agent["abilities"][a]["value"] for a in ABILITY_ROWS] == [100.0, 0.0, 50.0, 100.0, 0.0]
    assert agent["abilities"]["mean"] == pytest.approx(50.0)
    assert agent["missing_routes"] == ["107"] and agent["expected_routes"] == 8
    unchecked = agent["abilities"]["unchecked_routes"]
    assert [u["route_id"] for u in unchecked] == ["103", "104", "108"]
    assert {u["kind"] for u in unchecked} == {"no junction provider"}
    assert "Traffic_Signs credit not checked for 3 failed route(s), no junction provider" in printed
    perfect = sets[1]
    assert perfect["driving_score"] == 100.0 and perfect["abilities"]["mean"] == 100.0
    # Its records reuse the agent's save_names, so the same three metric files are read (one --metric-dir for all).
    assert perfect["smoothness"]["value"] == pytest.approx(50.0) and perfect["smoothness"]["routes"] == 3

    # Every printed figure equals the JSON figure rounded to 2 decimals.
    json_rows = {
        "Driving score": lambda s: s["driving_score"],
        "Success rate (%)": lambda s: s["success_rate"],
        "Route completion (%)": lambda s: s["route_completion"],
        "Infraction penalty (%)": lambda s: s["infraction_penalty"],
        "Efficiency (%)": lambda s: s["efficiency"]["value"],
        "Smoothness (%)": lambda s: s["smoothness"]["value"],
        "Smoothness, corrected units (%)": lambda s: s["smoothness_corrected"]["value"],
        **{f"{a} (%)": (lambda s, a=a: s["abilities"][a]["value"]) for a in ABILITY_ROWS},
        "Mean ability (%)": lambda s: s["abilities"]["mean"],
    }
    assert set(json_rows) <= set(rows)
    for label, read in json_rows.items():
        for cell, s in zip(rows[label], sets):
            expected = read(s)
            assert _num(cell) == (None if expected is None else round(expected, 2)), (label, s["name"])
    assert rows["Records / expected routes"] == ["7/8", "8/8"]
    assert "[agent] 7 records for 8 expected routes" in printed

    png = out.with_name("summary_abilities.png")
    assert png.read_bytes()[:8] == PNG_SIGNATURE


def test_bar_heights_match_the_json(synthetic_run, perfect_run, hand_junctions, tmp_path):
    routes = read_routes(synthetic_run.routes_file)
    settings = EvalSettings(routes=routes, junctions=hand_junctions)
    summaries = [evaluate(load_result_argument(p), settings) for p in (synthetic_run.run_dir, perfect_run)]
    png = tmp_path / "bars.png"
    heights = plot_abilities(summaries, png)
    # One bar per ability and the mean, per result set.
    assert [len(h) for h in heights] == [6, 6]
    assert heights[0] == pytest.approx([100.0, 0.0, 50.0, 100.0, 25.0, 55.0])
    assert heights[1] == pytest.approx([100.0] * 6)
    labels, values = ability_bars(summaries)
    assert labels == ABILITY_ROWS + ["Mean"] and values[0][5] == pytest.approx(55.0)
    assert png.read_bytes()[:8] == PNG_SIGNATURE


def test_vad_summary(b2d_data_dir, tmp_path, capsys):
    out = tmp_path / "vad.json"
    code = main(["summary", str(b2d_data_dir / "VAD_merged_results.json"), "--out", str(out)])
    printed = capsys.readouterr().out
    assert code == 0
    _, rows = _parse_table(printed)
    assert rows["Driving score"] == ["42.35"] and rows["Success rate (%)"] == ["15.00"]
    assert rows["Efficiency (%)"] == ["157.95"]
    assert "7 missing route(s) count 0" in printed
    assert "pass --routes" in printed and not out.with_name("vad_abilities.png").exists()
    # Leaderboard records (not b2d-collect's): over Bench2Drive's 220 routes, and the output says so.
    assert "[VAD_merged_results] 220: Bench2Drive's 220 evaluation routes (bench2drive220)" in printed
    data = json.loads(out.read_text())["result_sets"][0]
    assert data["records"] == 213 and data["expected_routes"] == 220 and data["abilities"] is None
    assert data["expected_routes_reason"].startswith("Bench2Drive's 220 evaluation routes")


def _error_line(capsys) -> str:
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    return lines[0]


def test_not_leaderboard_json_is_one_clear_line(tmp_path, capsys):
    bad = tmp_path / "notes.json"
    bad.write_text("[1, 2, 3]")
    assert main(["summary", str(bad), "--out", str(tmp_path / "o.json")]) == 1
    line = _error_line(capsys)
    assert line.startswith("b2d-eval: error:") and "notes.json" in line and "Leaderboard" in line


def test_route_missing_from_xml_is_one_clear_line(synthetic_run, b2d_data_dir, tmp_path, capsys):
    xml = b2d_data_dir / "drivetransformer_bench2drive_dev10.xml"
    assert main(["summary", str(synthetic_run.run_dir), "--routes", str(xml), "--out", str(tmp_path / "o.json")]) == 1
    line = _error_line(capsys)
    assert "drivetransformer_bench2drive_dev10.xml" in line and "RouteScenario_101_rep0" in line


def test_record_count_mismatch_warns_or_fails_in_strict_mode(synthetic_run, tmp_path, capsys):
    args = ["summary", str(synthetic_run.run_dir), "--num-routes", "10", "--out", str(tmp_path / "o.json")]
    assert main(args) == 0
    assert "7 records for 10 expected routes; the 3 missing route(s) count 0" in capsys.readouterr().out
    assert main([*args, "--strict"]) == 1
    assert "7 records for 10 expected routes" in _error_line(capsys)


def test_malformed_route_xml_is_one_clear_line(synthetic_run, tmp_path, capsys):
    xml = tmp_path / "broken.xml"
    xml.write_text("<routes>\n<route id='1' town='Town01'>\n</routes>\n")
    assert main(["summary", str(synthetic_run.run_dir), "--routes", str(xml), "--out", str(tmp_path / "o.json")]) == 1
    line = _error_line(capsys)
    assert "broken.xml: line 3" in line


def test_inconsistent_arguments_exit_with_usage(synthetic_run, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["summary", str(synthetic_run.run_dir), "--names", "a", "b", "--out", str(tmp_path / "o.json")])
    assert exc.value.code == 2 and "--names gives 2 label(s) for 1 result set(s)" in capsys.readouterr().err


def test_merge_flag_makes_one_set_of_all_files(synthetic_run, tmp_path, capsys):
    out = tmp_path / "m.json"
    files = [str(p) for p in synthetic_run.files]
    assert main(["summary", *files, "--merge", "--names", "run", "--num-routes", "8", "--out", str(out)]) == 0
    (only,) = json.loads(out.read_text())["result_sets"]
    assert only["name"] == "run" and only["records"] == 7 and only["driving_score"] == pytest.approx(62.5)


def test_shipped_files_by_bare_name(tmp_path, monkeypatch, capsys):
    # From a folder holding neither file, the bare names reach the copies the package ships.
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "s.json"
    assert main(["summary", "VAD_merged_results.json", "--routes", "bench2drive220.xml", "--out", str(out)]) == 0
    result = json.loads(out.read_text())["result_sets"][0]
    assert result["driving_score"] == pytest.approx(42.35, abs=0.005)
    assert result["abilities"]["Overtaking"]["value"] == pytest.approx(24.44, abs=0.005)  # 11 of 45 routes
