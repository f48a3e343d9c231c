"""The table that ``scripts/fault_matrix.py`` prints (the matrix itself runs for minutes: not in the test suite)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path


def _script():
    path = Path(__file__).resolve().parents[2] / "scripts" / "fault_matrix.py"
    spec = importlib.util.spec_from_file_location("fault_matrix", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_one_line_per_case_and_a_count_of_failures():
    fm = _script()
    table = fm.format_table([
        fm.CaseResult("kill-9-driver", True, "killed; --resume rc 0", clips=2, asked=2, clear_error=True),
        fm.CaseResult("loader-stray", False, "100000 frames"),
    ]).splitlines()
    # Columns as wide as their widest cell ("kill-9-driver": 13, "result": 6, "clips/asked" and "clear error": 11),
    # two spaces apart; the outcome last, unpadded; "—" where a column does not apply.
    assert table == [
        "case           result  clips/asked  clear error  outcome",
        "kill-9-driver  ok      2/2          yes          killed; --resume rc 0",
        "loader-stray   FAIL    —            —            100000 frames",
        "1 of 2 cases held; 1 FAILED",
    ]
    assert fm.format_table([fm.CaseResult("x", True, "fine", clips=0, asked=1, clear_error=False)]).splitlines()[1:] == [
        "x     ok      0/1          no           fine",
        "1 of 1 cases held",
    ]
