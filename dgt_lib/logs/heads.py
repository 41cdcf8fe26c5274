"""A costmap for the robot of a drive log, a robot the kit never trained on.

Two ways to a head for it, compared on the log's held-out runs (:func:`compare_heads`):

- **zero-shot**: the vehicle-conditioned network (docs/vehicles.md) answers for the
  robot's spec; nothing of the log is learnt.
- **few-shot**: a new head on the multi-task network's shared backbone (paper:
  Multi-Task Learning: the trunk is shared, a vehicle is a head), fitted to the log's
  training runs with the paper's loss ‖L̂(P) − L(t_P)‖² while the backbone stays frozen:
  the named vehicles' heads predict exactly as before (:class:`BackboneHead`).

Either head maps the log's own BEV into the paper's K-heading costmap
(:func:`robot_costmap`, ``dgt log costmap``), with the occupancy map's τ_s by the paper's
rule on what the robot drove over (:func:`log_tau_s`), or any world's (:func:`world_maps`,
``dgt log plan``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import torch
from scipy.ndimage import binary_dilation
from torch import nn

from dgt_lib.core import artifacts
from dgt_lib.core.config import Profile
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.learning.model import DGTNet
from dgt_lib.learning.training import predict, window_predictor
from dgt_lib.mapping.costmap import directional_costmap
from dgt_lib.mapping.occupancy import occupancy_map, select_tau_s
from dgt_lib.mapping.world_maps import WorldMaps
from dgt_lib.perception.bev import GRADIENT, BEVMap
from dgt_lib.perception.dataset import SPLIT_NAMES, PatchDataset
from dgt_lib.world.worlds import World

HEADS: tuple[str, ...] = ("few-shot", "zero-shot")
"""The heads a log's robot can have (module docstring)."""
HEAD_STEPS = 400
"""Full-batch Adam steps at most when fitting a few-shot head."""
HEAD_PATIENCE = 40
"""Steps without a better validation loss before the fit stops."""
HEAD_LR_SCALES = (1.0, 4.0, 16.0)
"""Adam's rates for the head, each over the embedding's width (Adam's first steps move every
weight by about the rate, so the logit by ~ rate × width × |ẑ|); the validation loss picks."""
TRAVERSED_L = 0.5
"""A patch labelled at least this was driven through (half the commanded progress or more)."""
DRIVEN_RADIUS_M = 1.0
"""Cells this close to a driven pose count as driven over [m]."""
TRAVERSED_PERCENTILE = 99.0
"""The percentile of the driven cells' gradients that τ_s rests on (:func:`log_tau_s`)."""


class BackboneHead(nn.Module):
    """A frozen :class:`DGTNet`'s embedding z and one new head on it, standardised by the
    log's training patches: L̂ = σ(w·(z − μ)/s + b), (B, 1). The network itself is not
    changed (its parameters are never stepped); ``vehicles`` names the one column."""

    def __init__(self, net: DGTNet, name: str, z_train: torch.Tensor) -> None:
        super().__init__()
        self.net, self.vehicles = net, (name,)
        self.head = nn.Linear(net.fc_hidden, 1)
        std = z_train.std(0) if len(z_train) > 1 else torch.ones(net.fc_hidden)
        self.register_buffer("z_mean", z_train.mean(0))
        self.register_buffer("z_std", torch.where(std > 1e-8, std, torch.ones_like(std)))

    def logit(self, z: torch.Tensor) -> torch.Tensor:
        """w·(z − μ)/s + b for embeddings z (B, fc_hidden) → (B,)."""
        return self.head((z - self.z_mean) / self.z_std).squeeze(1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.sigmoid(self.logit(self.net.embed(x)))[:, None]


@torch.no_grad()
def embeddings(net: DGTNet, patches: np.ndarray, batch_size: int = 1024) -> torch.Tensor:
    """The shared embedding z (N, fc_hidden) of raw patches (N, 6, 22, 7), in eval mode."""
    net.eval()
    parts = [net.embed(torch.as_tensor(patches[i:i + batch_size], dtype=torch.float32))
             for i in range(0, len(patches), batch_size)]
    return torch.cat(parts) if parts else torch.zeros(0, net.fc_hidden)


def few_shot_head(net: DGTNet, dataset: PatchDataset, name: str) -> BackboneHead:
    """A head for the log's robot on ``net``'s frozen backbone, fitted to the training
    split of ``dataset`` (the log's patches): it starts at the prior (L̂ = mean training
    label for every patch, w = 0) and takes full-batch Adam steps on the mean squared
    error until the validation split's stops improving (the training split's when the
    log holds no validation run), at each rate of :data:`HEAD_LR_SCALES` over the
    embedding's width; the fit with the lowest validation loss is kept. Deterministic."""
    train = dataset.split == SPLIT_NAMES.index("train")
    if not train.any():
        raise ValueError("the log has no training patches to fit a head to")
    val = dataset.split == SPLIT_NAMES.index("val")
    val = val if val.any() else train
    z = embeddings(net, dataset.patches)
    y = torch.as_tensor(dataset.labels, dtype=torch.float32)
    model = BackboneHead(net, name, z[train])
    fits = [_fit(model, z[train], y[train], z[val], y[val], scale / net.fc_hidden)
            for scale in HEAD_LR_SCALES]
    model.head.load_state_dict(min(fits, key=lambda fit: fit[0])[1])
    return model.eval()


def _fit(model: BackboneHead, zt: torch.Tensor, yt: torch.Tensor, zv: torch.Tensor,
         yv: torch.Tensor, lr: float) -> tuple[float, dict[str, torch.Tensor]]:
    """One fit of the head from the prior at Adam rate ``lr``: (best validation loss, the
    head's weights there)."""
    prior = float(np.clip(yt.mean(), 0.01, 0.99))
    with torch.no_grad():
        model.head.weight.zero_()
        model.head.bias.fill_(math.log(prior / (1 - prior)))
    opt = torch.optim.Adam(model.head.parameters(), lr=lr)
    best, best_state, since = math.inf, None, 0
    for _ in range(HEAD_STEPS):
        with torch.no_grad():
            loss_v = float(torch.mean((torch.sigmoid(model.logit(zv)) - yv) ** 2))
        if loss_v < best - 1e-7:
            best, since = loss_v, 0
            best_state = {k: v.clone() for k, v in model.head.state_dict().items()}
        elif (since := since + 1) >= HEAD_PATIENCE:
            break
        opt.zero_grad()
        torch.mean((torch.sigmoid(model.logit(zt)) - yt) ** 2).backward()
        opt.step()
    return best, best_state


def zero_shot_head(profile: Profile, spec: VehicleSpec, *, progress: bool = True) -> nn.Module:
    """The vehicle-conditioned network of ``profile`` answering for ``spec`` (trained
    first, on the named vehicles' data, when the cache does not hold it)."""
    from dgt_lib.stages.conditioned import ensure_conditioned_model
    from dgt_lib.stages.dataset import ensure_dataset

    net = ensure_conditioned_model(profile, ensure_dataset(profile, progress=progress),
                                   progress=progress).model
    return net.for_vehicles([spec]).eval()


def compare_heads(dataset: PatchDataset, heads: dict[str, nn.Module],
                  batch_size: int = 1024) -> dict[str, dict[str, float]]:
    """Each head's error on the log's held-out runs (the test split): mean absolute error
    of L̂ against the log's labels, and the same for the *prior* (the mean training label
    for every patch: what a head must beat to have learnt anything). Raises ValueError
    for a log whose runs are all in training."""
    test = dataset.split == SPLIT_NAMES.index("test")
    if not test.any():
        raise ValueError("the log holds no held-out run (one run is all training): record "
                         "or drive several runs, with a stop between them")
    y = dataset.labels[test].astype(np.float64)
    prior = float(dataset.labels[dataset.split == SPLIT_NAMES.index("train")].mean())
    rows = {"prior": np.full_like(y, prior)} | {
        name: predict(h, dataset.patches[test], batch_size)[:, 0] for name, h in heads.items()}
    return {name: {"mae": float(np.mean(np.abs(p - y))), "n": int(test.sum())}
            for name, p in rows.items()}


def log_tau_s(bev: BEVMap, dataset: PatchDataset, margin: float) -> float:
    """τ_s by the paper's rule on the log ("the smallest threshold that eliminates no
    terrain traversable in at least one direction"), over the observed cells within
    :data:`DRIVEN_RADIUS_M` of the poses the robot drove through (patches labelled at
    least :data:`TRAVERSED_L`; where it stalled against an obstacle does not count):
    their :data:`TRAVERSED_PERCENTILE`-th percentile gradient times ``margin``. A log's
    map holds a few mis-mapped cells under the drive (depth edges: gradients of 3–7 m/m
    on 0.5 % of them in a `demo` log); their maximum would free every obstacle."""
    drove = dataset.pose[dataset.labels >= TRAVERSED_L].astype(np.float64)
    if len(drove) == 0:
        raise ValueError(f"the log has no patch labelled L ≥ {TRAVERSED_L}: the robot "
                         "never drove through freely, so τ_s has nothing to rest on")
    r, c = bev.grid.xy_to_cell(drove[:, 0], drove[:, 1])
    inside = (r >= 0) & (r < bev.grid.shape[0]) & (c >= 0) & (c < bev.grid.shape[1])
    under = np.zeros(bev.grid.shape, bool)
    under[r[inside], c[inside]] = True
    radius = int(round(DRIVEN_RADIUS_M / bev.grid.resolution))
    disk = np.hypot(*np.mgrid[-radius:radius + 1, -radius:radius + 1]) <= radius
    under = binary_dilation(under, disk) & bev.observed
    if not under.any():
        raise ValueError("the log's map observed none of the cells the robot drove over")
    steepest = np.percentile(bev.channels[GRADIENT][under], TRAVERSED_PERCENTILE)
    return select_tau_s(np.array([steepest]), margin)


def log_costmap(bev: BEVMap, head: nn.Module, profile: Profile, tau_s: float, *,
                progress: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The K-heading costmap (K, H, W) of the log's map by ``head`` (one column), with the
    profile's inference settings, and the occupancy map (H, W) at ``tau_s``."""
    cfg = profile.costmap
    cost = directional_costmap(bev, window_predictor(head, cfg.batch_size), cfg.n_headings,
                               stride=cfg.stride, batch_size=cfg.batch_size, progress=progress)
    return cost[0], occupancy_map(bev, tau_s)


def log_heads(summary: dict, spec: VehicleSpec, profile: Profile, head: str = "few-shot",
              *, progress: bool = True) -> tuple[nn.Module, dict[str, dict[str, float]]]:
    """The head ``head`` (:data:`HEADS`) for the robot of the ingested log of ``summary``
    (:func:`~dgt_lib.logs.ingest.ingest`), and :func:`compare_heads`' errors of both heads
    and the prior on the log's held-out runs (both heads are built for them); a log
    without a held-out run builds ``head`` alone and has no errors."""
    from dgt_lib.stages.costmaps import load_model

    if head not in HEADS:
        raise ValueError(f"unknown head {head!r}; valid heads: {', '.join(HEADS)}")
    dataset = PatchDataset.from_arrays(artifacts.load(Path(summary["folder"]) / "dataset.npz"))
    held_out = bool((dataset.split == SPLIT_NAMES.index("test")).any())
    build = {"few-shot": lambda: few_shot_head(load_model(profile, progress=progress),
                                               dataset, spec.name),
             "zero-shot": lambda: zero_shot_head(profile, spec, progress=progress)}
    made = {name: make() for name, make in build.items() if held_out or name == head}
    return made[head], compare_heads(dataset, made) if held_out else {}


def robot_costmap(summary: dict, head: nn.Module, profile: Profile, *, progress: bool = True
                  ) -> tuple[BEVMap, np.ndarray, np.ndarray]:
    """The log's own map (BEV), its costmap (K, H, W) by ``head`` and its occupancy, τ_s
    from the log (:func:`log_tau_s`)."""
    folder = Path(summary["folder"])
    bev = BEVMap.from_arrays(artifacts.load(folder / "bev.npz"))
    dataset = PatchDataset.from_arrays(artifacts.load(folder / "dataset.npz"))
    tau_s = log_tau_s(bev, dataset, profile.costmap.tau_s_margin)
    return (bev, *log_costmap(bev, head, profile, tau_s, progress=progress))


def world_maps(world: World, head: nn.Module, profile: Profile, *, progress: bool = True
               ) -> tuple[WorldMaps, np.ndarray]:
    """A world's maps (its BEV, occupancy at the profile's τ_s) and its costmap (K, H, W) by
    ``head``: the robot's map of a kit world or of your terrain, for ``dgt log plan``."""
    from dgt_lib.stages.costmaps import ensure_tau_s, world_bev

    bev, _ = world_bev(world, profile, progress=progress)
    tau_s = ensure_tau_s(profile)
    cost, occupancy = log_costmap(bev, head, profile, tau_s, progress=progress)
    return WorldMaps(world.name, bev, occupancy, tau_s, {}), cost
