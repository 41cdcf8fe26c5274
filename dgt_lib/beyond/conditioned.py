"""A network conditioned on vehicle properties: one head for every vehicle, even one never
driven (the paper's future work, "conditioning directly on vehicle properties";
docs/vehicles.md).

:class:`~dgt_lib.learning.model.DGTNet` has one head per named vehicle, so a new vehicle
needs new data. :class:`ConditionedNet` keeps DGTNet's backbone (both ResNet-18 branches
and the FC layer: it *is* a DGTNet with other heads) and replaces the per-vehicle heads by
one head modulated by the vehicle's properties, FiLM-style (Perez et al. 2018)::

    z = DGTNet.embed(P)                                    (B, F)   shared embedding
    c_v = (s(v) − μ_s) / σ_s                               (V, D)   normalised spec vector
    [γ_v, β_v, δ_v] = W₂ ReLU(W₁ c_v + b₁) + b₂            (V, 2F+1) FiLM parameters
    L̂_v(P) = σ(w · ReLU((1 + γ_v) ⊙ z + β_v) + b + δ_v)    (B, V)

s(v) is :func:`spec_vector` (:data:`FEATURES`: geometry, mass, torques, driven wheels,
steering, the torque-limited climb), μ_s and σ_s its mean and spread over the training
vehicles, kept as buffers so a checkpoint carries them. W₂, b₂ start at zero, so every
vehicle starts with the same head, except that :meth:`ConditionedNet.init_heads` sets
the offsets δ_v to start each vehicle at its own prior, as DGTNet's heads start.

It trains with the kit's own loop (:func:`~dgt_lib.learning.training.fit`, also inside
:func:`~dgt_lib.learning.run.train_network`: the masked loss picks each sample's vehicle
column) on a ``TrainingSet.select`` of the named vehicles, or on
:func:`spec_training_set` for any vehicles. :meth:`ConditionedNet.heads_for` evaluates any
spec, e.g. one read by :func:`~dgt_lib.core.vehicle_file.load_vehicle`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from dgt_lib.core.config import VEHICLES, TrainConfig
from dgt_lib.core.vehicle_spec import CameraMount, VehicleSpec
from dgt_lib.core.vehicles import get_vehicle, is_named
from dgt_lib.learning.checkpoints import TrainResult, load_checkpoint
from dgt_lib.learning.model import HEAD_PRIOR_CLIP, ArchitectureMismatchError, DGTNet
from dgt_lib.learning.run import train_network
from dgt_lib.learning.training import (
    TrainingSet,
    channel_statistics,
    resolve_device,
)
from dgt_lib.perception.dataset import TRAIN, VAL, PatchDataset

FEATURES: dict[str, Callable[[VehicleSpec], float]] = {
    "wheelbase_m": lambda v: v.wheelbase_m,
    "track_m": lambda v: v.track_m,
    "length_m": lambda v: v.length_m,
    "width_m": lambda v: v.width_m,
    "height_m": lambda v: v.height_m,
    "ground_clearance_m": lambda v: v.ground_clearance_m,
    "wheel_radius_m": lambda v: v.wheel_radius_m,
    "log_mass_kg": lambda v: math.log(v.mass_kg),
    "log_drive_torque_nm": lambda v: math.log(v.drive_torque_nm),
    "log_brake_torque_nm": lambda v: math.log(v.brake_torque_nm),
    "driven_wheels": lambda v: float(v.driven_wheels),
    "max_steer_deg": lambda v: math.degrees(v.max_steer_rad),
    "max_climb_deg": lambda v: v.max_climb_deg,
}
"""The spec vector s(v): what a vehicle's locomotion depends on, masses and torques as
logarithms (they span a factor of six over the training vehicles)."""
MIN_SPREAD = 1e-6  # a feature that spreads less over the training vehicles gets σ = 1


def spec_vector(spec: VehicleSpec | str) -> np.ndarray:
    """s(v): the :data:`FEATURES` of one vehicle (a spec or a named vehicle), (D,) float64."""
    v = get_vehicle(spec)
    return np.array([f(v) for f in FEATURES.values()], dtype=np.float64)


def spec_statistics(specs: Sequence[VehicleSpec | str]) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation (each (D,)) of the spec vectors of the training
    vehicles; a feature that does not vary among them gets σ = 1 (it is then only
    shifted)."""
    if not specs:
        raise ValueError("spec statistics need at least one vehicle")
    s = np.stack([spec_vector(v) for v in specs])
    std = s.std(axis=0)
    return s.mean(axis=0), np.where(std > MIN_SPREAD, std, 1.0)


class ConditionedNet(DGTNet):
    """DGTNet's backbone with a head conditioned on the vehicle's spec (module docstring).

    Args:
        vehicles: the heads, in output order: specs or names of named vehicles (distinct
            names). Output column j is vehicle ``vehicles[j]``, as DGTNet's.
        width, fc_hidden: the backbone's size, as DGTNet's.
        film_hidden: units of the FiLM generator's hidden layer.
        reference: the training vehicles μ_s, σ_s are computed from (default
            ``vehicles``).
        rgb_weights, inputs: as DGTNet's (ImageNet RGB weights; the channels it sees).

    Buffers (in the state dict): ``spec_mean``, ``spec_std`` (D,) and ``spec_raw``
    (V, D), the heads' spec vectors, so a loaded checkpoint evaluates its heads without
    the specs. ``self.specs`` holds the specs themselves.
    """

    def __init__(self, vehicles: Sequence[VehicleSpec | str] = VEHICLES, width: int = 64,
                 fc_hidden: int = 256, film_hidden: int = 64,
                 reference: Sequence[VehicleSpec | str] | None = None,
                 rgb_weights: str | Path | None = None, inputs: str = "rgbd") -> None:
        super().__init__(VEHICLES, width=width, fc_hidden=fc_hidden, rgb_weights=rgb_weights,
                         inputs=inputs)
        del self.vehicle_heads  # one conditioned head replaces the four
        specs = tuple(get_vehicle(v) for v in vehicles)
        names = tuple(v.name for v in specs)
        if not specs or len(set(names)) != len(names):
            raise ValueError(f"vehicles must be distinct, at least one; got {names}")
        self.vehicles, self.specs = names, specs
        self.film_hidden = int(film_hidden)
        mean, std = spec_statistics(specs if reference is None else reference)
        d = len(FEATURES)
        self.register_buffer("spec_mean", torch.as_tensor(mean, dtype=torch.float32))
        self.register_buffer("spec_std", torch.as_tensor(std, dtype=torch.float32))
        self.register_buffer("spec_raw", self._raw(specs))
        self.film = nn.Sequential(nn.Linear(d, self.film_hidden), nn.ReLU(inplace=True),
                                  nn.Linear(self.film_hidden, 2 * self.fc_hidden + 1))
        nn.init.zeros_(self.film[2].weight)
        nn.init.zeros_(self.film[2].bias)  # γ = β = δ = 0: every vehicle starts alike
        self.head = nn.Linear(self.fc_hidden, 1)

    @staticmethod
    def _raw(specs: Sequence[VehicleSpec]) -> torch.Tensor:
        return torch.as_tensor(np.stack([spec_vector(v) for v in specs]), dtype=torch.float32)

    def architecture(self) -> dict[str, Any]:
        """What a checkpoint must match to load into this model; the heads' specs too when
        one is not a named vehicle (a generated one), so the checkpoint rebuilds it."""
        arch = {**super().architecture(), "name": "ConditionedNet",
                "vehicles": list(self.vehicles), "film_hidden": self.film_hidden,
                "features": list(FEATURES)}
        if not all(is_named(v) for v in self.specs):
            arch["specs"] = [dataclasses.asdict(v) for v in self.specs]
        return arch

    def normalise(self, raw: torch.Tensor) -> torch.Tensor:
        """c = (s − μ_s) / σ_s for spec vectors ``raw`` (V, D)."""
        return (raw - self.spec_mean) / self.spec_std

    def _conditioned(self, z: torch.Tensor, raw: torch.Tensor) -> torch.Tensor:
        """L̂ (B, V) for embeddings z (B, F) and raw spec vectors (V, D)."""
        f = self.fc_hidden
        film = self.film(self.normalise(raw))  # (V, 2F + 1)
        gamma, beta, delta = film[:, :f], film[:, f : 2 * f], film[:, 2 * f]
        h = torch.relu(z[:, None, :] * (1.0 + gamma[None]) + beta[None])  # (B, V, F)
        return torch.sigmoid(self.head(h).squeeze(-1) + delta[None])  # (B, V)

    def heads(self, z: torch.Tensor) -> torch.Tensor:
        """Every head's locomotion from the embedding: (B, fc_hidden) → (B, V)."""
        return self._conditioned(z, self.spec_raw)

    def heads_for(self, z: torch.Tensor, specs: Sequence[VehicleSpec | str]) -> torch.Tensor:
        """Locomotion (B, len(specs)) of any vehicles, trained on or not, from z (B, F)."""
        raw = self._raw([get_vehicle(v) for v in specs]).to(z.device)
        return self._conditioned(z, raw)

    def for_vehicles(self, specs: Sequence[VehicleSpec | str]) -> VehicleHeads:
        """This network answering for ``specs`` (any vehicles) instead of its own heads: a
        module with the same weights whose column j is ``specs[j]``, for whatever takes a
        network (``training.predict``, the costmap inference)."""
        return VehicleHeads(self, specs)

    @torch.no_grad()
    def init_heads(self, mean_labels: Sequence[float], weight_scale: float = 0.1) -> None:
        """Start every vehicle at its prior, as :meth:`DGTNet.init_heads` does: L̂_v ≈ m_v,
        the mean training label of ``mean_labels`` (one per head, in [0, 1]), for every
        patch. The shared head gets w ← weight_scale · w and b ← 0; the row of W₂, b₂ that
        makes δ_v is the least-norm solution of δ_v = logit(clip(m_v, 0.01, 0.99)) over the
        heads' vehicles (exact while they are at most ``film_hidden`` + 1 and their hidden
        FiLM activations are independent)."""
        means = np.asarray(mean_labels, dtype=np.float64)
        if means.shape != (len(self.vehicles),) or not np.all((means >= 0) & (means <= 1)):
            raise ValueError(f"need one mean label in [0, 1] per head ({self.vehicles}), "
                             f"got {means.tolist()}")
        if not (math.isfinite(weight_scale) and weight_scale >= 0):
            raise ValueError(f"weight_scale must be finite and ≥ 0, got {weight_scale}")
        prior = np.clip(means, *HEAD_PRIOR_CLIP)
        logits = torch.as_tensor(np.log(prior / (1.0 - prior)), dtype=torch.float32)
        self.head.weight.mul_(weight_scale)
        self.head.bias.zero_()
        hidden = torch.relu(self.film[0](self.normalise(self.spec_raw)))  # (V, H)
        a = torch.cat([hidden, torch.ones(len(hidden), 1)], dim=1)  # (V, H + 1)
        row = torch.linalg.pinv(a.double()) @ logits.double()  # least-norm δ row
        self.film[2].weight[-1] = row[:-1].float()
        self.film[2].bias[-1] = float(row[-1])

class VehicleHeads(nn.Module):
    """A :class:`ConditionedNet` (its weights, not a copy) evaluated for other vehicles:
    L̂ (B, len(specs)), column j for ``specs[j]`` (:meth:`ConditionedNet.for_vehicles`)."""

    def __init__(self, net: ConditionedNet, specs: Sequence[VehicleSpec | str]) -> None:
        super().__init__()
        specs = tuple(get_vehicle(v) for v in specs)
        if not specs:
            raise ValueError("for_vehicles needs at least one vehicle")
        self.net, self.specs = net, specs
        self.vehicles = tuple(v.name for v in specs)
        self.register_buffer("spec_raw", ConditionedNet._raw(specs).to(net.spec_raw.device))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net._conditioned(self.net.embed(x), self.spec_raw)


def conditioned_from_architecture(arch: dict[str, Any]) -> ConditionedNet:
    """An untrained ConditionedNet of a checkpoint's architecture (its heads are named
    vehicles; the spec statistics come with the weights): what
    :func:`~dgt_lib.learning.checkpoints.load_checkpoint` fills with them."""
    if arch.get("name") != "ConditionedNet" or arch.get("features") != list(FEATURES):
        raise ArchitectureMismatchError(
            f"not a ConditionedNet of the spec features {list(FEATURES)}: {arch}")
    heads = [spec_from_dict(d) for d in arch["specs"]] if "specs" in arch else arch["vehicles"]
    return ConditionedNet(heads, width=arch["width"], fc_hidden=arch["fc_hidden"],
                          film_hidden=arch["film_hidden"], inputs=arch.get("inputs", "rgbd"))


def spec_from_dict(d: dict[str, Any]) -> VehicleSpec:
    """The :class:`VehicleSpec` of ``dataclasses.asdict(spec)`` (a checkpoint's heads)."""
    return VehicleSpec(**{**d, "camera": CameraMount(**d["camera"]),
                          "color": tuple(d["color"])})


def load_conditioned(source: str | Path | dict[str, Any], *,
                     vehicles: Sequence[str] | None = None,
                     device: str | torch.device = "cpu") -> TrainResult:
    """A ConditionedNet checkpoint (a ``.pt`` path or its dict), checked as
    :func:`~dgt_lib.learning.checkpoints.load_checkpoint` checks a DGTNet's."""
    return load_checkpoint(source, vehicles=vehicles, device=device,
                           build=conditioned_from_architecture)


def train_conditioned(dataset: PatchDataset, cfg: TrainConfig, *,
                      vehicles: Sequence[str] = VEHICLES, seed: int = 0,
                      film_hidden: int = 64, device: str | torch.device | None = None,
                      progress: bool = True, rgb_weights: str | Path | None = None,
                      **run: Any) -> TrainResult:
    """Train a new ConditionedNet on the samples of the named ``vehicles`` (its heads;
    leave one out to predict it from its spec alone) as
    :func:`~dgt_lib.learning.run.train_model` trains a DGTNet: the same training set,
    seeding, input normalisation, loop and bookkeeping (``run``)."""
    data = TrainingSet.select(dataset, tuple(vehicles), cfg)
    device = resolve_device(device)
    model = _new_model(data, data.vehicles, cfg, seed, film_hidden, rgb_weights)
    return train_network(model, data, cfg, seed=seed, device=device, progress=progress, **run)


def train_conditioned_specs(dataset: PatchDataset, specs: Sequence[VehicleSpec],
                            cfg: TrainConfig, *, seed: int = 0, film_hidden: int = 64,
                            device: str | torch.device | None = None, progress: bool = True,
                            rgb_weights: str | Path | None = None, **run: Any) -> TrainResult:
    """:func:`train_conditioned` for heads of any vehicles (``specs``: named and generated
    ones): ``dataset.vehicle`` is each sample's column among ``specs``
    (:func:`spec_training_set`); μ_s, σ_s are those of all of ``specs``."""
    data = spec_training_set(dataset, [v.name for v in specs], cfg)
    device = resolve_device(device)
    model = _new_model(data, tuple(specs), cfg, seed, film_hidden, rgb_weights)
    return train_network(model, data, cfg, seed=seed, device=device, progress=progress, **run)


def _new_model(data: TrainingSet, heads: Sequence[VehicleSpec | str], cfg: TrainConfig,
               seed: int, film_hidden: int, rgb_weights: str | Path | None) -> ConditionedNet:
    """A new ConditionedNet of ``heads`` (seeded) with ``data``'s input normalisation."""
    torch.manual_seed(seed)
    model = ConditionedNet(heads, width=cfg.width, fc_hidden=cfg.fc_hidden,
                           film_hidden=film_hidden, rgb_weights=rgb_weights, inputs=cfg.inputs)
    model.set_normalization(*channel_statistics(data.dataset.patches, data.train_index))
    return model


def spec_training_set(dataset: PatchDataset, vehicles: Sequence[str],
                      cfg: TrainConfig) -> TrainingSet:
    """A :class:`~dgt_lib.learning.training.TrainingSet` for a net whose heads are
    ``vehicles`` (names, any vehicles: ``ConditionedNet.vehicles``): here
    ``dataset.vehicle`` is each sample's column among them (not an index into
    ``config.VEHICLES``). Checked as
    ``TrainingSet.select`` checks: ≥ 2 training and ≥ 1 validation samples, labels in
    [0, 1], ``cfg.epochs`` ≥ 1, ``cfg.batch_size`` ≥ 2."""
    n_vehicles = len(vehicles)
    column = dataset.vehicle.astype(np.int64)
    if len(column) and (column.min() < 0 or column.max() >= n_vehicles):
        raise ValueError(f"dataset.vehicle must be columns 0 … {n_vehicles - 1}, got "
                         f"{column.min()} … {column.max()}")
    if cfg.epochs < 1 or cfg.batch_size < 2:
        raise ValueError(f"need epochs ≥ 1 and batch_size ≥ 2, got {cfg.epochs}, "
                         f"{cfg.batch_size}")
    train_idx = np.flatnonzero(dataset.split == TRAIN)
    val_idx = np.flatnonzero(dataset.split == VAL)
    if len(train_idx) < 2 or len(val_idx) == 0:
        raise ValueError(f"need ≥ 2 training and ≥ 1 validation samples, got "
                         f"{len(train_idx)} and {len(val_idx)}")
    used = dataset.labels[np.concatenate([train_idx, val_idx])]
    if not np.all((used >= 0) & (used <= 1)):
        raise ValueError("labels must be locomotion values in [0, 1]")
    return TrainingSet(dataset, tuple(vehicles), np.ones(len(column), bool), train_idx,
                       val_idx, column, codes=tuple(range(n_vehicles)))
