"""A robot the kit never trained on, from its drive log: a head fitted on the shared backbone
learns what separates the log's labels and leaves the named vehicles' network as it was;
``dgt log costmap`` compares both heads on the held-out runs and writes the robot's
directional costmap of the log's own map."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

pytest.importorskip("rosbags")

from dgt_lib.app.cli import main  # noqa: E402
from dgt_lib.beyond.conditioned import ConditionedNet  # noqa: E402
from dgt_lib.core import artifacts  # noqa: E402
from dgt_lib.core.config import get_profile  # noqa: E402
from dgt_lib.core.vehicle_file import load_vehicle  # noqa: E402
from dgt_lib.learning.model import DGTNet  # noqa: E402
from dgt_lib.learning.training import predict  # noqa: E402
from dgt_lib.logs import heads  # noqa: E402
from dgt_lib.logs.record import record_log  # noqa: E402
from dgt_lib.perception.dataset import PatchDataset  # noqa: E402
from dgt_lib.world.terrain import get_world  # noqa: E402

SMOKE = get_profile("smoke")
TRUCK_FILE = Path(__file__).resolve().parents[1] / "examples" / "my_truck.toml"
TRUCK = load_vehicle(TRUCK_FILE)


def _small_net() -> DGTNet:
    torch.manual_seed(0)
    return DGTNet(width=8, fc_hidden=16).eval()


def _coloured(n: int, seed: int) -> PatchDataset:
    """Patches red (L = 0.2) or green (L = 0.9) on flat ground, runs of 10 split 6/2/2."""
    rng = np.random.default_rng(seed)
    green = rng.random(n) < 0.5
    patches = np.zeros((n, 6, 22, 7), np.float16)
    patches[:, 0] = np.where(green, 0.1, 0.8)[:, None, None]
    patches[:, 1] = np.where(green, 0.8, 0.1)[:, None, None]
    patches[:, 3:] = rng.normal(0, 0.01, (n, 3, 22, 7))
    run = np.arange(n) // 10
    split = np.select([run % 10 < 6, run % 10 < 8], [0, 1], 2).astype(np.int8)
    return PatchDataset(patches=patches, observed=np.ones((n, 22, 7), bool),
                        labels=np.where(green, 0.9, 0.2).astype(np.float32),
                        vehicle=np.zeros(n, np.int8), trajectory=run.astype(np.int32),
                        pose=np.zeros((n, 3), np.float32), split=split)


def test_a_few_shot_head_learns_the_logs_labels_and_leaves_the_shared_network_as_it_was():
    net, data = _small_net(), _coloured(400, seed=1)
    before = {k: v.clone() for k, v in net.state_dict().items()}
    named = predict(net, data.patches)
    head = heads.few_shot_head(net, data, "my_truck")
    errors = heads.compare_heads(data, {"few-shot": head})
    assert errors["prior"]["mae"] > 0.3  # a constant cannot tell red from green
    assert errors["few-shot"]["mae"] < 0.1  # the head on the frozen features can
    assert errors["few-shot"]["n"] == int((data.split == 2).sum())
    assert all(torch.equal(before[k], v) for k, v in net.state_dict().items())
    assert np.array_equal(predict(net, data.patches), named)  # the named vehicles' heads


def test_a_log_whose_runs_are_all_training_has_no_held_out_error():
    data = _coloured(40, seed=2)
    data.split[:] = 0
    with pytest.raises(ValueError, match="no held-out run"):
        heads.compare_heads(data, {})


@pytest.fixture(scope="module")
def truck_log(tmp_path_factory):
    """Three 8 s drives of a truck the kit never trained on, as one MCAP log."""
    path, _ = record_log(get_world("training", SMOKE), TRUCK,
                         tmp_path_factory.mktemp("log") / "truck.mcap", seed=5,
                         config=replace(SMOKE.collect, episode_duration_s=8.0), runs=3)
    return path


def test_dgt_log_costmap_compares_both_heads_and_writes_the_robots_costmap(
        truck_log, tmp_path, monkeypatch, capsys):
    rasterio = pytest.importorskip("rasterio")
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / "data"))
    monkeypatch.setattr("dgt_lib.stages.costmaps.load_model",
                        lambda prof, progress=True: _small_net())
    monkeypatch.setattr(heads, "zero_shot_head", lambda prof, spec, progress=True:
                        ConditionedNet(width=8, fc_hidden=16).for_vehicles([spec]).eval())
    out = tmp_path / "truck.tif"
    assert main(["log", "costmap", str(truck_log), "--vehicle", str(TRUCK_FILE),
                 "--out", str(out), "--profile", "smoke", "--set", "collect.episode_duration_s=8"]
                ) == 0
    printed = capsys.readouterr().out
    for name in ("prior", "few-shot", "zero-shot"):
        assert f"held-out runs, {name:>9}: MAE" in printed
    with rasterio.open(out) as tif:
        cost = tif.read()
    assert tif.count == SMOKE.costmap.n_headings + 1  # K heading layers and the occupancy
    layers = cost[:SMOKE.costmap.n_headings]
    assert np.isfinite(layers).any() and np.nanmin(layers) >= 0 and np.nanmax(layers) <= 1
    assert main(["log", "costmap", str(truck_log), "--vehicle", str(TRUCK_FILE), "--out",
                 str(tmp_path / "nav2") + "/", "--format", "nav2", "--head", "zero-shot",
                 "--profile", "smoke", "--set", "collect.episode_duration_s=8"]) == 0
    written = sorted(p.name for p in (tmp_path / "nav2").glob("*.yaml"))
    assert len(written) == SMOKE.costmap.n_headings + 1  # a map per heading, the occupancy
    assert all(name.startswith("my_truck_zero-shot") for name in written)


def test_dgt_log_plan_plans_with_the_robots_head_round_a_block_on_your_terrain(
        truck_log, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / "data"))
    loaded = []
    monkeypatch.setattr("dgt_lib.stages.costmaps.load_model", lambda prof, progress=True:
                        loaded.append(prof.train.inputs) or _small_net())
    monkeypatch.setattr("dgt_lib.stages.costmaps.ensure_tau_s", lambda prof: 0.6)
    monkeypatch.setattr(heads, "zero_shot_head", lambda prof, spec, progress=True:
                        ConditionedNet(width=8, fc_hidden=16).for_vehicles([spec]).eval())
    heights = np.zeros((80, 120), np.float32)
    heights[20:60, 55:65] = 3.0  # a block between start and goal
    np.save(tmp_path / "tiny.npy", heights)
    assert main(["log", "plan", str(truck_log), "--vehicle", str(TRUCK_FILE), "--world",
                 str(tmp_path / "tiny.npy"), "--start", "8,16,0", "--goal", "40,16",
                 "--profile", "smoke", "--set", "collect.episode_duration_s=8"]) == 0
    out = capsys.readouterr().out
    assert f"few-shot head from the log {truck_log}" in out and "found: length" in out
    length = float(out.split("found: length ")[1].split(" m")[0])
    assert length > 34.0  # round the block: the straight line is 32 m
    assert loaded == ["geometry"]  # a height map has no colour: the geometry network's head


def test_dgt_log_plan_on_a_world_it_cannot_load_stops_before_reading_the_log(
        truck_log, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / "data"))
    assert main(["log", "plan", str(truck_log), "--vehicle", str(TRUCK_FILE), "--world",
                 "nowhere", "--start", "1,2,0", "--goal", "3,4", "--profile", "smoke"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dgt log plan: error: 'nowhere' is neither a world")
    assert not (tmp_path / "data" / "logs").exists()  # nothing ingested
