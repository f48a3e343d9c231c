"""``b2d-collect`` end to end at a tiny resolution: clips, annotations vs the simulator, kill -9 + resume, errors.

The routes are the generated Accident routes of the default town, cut to ~22 m (the accident lies beyond the route's
end, its actors are within the 100 m annotation radius from the start), so that a clip takes seconds.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from b2d_data.cli.collect import main
from b2d_data.codecs.anno_json import read_anno
from b2d_data.collection import run_log as rl
from b2d_data.collection.towns import TownSource, load_map
from b2d_data.format.names import ClipName
from b2d_data.format.road_option import RoadOption
from b2d_data.scenarios.route_xml import read_routes, write_routes

from ..conftest import assert_all_exit, descendants, sigint_default

N = 2
TINY = ["--width", "64", "--height", "36", "--lidar-azimuth-steps", "90", "--encode-workers", "0", "--no-progress"]
ROUTE_LENGTH = 22.0  # m of each generated route that the tests keep


@pytest.fixture(scope="module")
def short_routes(tmp_path_factory) -> tuple[Path, Path]:
    """(Town100.xodr, a route file with 3 short Accident routes on it)."""
    from b2d_data.scenarios import placement
    from b2d_data.scenarios.route import DenseRoute
    from b2d_data.scenarios.triggers import trigger_route_index

    folder = tmp_path_factory.mktemp("town")
    town = TownSource(preset="all").materialise(folder)
    world_map = load_map(town)
    short = []
    for route in placement.make_routes(world_map, "Accident", 3, seed=0, params="bench2drive220"):
        start = route.waypoints[0]
        keep = tuple(p for p in route.waypoints if math.hypot(p.x - start.x, p.y - start.y) <= ROUTE_LENGTH)
        cut = replace(route, waypoints=keep)
        dense = DenseRoute.from_route(world_map, cut)
        assert trigger_route_index(dense, cut.scenarios[0].trigger_point) is not None, "trigger cut off the route"
        short.append(cut)
    path = folder / "short_accident.xml"
    write_routes(short, path)
    return town.xodr, path


def _args(short_routes: tuple[Path, Path], out: Path, *extra: str) -> list[str]:
    xodr, routes = short_routes
    return [
        "--routes",
        str(routes),
        "--xodr",
        str(xodr),
        "--scenario",
        "Accident",
        "--n",
        str(N),
        "--seed",
        "7",
        "--out",
        str(out),
        *TINY,
        *extra,
    ]


def _clips(out: Path) -> list[Path]:
    return sorted(p for p in out.iterdir() if p.is_dir() and not p.name.startswith(".") and (p / "anno").is_dir())


def _temporaries(out: Path) -> list[Path]:
    return [p for p in out.rglob(".*") if ".tmp-" in p.name or ".old-" in p.name]


@pytest.fixture(scope="module")
def collection(short_routes, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("corpus") / "data"
    assert main(_args(short_routes, out)) == 0
    return out


def test_collects_exactly_n_clips_that_load(collection):
    from b2d_data import ClipDataset

    clips = _clips(collection)
    assert len(clips) == N
    records = rl.final_records(rl.read_run_log(collection / rl.LOG_FILE))
    by_clip = {r["clip"]: r for r in records if r["status"] == "clip"}
    assert sorted(by_clip) == [c.name for c in clips]
    for clip in clips:
        name = ClipName.parse(clip.name)
        assert (name.scenario, name.town) == ("Accident", "Town100")
        assert (collection / "results" / f"{clip.name}.json").is_file()
    assert (collection / "maps" / "Town100_HD_map.npz").is_file()
    summary = json.loads((collection / "summary.json").read_text())
    assert summary["complete"] and summary["scenarios"][0]["clips"] == N

    ds = ClipDataset(collection, index="memory", radar=True, depth=True, semantic=True, instance=True, keep_anno=True)
    frames = {c.name: by_clip[c.name]["frames"] for c in clips}
    assert len(ds) == sum(frames.values())
    for i in (0, len(ds) - 1):
        sample = ds[i]
        assert sample["images"].shape == (6, 36, 64, 3)
        assert sample["depth"].shape == sample["semantic"].shape == sample["instance"].shape == (6, 36, 64)
        assert sample["lidar"].ndim == 2 and sample["lidar"].shape[0] > 0
        assert "radar" in sample and sample["boxes"].shape[1] == 7
    for clip in clips:
        n = frames[clip.name]
        assert len(list((clip / "anno").glob("*.json.gz"))) == n
        assert len(list((clip / "camera" / "rgb_top_down").glob("*.jpg"))) == n
        from b2d_data.codecs.jpeg import read_jpeg

        assert read_jpeg(clip / "camera" / "rgb_top_down" / f"{n - 1:05d}.jpg").shape == (36, 64, 3)


def test_eval_summary_of_the_collection_scores_its_own_routes(collection, tmp_path, capsys):
    """``b2d-eval summary OUT/results``, as ``b2d-collect --help`` suggests: over the N routes run, not 220."""
    from b2d_data.cli.eval import main as eval_main

    out = tmp_path / "summary.json"
    assert eval_main(["summary", str(collection / "results"), "--out", str(out)]) == 0
    data = json.loads(out.read_text())["result_sets"][0]
    finals = rl.final_records(rl.read_run_log(collection / rl.LOG_FILE))
    assert len(finals) == N and data["expected_routes"] == N
    assert data["driving_score"] == pytest.approx(sum(r["score_composed"] for r in finals) / N)
    assert data["success_rate"] == pytest.approx(100.0)  # both attempts made clips
    assert f"[results] {N}: b2d-collect collection" in capsys.readouterr().out


def _resimulate(collection: Path, clip: Path, short_routes) -> list[dict]:
    """Run the clip's route again without sensors, recording the simulator state at every recorded tick."""
    from b2d_data.expert import Expert, ExpertConfig
    from b2d_data.scenarios.route import DenseRoute
    from b2d_data.scenarios.route_runner import RouteRunner
    from b2d_data.sim.builtin.world import BuiltinSimulator

    xodr, routes_file = short_routes
    name = ClipName.parse(clip.name)
    record = next(
        r for r in rl.final_records(rl.read_run_log(collection / rl.LOG_FILE)) if r["route_id"] == str(name.route_id)
    )
    route = next(r for r in read_routes(routes_file) if r.id == str(name.route_id))
    world_map = load_map(TownSource(xodr=xodr))
    sim = BuiltinSimulator(world_map, seed=record["seed"], weather=route.weather_at(0.0))
    dense = DenseRoute.from_route(world_map, route)
    expert = Expert(world_map, dense, ExpertConfig.for_builtin(), seed=record["seed"])
    states: list[dict] = []

    def on_frame(snapshot, info):
        ego = snapshot.actors[info.ego_id]
        scenario_ids = {
            a.id
            for a in snapshot.actors.values()
            if a.role_name == "scenario" and a.parent_id is None and ego.location.distance_2d(a.location) <= 100.0
        }
        states.append({"ego": ego.transform, "scenario_ids": scenario_ids})

    RouteRunner(sim, route, expert, seed=record["seed"], on_frame=on_frame, dense_route=dense).run()
    sim.close()
    return states


def test_annotations_agree_with_the_simulator(collection, short_routes):
    clip = _clips(collection)[0]
    states = _resimulate(collection, clip, short_routes)
    annos = [read_anno(p) for p in sorted((clip / "anno").glob("*.json.gz"))]
    assert len(annos) == len(states)
    valid_commands = {int(o) for o in RoadOption}
    seen_scenario_actor = False
    for anno, state in zip(annos, states):
        ego = anno["bounding_boxes"][0]
        assert ego["class"] == "ego_vehicle"
        t = state["ego"]
        np.testing.assert_allclose(ego["location"], [t.location.x, t.location.y, t.location.z], atol=1e-4)
        np.testing.assert_allclose(ego["rotation"], t.rotation.to_anno(), atol=1e-4)
        np.testing.assert_allclose(np.array(ego["world2ego"]), t.inverse_matrix(), atol=1e-4)
        ids = {box["id"] for box in anno["bounding_boxes"][1:]}
        assert {str(i) for i in state["scenario_ids"]} <= ids
        seen_scenario_actor |= bool(state["scenario_ids"])
        for key in ("next_command", "command_near", "command_far"):
            assert anno[key] in valid_commands
    assert seen_scenario_actor, "the accident's actors never showed up within 100 m"


def test_num_points_recount_exactly_from_the_written_lidar(collection):
    """Bench2Drive's counting rule on each frame's LAZ file (read back with the project's reader) gives every
    stored ``num_points``: the count is made on exactly the points that are written."""
    from b2d_data.codecs.laz import read_laz

    checked = nonzero = 0
    for clip in _clips(collection):
        for path in sorted((clip / "anno").glob("*.json.gz")):
            anno = read_anno(path)
            points = read_laz(clip / "lidar" / path.name.replace(".json.gz", ".laz"))
            ego = anno["bounding_boxes"][0]
            world2ego = np.asarray(ego["world2ego"])
            for box in anno["bounding_boxes"][1:]:
                if "num_points" not in box:
                    continue
                # The rule: a box centred on the actor origin in the ego frame, turned by the yaw relative to the
                # ego, with the half extents; points strictly inside.
                origin = world2ego[:3, :3] @ np.asarray(box["location"]) + world2ego[:3, 3]
                yaw = math.radians(box["rotation"][2] - ego["rotation"][2])
                d = points - origin
                along = math.cos(yaw) * d[:, 0] + math.sin(yaw) * d[:, 1]
                across = -math.sin(yaw) * d[:, 0] + math.cos(yaw) * d[:, 1]
                ex, ey, ez = box["extent"]
                count = int(((np.abs(along) < ex) & (np.abs(across) < ey) & (np.abs(d[:, 2]) < ez)).sum())
                assert count == box["num_points"], (clip.name, path.name, box["id"], count, box["num_points"])
                checked += 1
                nonzero += count > 0
    assert checked > 100 and nonzero > 20, (checked, nonzero)


def _ego_xy(anno: dict, world_xyz: list[float]) -> tuple[float, float]:
    """A world point in the annotation's ego frame (x forward, y right)."""
    p = np.asarray(anno["bounding_boxes"][0]["world2ego"]) @ np.array([*world_xyz, 1.0])
    return float(p[0]), float(p[1])


def test_expert_assessment_decodes_to_the_expert_and_the_scene(collection):
    """Every frame has its npz (format.md §2.8), whose action and raster agree with the frame's annotation."""
    import zipfile

    from b2d_data.codecs.format_info import read_format_info
    from b2d_data.format import expert_feature as ef
    from b2d_data.format.expert_actions import ACTIONS, action_control

    near_straight = vehicles_checked = 0
    for clip in _clips(collection):
        annos = [read_anno(p) for p in sorted((clip / "anno").glob("*.json.gz"))]
        names = sorted(p.name for p in (clip / "expert_assessment").iterdir())
        assert names == sorted(f"{k - 1:05d}.npz" for k in range(len(annos)))  # -0001.npz first
        info = read_format_info(clip)
        assert info is not None and info.expert_assessment and info.expert_feature == ef.layout_record()
        progress = []
        for k, anno in enumerate(annos):
            path = clip / "expert_assessment" / f"{k - 1:05d}.npz"
            with zipfile.ZipFile(path) as z:  # np.savez(path, vector): one unnamed, uncompressed array
                assert [(e.filename, e.compress_type) for e in z.infolist()] == [("arr_0.npy", zipfile.ZIP_STORED)]
            vec = np.load(path)["arr_0"]
            assert vec.shape == (1538,)
            progress.append(float(vec[-2]))
            # Action → controls within the table's resolution of the annotation's control (format/expert_actions.py:
            # 0.21 while |steer| ≤ 0.1; 0.59 anywhere else, the farthest forward control (1, ±1) being √(0.3² + 0.5²)
            # from (0.7, ±0.5)); a brake decodes to the full-brake action.
            action = action_control(vec[-1])
            throttle, steer, brake = anno["throttle"], anno["steer"], anno["brake"]
            if brake >= 0.5:
                assert action == ACTIONS[0]
            else:
                gap = math.hypot(action.throttle - throttle, action.steer - steer)
                assert action.brake == 0.0 and not action.reverse
                if abs(steer) <= 0.1:
                    near_straight += 1
                    assert gap <= 0.21, (clip.name, k, anno["throttle"], anno["steer"], action)
                else:
                    assert gap <= 0.59
            # Feature → the raster of what the simulator held (the annotation is the same snapshot).
            raster = ef.unflatten(vec[:-2])
            assert np.allclose(raster[ef.SPEED], min(max(anno["speed"] / 25.0, 0.0), 1.0), atol=1e-6)
            assert raster[ef.DRIVABLE, 7:9, 7:9].any() and raster[ef.ROUTE, 7:9, 7:9].any()  # the ego's own cells
            for channel, cls in ((ef.VEHICLES, "vehicle"), (ef.WALKERS, "walker")):
                boxes = [b for b in anno["bounding_boxes"][1:] if b["class"] == cls]
                centres = [_ego_xy(anno, b["center"]) for b in boxes]
                for box, (x, y) in zip(boxes, centres):
                    cell = ef.cell_of(x, y)
                    on_edge = min(abs(x / 2.0 - round(x / 2.0)), abs(y / 2.0 - round(y / 2.0))) < 0.03
                    if cell is not None and not on_edge:  # the cell holding a box centre overlaps the box
                        assert raster[channel][cell] == 1.0, (clip.name, k, box["id"], cell)
                        vehicles_checked += channel == ef.VEHICLES
                # Conversely, a lit cell lies within reach of a box: centre distance ≤ cell and box half diagonals.
                for r, c in zip(*np.nonzero(raster[channel])):
                    cx, cy = 16.0 - 2.0 * r - 1.0, -16.0 + 2.0 * c + 1.0
                    assert any(
                        math.hypot(cx - x, cy - y) <= math.sqrt(2.0) + math.hypot(*b["extent"][:2]) + 0.05
                        for b, (x, y) in zip(boxes, centres)
                    ), (clip.name, k, cls, (r, c))
            stops = [b for b in anno["bounding_boxes"] if b.get("state") in (0, 1) or "stop" in b.get("type_id", "")]
            assert stops or not raster[ef.STOP].any()
        assert progress == sorted(progress) and 0.0 <= progress[0] <= 0.1 and progress[-1] <= 1.0
    assert near_straight > 0 and vehicles_checked > 0  # the tight bound and the vehicle cells were exercised


def test_clip_dataset_returns_the_expert_assessment(collection):
    from b2d_data import ClipDataset
    from b2d_data.format import expert_feature as ef
    from b2d_data.format.expert_actions import action_control

    clip = _clips(collection)[0]
    flat = ClipDataset(collection, index="memory", clips=[clip.name], expert=True, cameras=(), lidar=False)
    bev = ClipDataset(collection, index="memory", clips=[clip.name], expert_bev=True, cameras=(), lidar=False)
    for k in (0, len(flat) - 1):
        vec = np.load(clip / "expert_assessment" / f"{k - 1:05d}.npz")["arr_0"]
        s, b = flat[k], bev[k]
        assert s["frame"] == k and np.array_equal(s["expert_feature"], vec[:-2])
        assert s["expert_value"] == vec[-2] and s["expert_action"] == int(vec[-1])
        assert np.array_equal(s["expert_control"], action_control(vec[-1]).as_array())
        assert b["expert_feature"].shape == (6, 16, 16) and np.array_equal(b["expert_feature"], ef.unflatten(vec[:-2]))



def _kill_mid_collection(args: list[str], out: Path, clips_first: int = 1, timeout: float = 240.0) -> set[int]:
    """Start b2d-collect, SIGKILL it once ``clips_first`` clips are complete and another one is being written.

    Returns the processes the collection had started (all of them must then exit on their own).
    """
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "b2d_data.cli.collect", *args],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + timeout
    helpers: set[int] = set()
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            helpers |= descendants(proc.pid)
            if out.is_dir() and len(_clips(out)) >= clips_first:
                partial = [p for p in out.glob(".*.tmp-*") if p.is_dir() and len(list(p.glob("anno/*.json.gz"))) >= 3]
                if partial:
                    break
            time.sleep(0.05)
        assert proc.poll() is None, "the collection ended before it could be killed"
        helpers |= descendants(proc.pid)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return helpers


def test_kill_9_then_resume_gives_exactly_n_clips_with_the_same_annotations(collection, short_routes, tmp_path, capsys):
    out = tmp_path / "data"
    out.mkdir()
    shutil.copytree(collection / "maps", out / "maps")  # the HD-map export is tested above; skip its 5 s here
    # One route at a time (the count below), with an encoder process, which must die too.
    args = _args(short_routes, out, "--workers", "1", "--encode-workers", "1")
    helpers = _kill_mid_collection(args, out)
    assert len(_clips(out)) == 1 and _temporaries(out), "expected one clip and one half-written clip"
    half_written = sorted(str(p.relative_to(out)) for p in out.glob(".*.tmp-*"))
    before = rl.read_run_log(out / rl.LOG_FILE)
    assert len(rl.interrupted_routes(before)) == 1
    killed_route = rl.interrupted_routes(before)[0]
    assert_all_exit(helpers)

    assert main(args) == 2  # a used folder needs --resume
    capsys.readouterr()
    assert main([*args, "--resume"]) == 0
    # The resume says what it kept and what it threw away, and the run log records both.
    err = capsys.readouterr().err
    assert "resume: kept 1 complete clip(s) from 1 finished attempt(s)" in err, err
    assert f"discarded {len(half_written)} half-written" in err and f"run again: {killed_route}" in err, err
    log_records = rl.read_run_log(out / rl.LOG_FILE)
    discarded = [r for r in log_records if r["event"] == rl.EVENT_DISCARDED]
    assert sorted(r["path"] for r in discarded) == half_written
    interrupted = [r for r in log_records if r["event"] == rl.EVENT_INTERRUPTED]
    assert [(r["route_id"], r["detected"]) for r in interrupted] == [(killed_route, "on resume")]

    clips = _clips(out)
    assert len(clips) == N
    assert not _temporaries(out)
    route_ids = [ClipName.parse(c.name).route_id for c in clips]
    assert len(set(route_ids)) == N
    records = rl.read_run_log(out / rl.LOG_FILE)
    finals = rl.final_records(records)
    assert not rl.interrupted_routes(records)
    assert sorted(r["clip"] for r in finals if r["status"] == "clip") == [c.name for c in clips]
    assert len({r["route_id"] for r in finals}) == len(finals)  # one finished attempt per route

    # Same seed, same routes: the resumed corpus holds the very same annotations as the uninterrupted one.
    assert [c.name for c in clips] == [c.name for c in _clips(collection)]
    for clip in clips:
        mine = sorted((clip / "anno").glob("*.json.gz"))
        reference = sorted((collection / clip.name / "anno").glob("*.json.gz"))
        assert [p.name for p in mine] == [p.name for p in reference]
        for a, b in zip(mine, reference):
            assert read_anno(a) == read_anno(b), f"{clip.name}/{a.name} differs between the two runs"


def test_user_errors_are_one_line_and_exit_2(short_routes, tmp_path, capsys, carla_maps_dir):
    cases = [
        ["--scenario", "Acident", "--out", str(tmp_path / "a")],
        ["--scenario", "Accident", "--town", "nowhere", "--out", str(tmp_path / "b")],
        ["--routes", str(tmp_path / "missing.xml"), "--out", str(tmp_path / "c")],
        ["--routes", str(short_routes[1]), "--xodr", str(carla_maps_dir / "Town01.xodr"), "--out", str(tmp_path / "d")],
    ]
    bad_xml = tmp_path / "bad.xml"
    bad_xml.write_text("<routes><route id='1' town='Town100'>")
    cases.append(["--routes", str(bad_xml), "--out", str(tmp_path / "e")])
    expected = ["Did you mean Accident", "unknown town preset", "route file not found", "Town100", "malformed XML"]
    for argv, text in zip(cases, expected):
        assert main([*argv, *TINY]) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("b2d-collect: error:") and text in err[0], err


def test_run_log_skips_a_line_cut_by_a_crash(tmp_path):
    log = rl.RunLog(tmp_path / rl.LOG_FILE)
    log.append({"event": "start", "route_id": "1"})
    with open(log.path, "ab") as f:
        f.write(b'{"event": "attempt", "route_id": "1", "sta')  # killed mid-write
    log.append({"event": "start", "route_id": "2"})
    records = rl.read_run_log(log.path)
    assert [r["route_id"] for r in records] == ["1", "2"]
    assert rl.interrupted_routes(records) == ["1", "2"]


def test_physics_only_in_two_worker_processes_matches_the_sensor_run(collection, short_routes, tmp_path):
    out = tmp_path / "records"
    assert main([*_args(short_routes, out), "--no-sensors", "--workers", "2"]) == 0
    assert not _clips(out)
    finals = rl.final_records(rl.read_run_log(out / rl.LOG_FILE))
    assert len({r["pid"] for r in finals}) >= 1 and all(r["frames"] == 0 for r in finals)
    reference = {r["route_id"]: r for r in rl.final_records(rl.read_run_log(collection / rl.LOG_FILE))}
    for r in finals:
        ref = reference[r["route_id"]]
        assert (r["status"], r["ticks"], r["score_route"], r["infractions"]) == (
            ref["status"],
            ref["ticks"],
            ref["score_route"],
            ref["infractions"],
        )
        assert (out / "results" / f"{r['clip']}.json").is_file()


@pytest.mark.parametrize("workers", [1, 2], ids=["inline", "pool"])
def test_jobs_report_their_frames_to_the_driver(short_routes, tmp_path, workers):
    """Each job's first frame report, and more while its route runs, reach the driver's ``on_frames``."""
    from b2d_data.cli.collect import _config, build_parser
    from b2d_data.collection.backends import InlineBackend, ProcessPoolBackend
    from b2d_data.collection.plan import plan_collection
    from b2d_data.collection.progress import frames_of

    config = _config(build_parser().parse_args([*_args(short_routes, tmp_path / "r"), "--no-sensors"]))
    tasks = plan_collection(config).scenarios[0].tasks[:workers]
    reports = []
    if workers == 1:
        backend = InlineBackend(tmp_path / "r", config, on_frames=reports.append)
    else:
        backend = ProcessPoolBackend(tmp_path / "r", config, workers, on_frames=reports.append)
    results = {}
    try:
        for task in tasks:
            backend.submit(task)
        while backend.running():
            results.update((str(task.route.id), result) for task, result in backend.wait(timeout=1.0))
    finally:
        backend.close()
    assert sorted(results) == sorted(str(t.route.id) for t in tasks)
    for route_id, result in results.items():
        frames = [r.frames for r in reports if r.route_id == route_id]
        assert frames and frames[0] == 1 and frames == sorted(frames), (route_id, frames)
        assert frames[-1] <= frames_of(result.ticks, result.frames)


def test_ray_requested_without_ray_is_a_clear_error(short_routes, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # as if Ray were not installed
    assert main([*_args(short_routes, tmp_path / "r"), "--ray", "auto"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pip install" in err[0], err


def test_resume_adopts_what_reached_the_disk_before_a_crash(tmp_path):
    """A record + clip written just before a kill are adopted; a failed kept clip is moved; a lone success re-runs."""
    from b2d_data.collection.corpus import reconcile
    from b2d_data.collection.job import CollectConfig, write_route_results
    from b2d_data.format import leaderboard as lb

    out = tmp_path / "data"

    def finished(route_id: int, success: bool, clip_on_disk: bool) -> str:
        name = f"Accident_Town100_Route{route_id}_Weather3"
        record = lb.RouteRecord(
            route_id=lb.record_route_id(route_id),
            status="Completed" if success else "Failed",
            town_name="Town100",
            index=0,
        )
        record.extra["b2d_collect"] = {"seed": 11, "clip": name, "success": success}
        write_route_results(out, name, record)
        if clip_on_disk:
            (out / name / "anno").mkdir(parents=True)
            (out / name / "b2d_format.json").write_text("{}")
        return name

    adopted = finished(1, True, clip_on_disk=True)
    kept_failed = finished(2, False, clip_on_disk=True)
    lost = finished(3, True, clip_on_disk=False)
    log = rl.RunLog(out / rl.LOG_FILE)
    records = [{"event": "start", "route_id": str(i)} for i in (1, 2, 3)]
    reconcile(out, records, CollectConfig(out=out, keep_failed=True), log)

    finals = {r["route_id"]: r for r in rl.final_records(rl.read_run_log(log.path))}
    assert set(finals) == {"1", "2"}  # route 3 has no clip: it is run again
    assert finals["1"]["status"] == "clip" and finals["1"]["seed"] == 11 and (out / adopted).is_dir()
    assert finals["2"]["status"] == "failed" and finals["2"]["clip_path"] == f"failed/{kept_failed}"
    assert not (out / kept_failed).exists() and (out / "failed" / kept_failed).is_dir()
    assert not (out / lost).exists()


@pytest.mark.parametrize(
    "how", ["ctrl-c on two workers", "kill (SIGTERM) in this process"], ids=["sigint-pool", "sigterm-inline"]
)
def test_interrupting_prints_no_traceback_and_records_the_routes(collection, short_routes, tmp_path, how):
    """Ctrl-C reaches every process of the terminal's group; kill only the driver. Both end quietly."""
    out = tmp_path / "data"
    out.mkdir()
    shutil.copytree(collection / "maps", out / "maps")
    ctrl_c = how.startswith("ctrl-c")
    args = _args(short_routes, out, "--encode-workers", "1", "--workers", "2" if ctrl_c else "1")
    stderr_path = tmp_path / "stderr.txt"
    with open(stderr_path, "wb") as stderr:
        proc = subprocess.Popen([sys.executable, "-m", "b2d_data.cli.collect", *args], stdout=subprocess.DEVNULL,
                                stderr=stderr, start_new_session=True, preexec_fn=sigint_default)  # fmt: skip
        helpers: set[int] = set()
        try:
            deadline = time.monotonic() + 240
            while time.monotonic() < deadline and proc.poll() is None:
                helpers |= descendants(proc.pid)
                if [p for p in out.glob(".*.tmp-*") if p.is_dir() and len(list(p.glob("anno/*.json.gz"))) >= 3]:
                    break
                time.sleep(0.05)
            helpers |= descendants(proc.pid)
            assert proc.poll() is None, "the collection ended before it could be interrupted"
            if ctrl_c:
                os.killpg(proc.pid, signal.SIGINT)
            else:
                os.kill(proc.pid, signal.SIGTERM)
            assert proc.wait(timeout=60) == 130
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    err = stderr_path.read_text()
    assert "Traceback" not in err and "leaked semaphore" not in err, err
    assert err.strip().splitlines()[-1] == "b2d-collect: interrupted; run the same command with --resume to finish"
    assert_all_exit(helpers)
    records = rl.read_run_log(out / rl.LOG_FILE)
    interrupted = [r["route_id"] for r in records if r["event"] == rl.EVENT_INTERRUPTED]
    assert interrupted and sorted(interrupted) == sorted(rl.interrupted_routes(records))
    assert all(r["detected"] == "on interrupt" for r in records if r["event"] == rl.EVENT_INTERRUPTED)



def test_kill_9_with_worker_processes_leaves_no_orphan_and_resumes(short_routes, tmp_path):
    out = tmp_path / "records"
    args = _args(short_routes, out, "--workers", "2", "--no-sensors")
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "b2d_data.cli.collect", *args],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    helpers: set[int] = set()
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            helpers |= descendants(proc.pid)
            records = rl.read_run_log(out / rl.LOG_FILE)
            if len([r for r in records if r.get("event") == "start"]) >= 2 and len(helpers) >= 3:
                break
            time.sleep(0.05)
        # Both routes are launched; kill at once: a 22 m route without sensors can end within a second
        # (a route process's modules are imported before it starts), and the test needs both mid-route.
        time.sleep(0.1)
        helpers |= descendants(proc.pid)
        assert proc.poll() is None, "the collection ended before it could be killed"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert not rl.final_records(rl.read_run_log(out / rl.LOG_FILE)), "killed too late: a route had finished"
    assert_all_exit(helpers)
    assert main([*args, "--resume"]) == 0
    records = rl.read_run_log(out / rl.LOG_FILE)
    finals = rl.final_records(records)
    assert len([r for r in finals if r["status"] == "clip"]) == N
    assert len({r["route_id"] for r in finals}) == len(finals)
    assert not rl.interrupted_routes(records)
