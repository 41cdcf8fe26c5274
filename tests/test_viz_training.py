"""The computing parts of the training figures (notebook 03): parameter and shape tables, head
gradients of the masked loss, own-head predictions, metric tables, inference speed and the
width trade-off. (Pure plotting runs in the notebook.)"""

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest
import torch

from dgt_lib import viz
from dgt_lib.core.config import VEHICLES, TrainConfig
from dgt_lib.learning.model import DGTNet, count_parameters
from dgt_lib.learning.synthetic import synthetic_dataset
from dgt_lib.learning.training import predict

TINY = TrainConfig(epochs=1, batch_size=32, width=2, fc_hidden=8)


@pytest.fixture(scope="module")
def small_data():
    return synthetic_dataset((40, 30, 30, 20), seed=3, patches_per_trajectory=5)


def _table_numbers(table: str) -> dict[str, int]:
    rows = [line.split("|")[1:-1] for line in table.splitlines()[2:]]
    return {r[0].strip(" *"): int(r[1].strip(" *").replace(",", "")) for r in rows}


def test_parameter_table_parts_add_up_to_the_model():
    torch.manual_seed(0)
    net = DGTNet(width=4, fc_hidden=16)
    counts = _table_numbers(viz.parameter_table(net))
    total = counts.pop("total")
    assert total == count_parameters(net)
    assert sum(counts.values()) == total
    assert counts["RGB branch (ResNet-18)"] == count_parameters(net.rgb)
    assert counts["4 vehicle heads (linear + sigmoid)"] == 4 * (16 + 1)


def test_shape_trace_follows_a_patch_through_both_branches_to_the_heads():
    torch.manual_seed(0)
    net = DGTNet(("jeep", "vw_van"), width=4, fc_hidden=16).train()
    steps = viz.shape_trace(net, torch.zeros(3, 6, 22, 7))
    trace = dict(steps)
    assert net.training, "the model's mode is restored"
    assert trace["rgb: input channels"] == trace["height: input channels"] == (3, 3, 22, 7)
    assert trace["rgb: conv 7×7 /2"] == (3, 4, 11, 4)
    assert trace["height: layer4 /2"] == (3, 32, 1, 1)  # 8 · width channels, one cell
    assert trace["concatenation"] == (3, 64)
    assert trace["shared embedding z (FC + ReLU)"] == (3, 16)
    assert trace["heads + sigmoid: L̂ per vehicle"] == (3, 2)
    assert steps[0][1] == (3, 6, 22, 7) and steps[-1][1] == (3, 2)
    assert "| concatenation | (3, 64) |" in viz.shape_table(steps)
    assert not net.rgb._forward_hooks and not net.fc._forward_pre_hooks, "hooks removed"


def test_only_the_heads_of_vehicles_in_the_batch_get_a_gradient(small_data):
    torch.manual_seed(0)
    net = DGTNet(width=2, fc_hidden=8).train()
    pick = np.concatenate([np.flatnonzero(small_data.vehicle == v)[:3] for v in (0, 3)])
    norms = viz.head_gradient_norms(
        net, torch.from_numpy(small_data.patches[pick].astype(np.float32)),
        torch.from_numpy(small_data.labels[pick]),
        torch.from_numpy(small_data.vehicle[pick].astype(np.int64)))
    assert norms.shape == (4,)
    assert norms[0] > 0 and norms[3] > 0
    assert norms[1] == 0 and norms[2] == 0
    assert all(p.grad is None for p in net.parameters()), "gradients cleared afterwards"


def test_own_head_predictions_pick_each_samples_vehicle_column(small_data):
    torch.manual_seed(0)
    multi = DGTNet(width=2, fc_hidden=8).eval()
    solo = DGTNet(("vw_van",), width=2, fc_hidden=8).eval()
    test = small_data.part("test")
    out = viz.own_head_predictions(multi, {"vw_van": solo}, test)
    full = predict(multi, test.patches)
    assert np.allclose(out["multi-task"], full[np.arange(len(test)), test.vehicle])
    van = test.vehicle == VEHICLES.index("vw_van")
    assert van.any() and (~van).any()
    assert np.allclose(out["single-task"][van], predict(solo, test.patches[van])[:, 0])
    assert np.isnan(out["single-task"][~van]).all()


def test_comparison_table_lists_every_vehicle_and_the_mse_difference():
    m = {"n": 10, "mse": 0.2, "mae": 0.3, "spearman": 0.5}
    metrics = {"multi-task": {v: dict(m) for v in VEHICLES},
               "single-task": {"jeep": dict(m, mse=0.25), "vw_van": dict(m, mse=0.1)}}
    table = viz.comparison_table(metrics, {"jeep": 100, "vw_van": 40})
    rows = {r.split("|")[1].strip(): [c.strip() for c in r.split("|")[2:-1]]
            for r in table.splitlines()[2:]}
    assert list(rows) == list(VEHICLES)
    assert rows["jeep"][:2] == ["100", "10"]
    assert rows["jeep"][-1] == "+0.0500"  # single-task worse: multi-task helped
    assert rows["vw_van"][-1] == "-0.1000"
    assert rows["carla_cola"][3] == "–" and rows["carla_cola"][-1] == "–"


def test_inference_rate_counts_patches_per_second(small_data):
    net = DGTNet(width=2, fc_hidden=8).eval()
    rate = viz.inference_rate(net, small_data.patches[:64], repeats=2)
    assert np.isfinite(rate) and rate > 0
    with pytest.raises(ValueError):
        viz.inference_rate(net, small_data.patches[:0])


def test_width_tradeoff_trains_one_model_per_width(small_data):
    rows = viz.width_tradeoff(small_data, TINY, [1, 2], epochs=1, n_patches=64, progress=False)
    assert [r["width"] for r in rows] == [1, 2]
    assert rows[0]["parameters"] < rows[1]["parameters"]
    assert rows[1]["parameters"] == count_parameters(DGTNet(width=2, fc_hidden=8))
    for r in rows:
        assert 0 <= r["test_mse"] <= 1 and r["patches_per_s"] > 0 and r["train_s"] > 0
    assert viz.tradeoff_table(rows).count("\n") == 3
