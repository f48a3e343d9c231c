"""The chain script's bookkeeping: stage order, stale-work detection, evaluation completeness."""

from __future__ import annotations

import importlib.util
import json
import os
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "run_baselines.py"
_spec = importlib.util.spec_from_file_location("run_baselines", SCRIPT)
assert _spec is not None and _spec.loader is not None
rb = importlib.util.module_from_spec(_spec)
sys.modules["run_baselines"] = rb  # its dataclasses look their module up there
_spec.loader.exec_module(rb)


def test_stages_run_in_chain_order(tmp_path: Path) -> None:
    args = rb.parse_args(["--work", str(tmp_path), "--stage", "table", "collect"])
    assert args.stages == ["collect", "table"]
    assert rb.parse_args(["--work", str(tmp_path)]).stages == list(rb.STAGES)


def test_retire_if_older(tmp_path: Path) -> None:
    folder = tmp_path / "train" / "admlp"
    folder.mkdir(parents=True)
    product, source = folder / "last.pt", tmp_path / ".collect_done"
    product.write_text("x")
    source.write_text("y")
    os.utime(product, (1000, 1000))
    os.utime(source, (500, 500))
    rb.retire_if_older(folder, product, source)
    assert folder.is_dir()  # the checkpoint is newer than the corpus: kept
    os.utime(source, (2000, 2000))
    rb.retire_if_older(folder, product, source)
    assert not folder.exists() and len(list((tmp_path / "train").glob("admlp.before-*"))) == 1


def test_eval_done_reads_progress(tmp_path: Path) -> None:
    assert not rb.eval_done(tmp_path)
    (tmp_path / "results.json").write_text(json.dumps({"_checkpoint": {"progress": [2, 3]}}))
    assert not rb.eval_done(tmp_path)
    (tmp_path / "results.json").write_text(json.dumps({"_checkpoint": {"progress": [3, 3]}}))
    assert rb.eval_done(tmp_path)


def test_agents_drive_the_best_checkpoint_where_there_is_one(tmp_path: Path) -> None:
    folder = tmp_path / "train" / "tcp"
    folder.mkdir(parents=True)
    (folder / "last.pt").write_text("x")
    assert rb.checkpoint_of(tmp_path, "tcp") == folder / "last.pt"
    (folder / "best.pt").write_text("y")
    assert rb.checkpoint_of(tmp_path, "tcp") == folder / "best.pt"
