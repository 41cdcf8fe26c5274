import re
import subprocess

import numpy as np
import pytest

from dgt_lib.core.config import get_profile
from dgt_lib.core.geometry import GridSpec
from dgt_lib.evaluation.experiments import ExperimentResult
from dgt_lib.evaluation.queries import Query
from dgt_lib.evaluation.trials import TrialResult, TrialTask
from dgt_lib.mapping.world_maps import WorldMaps
from dgt_lib.navigation.outcome import TrialOutcome
from dgt_lib.perception.bev import BEVMap
from dgt_lib.viz import recording as dgt_rr
from dgt_lib.viz.recording_layout import Layout, ViewSpec
from dgt_lib.world.worlds import from_heightmap


def uncovered(layout: Layout, entities=None) -> list[str]:
    """The logged entity paths (or ``entities``) that no view of ``layout`` shows."""
    views = [v for side in layout.views() for v in side]
    return sorted(p for p in (layout.entities if entities is None else entities)
                  if not any(v.shows(p.strip("/")) for v in views))

SMOKE = get_profile("smoke")


def _rrd_print(path) -> str:
    done = subprocess.run([dgt_rr._rerun_exe(), "rrd", "print", str(path)],
                          capture_output=True, text=True, check=True)
    return done.stdout + done.stderr


def _recording_entities(printed: str) -> set[str]:
    """Entity paths of the file's recording store (not its blueprint store), as
    ``rerun rrd print`` lists them, without rerun's own ``/__properties``."""
    entities, store = set(), None
    for line in printed.splitlines():
        if line.strip() in ("Recording,", "Blueprint,"):
            store = line.strip(" ,")
        m = re.match(r"Chunk\(\S+\) with .* - (/\S+) - data columns", line)
        if m and store == "Recording" and not m.group(1).startswith("/__"):
            entities.add(m.group(1).strip("/"))
    return entities


def _file_views(path) -> list[ViewSpec]:
    """The views of the blueprint stored in the file, read from `rerun rrd print -vvv`:
    each view's origin (``/view/<id>``) and contents (``/view/<id>/ViewContents``)."""
    printed = subprocess.run([dgt_rr._rerun_exe(), "rrd", "print", "-vvv", str(path)],
                             capture_output=True, text=True, check=True).stdout
    origins, contents, entity = {}, {}, None
    for line in printed.splitlines():
        m = re.match(r"Chunk\(\S+\) with .* - (/\S+) - ", line)
        if m:
            entity = m.group(1)
        elif line.startswith("│ │ row_") and entity:
            last = line.split("┆")[-1].strip(" │").removeprefix("[").removesuffix("]")
            if m := re.fullmatch(r"/view/([0-9a-f-]+)", entity):
                origins[m.group(1)] = last
            elif m := re.fullmatch(r"/view/([0-9a-f-]+)/ViewContents", entity):
                contents[m.group(1)] = tuple(q.strip() for q in last.split(","))
    return [ViewSpec(object, origins[i], i, contents.get(i, ("$origin/**",)))
            for i in origins]


def _tiny_experiment(n_trials=2):
    """A 12 m × 16 m ramp, its BEV and two methods' costmaps, and trials that drove it."""
    heights = np.tile(np.linspace(0.0, 2.0, 40), (30, 1))
    world = from_heightmap(heights, 0.4, name="ramp")
    channels = np.zeros((6, 30, 40), np.float32)
    channels[3] = heights
    bev = BEVMap(world.grid, channels, np.ones((30, 40), bool), np.ones((30, 40), np.int64))
    rng = np.random.default_rng(0)
    maps = WorldMaps("ramp", bev, np.zeros((30, 40), np.uint8), 0.5,
                     {(m, "jeep"): rng.random((8, 30, 40)) for m in ("dgt", "binary")})
    results = []
    for i in range(n_trials):
        for m in ("dgt", "binary"):
            task = TrialTask("experiment1", "ramp", m, "jeep", Query((1, 1, 0), (10, 8), "A"),
                             i, "smoke", 0)
            t = np.linspace(0.0, 4.0, 21)
            traj = np.column_stack([t, 1 + 2 * t, 1 + 1.5 * t, np.zeros_like(t)])
            results.append(TrialResult(task, TrialOutcome(True, "success", 4.0),
                                       path=traj[:, 1:4], trajectory=traj,
                                       speed=np.full(21, 2.5)))
    return ExperimentResult("experiment1", "ramp", results), world, maps


def test_every_entity_of_an_experiment_recording_is_in_a_view(tmp_path):
    """What a learner opens: every entity the file holds is shown by some view of the
    blueprint stored in the same file (both as `rerun rrd print` lists them)."""
    result, world, maps = _tiny_experiment()
    path = tmp_path / "experiment1.rrd"
    layout = dgt_rr.log_experiment(result, world, maps, path, SMOKE)
    printed = _rrd_print(path)
    entities = _recording_entities(printed)
    assert {"world/terrain", "maps/bev/height", "maps/occupancy", "notes/results",
            "world/costmap/jeep/dgt/heading_7", "world/vehicle/binary/jeep_1_A/pose"} <= entities
    assert entities == layout.entities  # nothing logged behind the layout's back
    views = _file_views(path)
    assert len(views) == len([v for side in layout.views() for v in side]) > 5
    assert sorted(e for e in entities if not any(v.shows(e) for v in views)) == []
    assert uncovered(layout, entities) == []
    left, right = layout.views()
    assert [v.name for v in right if v.origin == "world"] == [
        "costmap Binary · jeep", "costmap DGT-Map · jeep"]
    assert "Blueprint," in printed and "make_active: true" in printed  # the file carries it


def test_the_coverage_check_finds_an_entity_no_view_shows():
    layout = Layout(entities={"world/terrain", "maps/occupancy", "stray/thing"})
    assert uncovered(layout) == ["stray/thing"]
    # the world view leaves costmaps to their own views: one not registered is uncovered
    layout.entities.add("world/costmap/jeep/dgt/heading_0")
    assert uncovered(layout) == ["stray/thing", "world/costmap/jeep/dgt/heading_0"]
    layout.costmaps[("jeep", "dgt")] = 1
    assert uncovered(layout) == ["stray/thing"]


def test_recording_id_names_the_profile_and_seed(tmp_path):
    """Demo and paper recordings of one experiment opened together do not merge."""
    ids = []
    for prof in (SMOKE, get_profile("demo"), SMOKE.with_(seed=3)):
        path = tmp_path / f"{prof.name}-{prof.seed}.rrd"
        with dgt_rr.Recording(path, "experiment1", prof) as rec:
            rec.log_text("results", "x")
        printed = _rrd_print(path)
        ids.append(re.search(r'Recording,\s*"[^"]+",\s*"([^"]+)"', printed).group(1))
    assert ids == ["experiment1/smoke/seed-0", "experiment1/demo/seed-0",
                   "experiment1/smoke/seed-3"]


def test_trials_play_one_after_another_and_the_vehicle_is_an_oriented_box(tmp_path):
    result, world, maps = _tiny_experiment(n_trials=1)
    path = tmp_path / "e.rrd"
    with dgt_rr.Recording(path, "e", SMOKE) as rec:
        for i, r in enumerate(result.results):
            rec.log_trajectory(f"t{i}", r.trajectory[:, 0], r.trajectory[:, 1:4],
                               vehicle="jeep")
    assert rec.layout.runs == 2
    printed = subprocess.run([dgt_rr._rerun_exe(), "rrd", "print", "-vvv", str(path)],
                             capture_output=True, text=True, check=True).stdout
    assert "Boxes3D:quaternions" in printed and "elapsed" in printed and "trial" in printed
    # direction of travel: (2, 1.5) per second → yaw = atan2(1.5, 2)
    assert dgt_rr.motion_yaw(result.results[0].trajectory[:, 1:3]) == pytest.approx(
        np.full(21, np.arctan2(1.5, 2.0)))


def test_motion_yaw_keeps_the_heading_through_a_stop():
    xy = np.array([[0, 0], [1, 0], [1, 0], [1, 1]], float)
    assert dgt_rr.motion_yaw(xy) == pytest.approx([0, 0, np.pi / 2, np.pi / 2])
    # standing still first: the first heading it drives
    xy = np.array([[0, 0], [0, 0], [0, -1], [0, -1]], float)
    assert dgt_rr.motion_yaw(xy) == pytest.approx([-np.pi / 2] * 4)
    assert dgt_rr.motion_yaw(np.zeros((3, 2))).tolist() == [0, 0, 0]


def test_recording_with_every_kind_of_entity_verifies(tmp_path):
    grid = GridSpec((0.0, 0.0), 0.4, (30, 40))
    x, y = grid.cell_centers()
    heights = 0.1 * x
    path = tmp_path / "runs" / "demo.rrd"
    with dgt_rr.Recording(path, "test", SMOKE) as rec:
        rec.log_terrain(heights, None, grid)
        channels = np.zeros((6, 30, 40), np.float32)
        channels[3] = heights
        rec.log_bev(channels, np.ones((30, 40), bool))
        rec.log_costmap(np.random.default_rng(0).random((8, 30, 40)), grid, "jeep")
        rec.log_occupancy(np.zeros((30, 40), np.uint8))
        t = np.linspace(0, 5, 20)
        xyz = np.stack([t, t, np.zeros_like(t)], 1)
        rec.log_path("dgt", xyz)
        rec.log_trajectory("trial_0", t, xyz, {"speed": np.full(20, 5.0)}, vehicle="jeep")
        rgb = np.zeros((12, 16, 3), np.uint8)
        rec.log_frame("f0", rgb, np.ones((12, 16), np.float32), np.zeros(3), np.eye(3), 10.0)
        rec.log_text("results", "| a | b |\n|---|---|\n| 1 | 2 |")
    assert path.stat().st_size > 1000
    assert uncovered(rec.layout) == []
    dgt_rr.verify(path)


def test_a_recording_replaces_its_file_only_when_complete(tmp_path):
    """A recording stopped half-way (``dgt plan`` interrupted while it logs) leaves the
    earlier file as it was; a complete one replaces it whole and leaves nothing beside it."""
    grid = GridSpec((0.0, 0.0), 0.4, (30, 40))
    path = tmp_path / "plan.rrd"
    path.write_bytes(b"the earlier recording")
    rec = dgt_rr.Recording(path, "test", SMOKE)
    rec.log_terrain(0.1 * grid.cell_centers()[0], None, grid)
    rec.stream.flush()
    assert path.read_bytes() == b"the earlier recording"  # still logging: untouched
    rec.close()
    dgt_rr.verify(path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.rrd"]


def test_map_image_puts_north_at_the_top():
    grid_array = np.array([[0, 0], [1, 1]])  # row 1 is further north (larger y)
    assert dgt_rr._map_image(grid_array)[0].tolist() == [1, 1]


def test_show_sends_the_file_to_a_notebook_viewer(tmp_path, monkeypatch):
    """Outside pytest, `show` builds rerun's notebook widget with the panels open and
    hands it the file's bytes; under pytest (nbmake) it only names the file."""
    path = tmp_path / "t.rrd"
    with dgt_rr.Recording(path, "t", SMOKE) as rec:
        rec.log_text("x", "hello")
    dgt_rr.show(path)  # PYTEST_CURRENT_TEST is set: no widget, no browser needed
    rerun_notebook = pytest.importorskip("rerun_notebook")
    sent, shown = [], []
    monkeypatch.delenv("PYTEST_CURRENT_TEST")
    monkeypatch.setattr(rerun_notebook.Viewer, "send_rrd", lambda self, data: sent.append(data))
    monkeypatch.setattr("IPython.display.display", lambda obj: shown.append(obj))
    dgt_rr.show(path, height=300)
    assert sent == [path.read_bytes()]
    assert shown[0]._panel_states["blueprint"] == "expanded" and shown[0]._height == 300


@pytest.mark.parametrize("content", [b"garbage", None])
def test_verify_rejects_a_broken_file(tmp_path, content):
    good = tmp_path / "good.rrd"
    with dgt_rr.Recording(good, "t", SMOKE) as rec:
        rec.log_text("x", "hello")
    bad = tmp_path / "bad.rrd"
    bad.write_bytes(content if content is not None else good.read_bytes()[:100])
    with pytest.raises(RuntimeError, match="verify"):
        dgt_rr.verify(bad)
