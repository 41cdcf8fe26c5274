"""The vehicle-conditioned network: DGTNet's outputs for the named vehicles, the kit's own
training loop, a spec normalisation carried by the state dict, and a never-seen vehicle
between two trained ones predicted from its properties alone."""

import math
import warnings
from dataclasses import replace

import numpy as np
import pytest
import torch

from dgt_lib.beyond.conditioned import (
    FEATURES,
    ConditionedNet,
    spec_statistics,
    spec_training_set,
    spec_vector,
)
from dgt_lib.core.config import VEHICLES, TrainConfig
from dgt_lib.core.vehicle_generator import generated_vehicles
from dgt_lib.core.vehicle_spec import GRAVITY_MPS2
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.learning.model import DGTNet
from dgt_lib.learning.run import train_network
from dgt_lib.learning.synthetic import plane_patches, synthetic_dataset
from dgt_lib.learning.training import TrainingSet, channel_statistics, fit
from dgt_lib.perception.dataset import TRAIN, VAL, PatchDataset

TINY = {"width": 4, "fc_hidden": 8, "film_hidden": 8}


def test_for_the_named_vehicles_it_answers_in_dgtnets_shape_and_order():
    torch.manual_seed(0)
    net, ref = ConditionedNet(**TINY).eval(), DGTNet(width=4, fc_hidden=8).eval()
    x = torch.from_numpy(synthetic_dataset((3, 3, 3, 3)).patches.astype(np.float32))
    out = net(x)
    assert out.shape == ref(x).shape == (12, 4) and net.vehicles == VEHICLES
    assert torch.all((out >= 0) & (out <= 1))
    z = net.embed(x)
    assert torch.equal(net.heads(z), out)
    assert torch.allclose(net.heads_for(z, list(VEHICLES)), out)
    assert net.head_index("mercedes_van") == 2
    assert not any(k.startswith("vehicle_heads") for k in net.state_dict())
    assert net.architecture()["name"] == "ConditionedNet"
    # the FiLM generator starts at zero: every vehicle starts with the same head
    assert torch.allclose(out, out[:, :1].expand_as(out))


def test_init_heads_starts_every_vehicle_at_its_own_prior():
    torch.manual_seed(0)
    net = ConditionedNet([*VEHICLES, *generated_vehicles(3)], **TINY).eval()
    x = torch.from_numpy(synthetic_dataset((3, 3, 3, 3)).patches.astype(np.float32))
    priors = [0.97, 0.6, 0.3, 0.1, 0.5, 0.8, 0.2]
    net.init_heads(priors)
    assert torch.allclose(net(x), torch.tensor(priors).expand(12, 7), atol=0.01)
    with pytest.raises(ValueError, match="one mean label in"):
        net.init_heads([0.5] * 6)


def test_spec_vectors_normalise_and_come_back_and_the_state_dict_carries_them():
    train = [get_vehicle(v) for v in VEHICLES] + generated_vehicles(6)
    net = ConditionedNet(train, **TINY)
    c = net.normalise(net.spec_raw)
    assert torch.allclose(net.spec_mean + net.spec_std * c, net.spec_raw, atol=1e-4)
    varying = np.ptp(np.stack([spec_vector(v) for v in train]), axis=0) > 0
    assert torch.allclose(c.mean(0), torch.zeros(len(FEATURES)), atol=1e-5)
    assert torch.allclose(c.std(0, unbiased=False)[varying], torch.ones(int(varying.sum())),
                          atol=1e-4)
    mean, std = spec_statistics([get_vehicle("vw_van")] * 2)  # nothing varies: σ = 1
    assert np.array_equal(std, np.ones(len(FEATURES)))
    assert np.array_equal(mean, spec_vector("vw_van"))
    # a fresh net (other vehicles' statistics) loading the checkpoint answers the same
    with torch.no_grad():  # vehicles answer differently once the FiLM layer is not zero
        net.film[2].weight.normal_(generator=torch.Generator().manual_seed(1))
    other = ConditionedNet(train, reference=[get_vehicle("jeep")] * 2, **TINY)
    assert not torch.equal(other.spec_mean, net.spec_mean)
    other.load_state_dict(net.state_dict())
    assert torch.equal(other.spec_mean, net.spec_mean)
    assert torch.equal(other.spec_std, net.spec_std)
    x = torch.from_numpy(synthetic_dataset((2, 2, 2, 2)).patches.astype(np.float32))
    out = net.eval()(x)
    assert torch.equal(other.eval()(x), out)
    assert not torch.allclose(out, out[:, :1].expand_as(out))


def _with_climb(climb_deg: float):
    """The vw_van with the drive torque that makes its torque-limited climb ``climb_deg``."""
    van = get_vehicle("vw_van")
    torque = (math.sin(math.radians(climb_deg)) * van.mass_kg * GRAVITY_MPS2
              * van.wheel_radius_m / van.driven_wheels)
    return replace(van, name=f"van_{climb_deg:g}", drive_torque_nm=torque)


def _label(climb_deg, grade_deg):
    """Synthetic truth: a vehicle holds grades below its max climb (a 3° wide sigmoid)."""
    return 1.0 / (1.0 + np.exp((grade_deg - climb_deg) / 3.0))


def _climb_dataset(specs, per_vehicle, rng) -> tuple[PatchDataset, np.ndarray]:
    column = np.repeat(np.arange(len(specs)), per_vehicle)
    grade = rng.uniform(-5, 55, len(column))  # [deg], uphill positive
    patches = plane_patches(np.tan(np.radians(grade)), np.zeros(len(column)), rng)
    labels = _label(np.array([s.max_climb_deg for s in specs])[column], grade)
    n = len(column)
    split = np.where(rng.random(n) < 0.85, TRAIN, VAL).astype(np.int8)
    return PatchDataset(patches, np.ones((n, 22, 7), bool), labels.astype(np.float32),
                        column.astype(np.int8), np.arange(n, dtype=np.int32),
                        np.zeros((n, 3), np.float32), split), grade


def test_a_vehicle_between_two_trained_ones_is_predicted_from_its_climb():
    """Seven vans that differ only in drive torque (max climb 10° … 40°) train with
    ``fit``; a van of 22° (between the trained 18° and 26°) is predicted to hold
    grades up to ≈ 22°, closer to its truth than either neighbour's labels are."""
    torch.manual_seed(0)
    train = [_with_climb(c) for c in (10, 14, 18, 26, 30, 36, 40)]
    held = _with_climb(22)
    data, _ = _climb_dataset(train, 80, np.random.default_rng(0))
    cfg = TrainConfig(epochs=16, batch_size=32, learning_rate=3e-3, lr_schedule="cosine",
                      selection="last", width=4, fc_hidden=16)
    net = ConditionedNet(train, width=4, fc_hidden=16, film_hidden=16)
    net.set_normalization(*channel_statistics(data.patches, np.flatnonzero(data.split == 0)))
    net.init_heads([float(data.labels[data.vehicle == j].mean()) for j in range(len(train))])
    ts = spec_training_set(data, net.vehicles, cfg)
    fit(net, torch.optim.Adam(net.parameters(), lr=cfg.learning_rate), ts, cfg,
        np.random.default_rng(0), torch.device("cpu"))
    net.eval()
    grades = np.repeat(np.arange(0.0, 50.5, 0.5), 8)  # [deg], 8 patches each
    patches = plane_patches(np.tan(np.radians(grades)), np.zeros(len(grades)),
                            np.random.default_rng(1))
    with torch.no_grad():
        pred = net.heads_for(net.embed(torch.from_numpy(patches.astype(np.float32))),
                             [held])[:, 0].numpy()
    truth = _label(held.max_climb_deg, grades)
    mae = np.abs(pred - truth).mean()
    neighbour = min(np.abs(_label(c, grades) - truth).mean() for c in (18, 26))
    assert mae < 0.5 * neighbour, (mae, neighbour)
    per_grade = pred.reshape(-1, 8).mean(axis=1)
    held_until = np.arange(0.0, 50.5, 0.5)[np.argmax(per_grade < 0.5)]  # first grade L̂ < ½
    assert abs(held_until - 22.0) <= 2.0, held_until


def test_the_kits_training_set_trains_it_for_the_named_vehicles():
    torch.manual_seed(0)
    data = synthetic_dataset((40, 30, 30, 30))
    cfg = TrainConfig(epochs=3, batch_size=16, width=4, fc_hidden=8)
    ts = TrainingSet.select(data, None, cfg)
    net = ConditionedNet(**TINY)
    net.set_normalization(*channel_statistics(data.patches, ts.train_index))
    before = ts.validation_loss(net, torch.device("cpu"))
    state = fit(net, torch.optim.Adam(net.parameters(), lr=3e-3), ts, cfg,
                np.random.default_rng(0), torch.device("cpu"))
    assert state.best_val < before
    # and the run around fit (priors, test metrics) takes it as it takes a DGTNet
    other = ConditionedNet(**TINY)
    other.set_normalization(*channel_statistics(data.patches, ts.train_index))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # one epoch: heads flagged as collapsed, rightly
        result = train_network(other, ts, replace(cfg, epochs=1), progress=False)
    assert isinstance(result.model, ConditionedNet) and set(result.metrics) == set(VEHICLES)


def test_a_training_set_of_any_vehicles_checks_its_columns():
    data, _ = _climb_dataset([_with_climb(10), _with_climb(20)], 10, np.random.default_rng(0))
    cfg = TrainConfig(epochs=1, batch_size=4)
    assert spec_training_set(data, ("a", "b"), cfg).heads.max() == 1
    with pytest.raises(ValueError, match="columns 0 … 0"):
        spec_training_set(data, ("a",), cfg)
