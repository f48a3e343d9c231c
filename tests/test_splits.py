"""Split manifests: official-list import, the baseline train/val split, and deterministic generation."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import pytest

from b2d_data import splits
from b2d_data.format.names import ClipName
from b2d_data.format.scenario_types import SCENARIO_TYPES
from b2d_data.format.weather import WEATHER_IDS


def test_import_mini_and_base_with_baseline_val(b2d_data_dir: Path) -> None:
    mini = splits.import_official(b2d_data_dir / "bench2drive_mini_10.json")
    assert len(mini.train) == 10 and mini.val == ()
    first = mini.train[0]
    assert first.clip == "AccidentTwoWays_Town12_Route1444_Weather0"
    assert first.sha256 == "2690cb0053a2e9208f50f9d48c4a1c5befae4179c07e6fb8f06dc4434fb82178"
    assert first.size == 341845960

    base = splits.import_official(
        b2d_data_dir / "bench2drive_base_1000.json", b2d_data_dir / "bench2drive_base_train_val_split.json", "base"
    )
    # The Zoo split: 50 val entries ("v1/<clip>"), the other 950 are train.
    assert (len(base.train), len(base.val)) == (950, 50)
    assert "ParkingCrossingPedestrian_Town13_Route545_Weather25" in base.clips("val")
    # The truncated released name stays (weather unknown) and is a train clip.
    assert "VehicleTurningRoutePedestrian_Town15_Route523_Weathe" in base.clips("train")
    # The mini clips are a subset of base with the same sha256.
    base_sha = {e.clip: e.sha256 for e in base.entries()}
    assert all(base_sha[e.clip] == e.sha256 for e in mini.train)


def test_full_list_loads_all_entries(b2d_data_dir: Path) -> None:
    full = splits.load_file_list(b2d_data_dir / "bench2drive_full+sup_13638.json")
    assert len(full) == 13638
    assert all(len(e.sha256 or "") == 64 and e.size and e.size > 0 for e in full)


def test_manifest_round_trip(tmp_path: Path, b2d_data_dir: Path) -> None:
    base = splits.import_official(
        b2d_data_dir / "bench2drive_base_1000.json", b2d_data_dir / "bench2drive_base_train_val_split.json", "base"
    )
    path = base.save(tmp_path / "base.json")
    again = splits.SplitManifest.load(path)
    assert again.train == base.train and again.val == base.val and again.name == "base"
    # The saved parts use the official layout (archive name → sha256, size).
    data = json.loads(path.read_text())
    key = next(iter(data["val"]))
    assert key.endswith(".tar.gz") and set(data["val"][key]) == {"sha256", "size"}
    # An official list loads as a manifest with everything in train.
    assert len(splits.SplitManifest.load(b2d_data_dir / "bench2drive_mini_10.json").train) == 10


def _synthetic_corpus(clips_per_scenario: int = 6) -> list[splits.SplitEntry]:
    towns = ("Town01", "Town03", "Town12", "Town13")
    out = []
    route = 0
    for st in SCENARIO_TYPES:
        for k in range(clips_per_scenario):
            route += 1
            weather = WEATHER_IDS[(route * 7) % len(WEATHER_IDS)]
            name = ClipName(st.clip_prefix, towns[(route + k) % len(towns)], route, weather)
            out.append(splits.SplitEntry(str(name), f"{route:064x}", 1000 + route))
    return out


def test_generate_mini_one_clip_per_family_and_deterministic() -> None:
    corpus = _synthetic_corpus()
    mini = splits.generate_mini(corpus, seed=3)
    assert len(mini.train) == 10
    families = [splits.scenario_family(ClipName.parse(c).scenario) for c in mini.clips()]
    # The corpus has the ten behaviour families (no NoScenario): one clip of each.
    assert len(set(families)) == 10
    assert splits.generate_mini(corpus, seed=3) == mini
    assert splits.generate_mini(list(reversed(corpus)), seed=3) == mini  # input order does not matter
    assert splits.generate_mini(corpus, seed=4).clips() != mini.clips()


def test_generate_base_val_covers_every_scenario_with_balanced_weather(b2d_data_dir: Path) -> None:
    corpus = list(splits.load_file_list(b2d_data_dir / "bench2drive_full+sup_13638.json"))
    base = splits.generate_base(corpus, seed=0)
    assert (len(base.train), len(base.val)) == (950, 50)
    assert not set(base.clips("train")) & set(base.clips("val"))
    scen = {ClipName.parse(c).scenario for c in base.clips()}
    assert {ClipName.parse(c).scenario for c in base.clips("val")} == scen  # every scenario present is in val
    weathers = Counter(ClipName.parse(c).weather_id for c in base.clips("val"))
    # 50 val clips over 23 weathers: balanced means every weather 2 or 3 times.
    assert len(weathers) == 23 and max(weathers.values()) - min(weathers.values()) <= 1
    # Scenarios are drawn round-robin: 45 scenarios into 1000 clips ⇒ at least 22 each where the corpus allows.
    counts = Counter(ClipName.parse(c).scenario for c in base.clips())
    assert min(counts.values()) >= 19  # ControlLoss has only 19 clips in Full+Sup
    assert splits.generate_base(corpus, seed=0) == base
    assert base.train[0].sha256 is not None


def test_generate_full_keeps_every_clip() -> None:
    corpus = _synthetic_corpus(clips_per_scenario=5)
    full = splits.generate_full(corpus, seed=1)
    assert sorted(full.entries()) == sorted(corpus)
    assert len(full.val) == 44  # 5 % of 220 = 11 < 44 scenarios ⇒ one per scenario


def test_bad_split_file_names_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "broken.json"
    bad.write_text("{not json")
    with pytest.raises(ValueError, match="broken.json"):
        splits.load_file_list(bad)
