"""Head collapse on skewed labels, and the prior head initialisation that prevents it.

97 % of the jeep's labels are ≈ 1. With PyTorch's default init a head starts at
L̂ ≈ 0.5, every sample pushes its logit up, and Adam moves every parameter by about
the learning rate per step, so the logit rises by ≈ lr × Σ|∂logit/∂θ| per step. With
``fc_hidden=256`` (the demo and paper value) that is ≈ 1 per step already at width 16
(≈ 1.8 at the demo's width 32): the logit overshoots logit(mean) ≈ 4 and ends up at
6–9, where the sigmoid's slope is ~1e-3 of what it was; Adam's second moment still
holds the early, large gradients, the steps vanish and the head predicts a constant
(``train.collapsed_heads``). ``TrainConfig.head_init="prior"`` (``DGTNet.init_heads``)
starts each head at logit(mean training label) with its weights × 0.1.

The setup here is the smallest one that collapses reliably with the profiles' Adam at
1e-3 and batch 64 (measured, seeds 0–9 and two data seeds: the default collapsed 20 of
20 times, the prior init 0 of 20, always with a lower test MSE):

- ``fc_hidden=256``, width 16. The smoke network (width 8, ``fc_hidden=64``) moves the
  logit only ≈ 0.2 per step; it creeps up to the mean without overshooting and does
  not collapse (std ratio 0.2–0.4 after 3 epochs), nor does width 16 with 64 units.
- Low labels ≈ 0.5, as in the collected jeep data (a constant L̂ = 1 has test MSE
  0.0079 there with 3 % of the labels below 0.95). With low labels ≈ 0 the default
  init recovered from the saturation in 4 of 6 seeds: the larger error of the few low
  samples pulls the logit back.
"""

import math
import warnings
from dataclasses import replace

import numpy as np
import pytest
import torch

from dgt_lib.core.config import VEHICLES, TrainConfig
from dgt_lib.learning.model import DGTNet
from dgt_lib.learning.run import train_model
from dgt_lib.learning.synthetic import plane_patches
from dgt_lib.learning.training import collapsed_heads, head_prior
from dgt_lib.perception.dataset import PatchDataset, split_by_trajectory

# Adam at 1e-3 and batch 64 as in the profiles; 3 epochs of ~22 steps: ~2.5 s on one thread.
SETUP = TrainConfig(epochs=3, batch_size=64, learning_rate=1e-3, width=16, fc_hidden=256)
SEEDS = (0, 1, 2)
CPU = "cpu"


def slope_dataset(n: int, seed: int, vehicle: str = "jeep", steep_fraction: float = 0.03,
                  depth: float = 0.5, trajectory_offset: int = 0) -> PatchDataset:
    """Planar patches (random colours, small roughness) of one vehicle; L falls on steep uphills.

    A fraction ``steep_fraction`` of the patches has an uphill slope s ∈ [0.35, 0.7]
    (rise/run), the rest s ∈ [−0.3, 0.3]. L = 1 − depth · sigmoid((s − 0.5)/0.05) minus
    |noise| (σ 0.005): ≈ 1 on the gentle patches, ≈ 1 − depth on the steepest, and
    predictable from the patch (its height ramp and gradient channel). Split 70/15/15
    by trajectories of 10 patches.
    """
    rng = np.random.default_rng(seed)
    steep = rng.random(n) < steep_fraction
    slope = np.where(steep, rng.uniform(0.35, 0.7, n), rng.uniform(-0.3, 0.3, n))
    rough = rng.uniform(0.0, 0.1, n)
    patches = plane_patches(slope, rough, rng)
    labels = 1.0 - depth / (1.0 + np.exp(-(slope - 0.5) / 0.05))
    labels = np.clip(labels - np.abs(rng.normal(0, 0.005, n)), 0, 1).astype(np.float32)
    code = np.full(n, VEHICLES.index(vehicle), dtype=np.int8)
    trajectory = (np.arange(n) // 10 + trajectory_offset).astype(np.int32)
    pose = np.column_stack([rng.uniform(0, 100, (n, 2)), rng.uniform(0, 2 * np.pi, n)])
    return PatchDataset(patches=patches, observed=np.ones((n, 22, 7), dtype=bool),
                        labels=labels, vehicle=code, trajectory=trajectory,
                        pose=pose.astype(np.float32),
                        split=split_by_trajectory(trajectory, code, seed=seed))


@pytest.fixture(scope="module")
def jeep():
    """2,000 jeep patches, 97 % of the labels ≈ 1 (the rest ≈ 0.5 … 0.9, by slope)."""
    return slope_dataset(2000, seed=0)


@pytest.fixture(scope="module")
def jeep_and_van():
    """1,000 jeep-like patches (skewed) and 1,000 vw_van patches (half steep: balanced)."""
    a = slope_dataset(1000, seed=0, vehicle="jeep")
    b = slope_dataset(1000, seed=1, vehicle="vw_van", steep_fraction=0.5, depth=1.0,
                      trajectory_offset=10_000)
    arrays = {k: np.concatenate([a.to_arrays()[k], b.to_arrays()[k]])
              for k in a.to_arrays()}
    return PatchDataset.from_arrays(arrays)


def _train(dataset, head_init, seed, vehicles):
    with warnings.catch_warnings():  # a collapsed head warns; the metrics say so below
        warnings.simplefilter("ignore")
        return train_model(dataset, replace(SETUP, head_init=head_init), vehicles=vehicles,
                           seed=seed, progress=False, device=CPU)


# ── DGTNet.init_heads ─────────────────────────────────────────────────────────


def test_init_heads_sets_each_bias_to_the_logit_of_its_prior_and_shrinks_the_weights():
    torch.manual_seed(0)
    model = DGTNet(width=8, fc_hidden=32).eval()
    before = [h.weight.detach().clone() for h in model.vehicle_heads]
    model.init_heads([0.97, 0.5, 1.0, 0.0])
    logit = [math.log(0.97 / 0.03), 0.0, math.log(0.99 / 0.01), math.log(0.01 / 0.99)]
    for head, w, b in zip(model.vehicle_heads, before, logit, strict=True):
        assert head.bias.item() == pytest.approx(b, abs=1e-6)  # 1.0 and 0.0: clipped
        torch.testing.assert_close(head.weight, 0.1 * w)
    with torch.no_grad():
        pred = model(torch.rand(16, 6, 22, 7))  # ≈ the prior for every patch
    np.testing.assert_allclose(pred.mean(0).numpy(), [0.97, 0.5, 0.99, 0.01], atol=0.05)


def test_init_heads_rejects_bad_priors():
    model = DGTNet(vehicles=("jeep", "vw_van"), width=8, fc_hidden=16)
    with pytest.raises(ValueError, match="one mean label per head"):
        model.init_heads([0.9])
    with pytest.raises(ValueError, match=r"in \[0, 1\]"):
        model.init_heads([0.9, float("nan")])
    with pytest.raises(ValueError, match="weight_scale"):
        model.init_heads([0.9, 0.5], weight_scale=-1.0)


# ── train_model and TrainConfig.head_init ─────────────────────────────────────


class _Stop(Exception):
    pass


def _stop(*args, **kwargs):
    raise _Stop


@pytest.mark.parametrize("head_init", ["prior", "default"])
def test_train_model_starts_each_head_at_its_mean_training_label(jeep_and_van, head_init,
                                                                  monkeypatch):
    calls = []

    def spy(self, means, weight_scale=0.1):
        calls.append(list(means))
        raise _Stop  # enough: no need to train

    monkeypatch.setattr(DGTNet, "init_heads", spy)
    monkeypatch.setattr(torch.optim, "Adam", _stop)  # stop before the first step either way
    ds = jeep_and_van
    with pytest.raises(_Stop):
        train_model(ds, replace(SETUP, head_init=head_init), vehicles=("vw_van", "jeep"),
                    progress=False, device=CPU)
    if head_init == "default":  # PyTorch's init: init_heads is never called
        assert calls == []
        return
    train_idx = np.flatnonzero(ds.split == 0)
    expected = [ds.labels[train_idx][ds.vehicle[train_idx] == VEHICLES.index(v)].mean()
                for v in ("vw_van", "jeep")]
    assert calls == [pytest.approx(expected)]
    assert head_prior(ds, train_idx, ("carla_cola",)) == pytest.approx(
        [ds.labels[train_idx].mean()])  # no samples of its own: the overall mean


def test_an_unknown_head_init_is_a_clear_error(jeep):
    with pytest.raises(ValueError, match="train.head_init=zeros is not allowed: "
                                         "train.head_init must be one of prior, default"):
        train_model(jeep, TrainConfig(head_init="zeros"), vehicles=("jeep",), progress=False)


def test_prior_is_the_default():
    assert TrainConfig().head_init == "prior"


# ── the collapse itself ───────────────────────────────────────────────────────


@pytest.mark.parametrize("seed", SEEDS)
def test_default_init_collapses_on_skewed_labels_and_the_prior_init_does_not(jeep, seed):
    default = _train(jeep, "default", seed, ("jeep",)).metrics
    prior = _train(jeep, "prior", seed, ("jeep",)).metrics
    assert collapsed_heads(default) == ["jeep"], default  # constant L̂ (saturated sigmoid)
    assert collapsed_heads(prior) == [], prior
    assert prior["jeep"]["mse"] < default["jeep"]["mse"]


def test_multitask_jeep_head_collapses_with_the_default_init_only(jeep_and_van):
    """The balanced vw_van head beside it learns with either init; the jeep head only
    with the prior."""
    vehicles = ("jeep", "vw_van")
    default = _train(jeep_and_van, "default", 0, vehicles).metrics
    prior = _train(jeep_and_van, "prior", 0, vehicles).metrics
    assert collapsed_heads(default) == ["jeep"], default
    assert collapsed_heads(prior) == [], prior
    assert prior["jeep"]["mse"] < default["jeep"]["mse"]


def test_the_training_stage_reports_a_collapsed_head_once(synthetic_pipeline, monkeypatch,
                                                          capsys):
    """``dgt reproduce`` says a collapsed head once, as its own warning line (trained now
    or read from the cache), not a second time as a Python warning from the training."""
    from dgt_lib.core.config import get_profile
    from dgt_lib.learning import run, training
    from dgt_lib.learning.synthetic import synthetic_dataset
    from dgt_lib.stages.train import models_stage

    def every_head(metrics, *args, **kwargs):
        return list(metrics)

    monkeypatch.setattr(run, "collapsed_heads", every_head)
    monkeypatch.setattr(training, "collapsed_heads", every_head)
    dataset = synthetic_dataset((120, 60, 60, 40), seed=0)
    for _ in range(2):  # trained, then from the cache
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            out = models_stage(get_profile("smoke"), dataset, kinds=("multitask",),
                               progress=False)
        assert not [w for w in caught if "near-constant" in str(w.message)]
        lines = [ln for ln in capsys.readouterr().out.splitlines() if "near-constant" in ln]
        assert len(lines) == len(VEHICLES) and all("[dgt] warning: multitask" in ln
                                                   for ln in lines)
        assert out.summary.count("COLLAPSED") == len(VEHICLES)
