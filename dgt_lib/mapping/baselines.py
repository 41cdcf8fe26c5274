"""The cost baselines of the paper (Section Baselines).

* **Isotropic** (DGT-Map(Iso)): the mean over the K directional layers — one cost per cell.
* **Single-task** (DGT-Map(ST)): the directional costmap of a model trained on one
  vehicle's data only — :func:`dgt_lib.mapping.costmap.directional_costmap` with that model.
* **Slope-based**: a plane fitted to the H̄ channel of each heading-aligned patch gives
  the forward slope angle θ; locomotion is the piecewise function

      L_sb(θ) = 1 − ((θ − θ0) / (θmax − θ0))^p_u     for θ ∈ [θ0, θmax]
      L_sb(θ) = 1 − ((θ0 − θ) / (θ0 − θmin))^p_d     for θ ∈ [θmin, θ0]
      L_sb(θ) = 0                                     otherwise,

  with {θ0, θmin, θmax, p_u, p_d} fitted per vehicle on the training split with
  Optuna (seeded); cost c_sb = 1 − L_sb. It produces the same (K, H, W) costmap
  type by running the same rotate → slide → average procedure.
* **Binary**: no costmap (zero cost), occupancy only.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from dgt_lib.perception.bev import HEIGHT, BEVMap
from dgt_lib.perception.patches import patch_offsets


def isotropic_costmap(costmap: np.ndarray) -> np.ndarray:
    """Mean over the K heading layers: (K, H, W) → (1, H, W) (or (V, K, H, W) → (V, 1, H, W))."""
    costmap = np.asarray(costmap)
    if costmap.ndim not in (3, 4):
        raise ValueError(f"expected a (K, H, W) or (V, K, H, W) costmap, got {costmap.shape}")
    return costmap.mean(axis=-3, keepdims=True)


def binary_costmap(shape: tuple[int, int]) -> np.ndarray:
    """The binary baseline's costmap: zero everywhere, (1, H, W); only occupancy matters."""
    return np.zeros((1, *shape), np.float32)


# ----------------------------------------------------------------------------- slope-based
def forward_slope(patches: np.ndarray, observed: np.ndarray | None = None) -> np.ndarray:
    """Forward slope angle θ [rad] of a plane fitted to each patch's H̄ channel.

    patches: (N, 6, 22, 7) (row 0 = ahead); observed: optional (N, 22, 7) mask of
    the cells to fit (all cells if None). Fits h = a·forward + b·left + c by least
    squares and returns atan(a): positive uphill in the driving direction.
    A patch with fewer than 3 observed cells gets slope 0.
    """
    h = np.asarray(patches[:, HEIGHT], dtype=np.float64).reshape(len(patches), -1)
    offsets = patch_offsets().reshape(-1, 2)
    design = np.column_stack([offsets, np.ones(len(offsets))])  # (154, 3)
    if observed is None:
        coef = h @ np.linalg.pinv(design).T  # (N, 3)
        return np.arctan(coef[:, 0])
    w = np.asarray(observed, dtype=np.float64).reshape(len(patches), -1)
    ata = np.einsum("nk,ki,kj->nij", w, design, design)  # (N, 3, 3)
    atb = np.einsum("nk,ki,nk->ni", w, design, h)  # (N, 3)
    ok = w.sum(axis=1) >= 3
    ata[~ok] = np.eye(3)
    atb[~ok] = 0.0
    coef = np.linalg.solve(ata + 1e-9 * np.eye(3), atb[..., None])[..., 0]
    return np.arctan(coef[:, 0])


@dataclass(frozen=True)
class SlopeModel:
    """Parameters of L_sb(θ) for one vehicle; angles in radians, θmin ≤ θ0 ≤ θmax."""

    theta0: float
    theta_min: float
    theta_max: float
    p_u: float
    p_d: float

    def __post_init__(self):
        if not self.theta_min <= self.theta0 <= self.theta_max:
            raise ValueError(f"need θmin ≤ θ0 ≤ θmax, got {self}")
        if self.p_u <= 0 or self.p_d <= 0:
            raise ValueError(f"decay exponents must be > 0, got {self}")

    def locomotion(self, theta: np.ndarray) -> np.ndarray:
        """L_sb(θ) (paper eq. slope-based predictor), θ [rad] → L in [0, 1]."""
        theta = np.asarray(theta, dtype=np.float64)
        up = (theta - self.theta0) / max(self.theta_max - self.theta0, 1e-9)
        down = (self.theta0 - theta) / max(self.theta0 - self.theta_min, 1e-9)
        out = np.where(theta >= self.theta0,
                       1.0 - np.clip(up, 0.0, 1.0) ** self.p_u,
                       1.0 - np.clip(down, 0.0, 1.0) ** self.p_d)
        out = np.where((theta > self.theta_max) | (theta < self.theta_min), 0.0, out)
        return out.astype(np.float32)

    def to_dict(self) -> dict[str, float]:
        return asdict(self)


def climb_slope_model(max_climb_deg: float, exponent: float = 1.0) -> SlopeModel:
    """L_sb from a vehicle's spec alone, nothing fitted: full locomotion on the flat
    (θ0 = 0), falling as |θ|^p to 0 at the torque-limited climb θmax = −θmin =
    ``max_climb_deg`` [deg] (``VehicleSpec.max_climb_deg``) in either direction — what a
    vehicle never driven has before any data."""
    if not 0.0 < max_climb_deg <= 90.0:
        raise ValueError(f"max_climb_deg must be in (0, 90], got {max_climb_deg}")
    climb = float(np.radians(max_climb_deg))
    return SlopeModel(0.0, -climb, climb, exponent, exponent)


def fit_slope_model(theta: np.ndarray, labels: np.ndarray, *, n_trials: int = 200,
                    seed: int = 0) -> SlopeModel:
    """Fit {θ0, θmin, θmax, p_u, p_d} to (slope θ [rad], label L) pairs with Optuna.

    Minimises the mean squared error of L_sb(θ) against the labels with a seeded
    TPE sampler. Search space: θ0 ∈ [−0.35, 0.35] rad (±20°), θmax − θ0 and
    θ0 − θmin ∈ [0.02, 1.2] rad, p_u, p_d ∈ [0.2, 8] (log scale).
    """
    import optuna

    theta = np.asarray(theta, dtype=np.float64)
    labels = np.asarray(labels, dtype=np.float64)
    if len(theta) == 0 or len(theta) != len(labels):
        raise ValueError("fit_slope_model needs matching, non-empty slopes and labels")

    def params(trial) -> SlopeModel:
        t0 = trial.suggest_float("theta0", -0.35, 0.35)
        return SlopeModel(
            theta0=t0,
            theta_min=t0 - trial.suggest_float("down_span", 0.02, 1.2),
            theta_max=t0 + trial.suggest_float("up_span", 0.02, 1.2),
            p_u=trial.suggest_float("p_u", 0.2, 8.0, log=True),
            p_d=trial.suggest_float("p_d", 0.2, 8.0, log=True),
        )

    def objective(trial) -> float:
        return float(np.mean((params(trial).locomotion(theta) - labels) ** 2))

    # ERROR, not WARNING: the objective cannot fail, so the only warning Optuna would log
    # is a failed trial with a traceback when Ctrl-C lands in it (the interrupt propagates).
    optuna.logging.set_verbosity(optuna.logging.ERROR)
    study = optuna.create_study(direction="minimize",
                                sampler=optuna.samplers.TPESampler(seed=seed))
    study.optimize(objective, n_trials=n_trials)
    return params(optuna.trial.FixedTrial(study.best_params))


class SlopePredictor:
    """A :data:`dgt_lib.mapping.costmap.Predictor` for the slope baseline: patches → L_sb
    per vehicle.

    ``models`` holds one :class:`SlopeModel` per vehicle, in output-column order.
    ``locomotion(θ, θ0, θmin, θmax, p_u, p_d)``, when given, replaces
    :meth:`SlopeModel.locomotion` (e.g. a learner's own L_sb from notebook 07's exercise).
    """

    def __init__(self, models: list[SlopeModel],
                 locomotion: Callable[..., np.ndarray] | None = None):
        if not models:
            raise ValueError("SlopePredictor needs at least one SlopeModel")
        self.models = list(models)
        self.locomotion = locomotion

    def __call__(self, patches: np.ndarray) -> np.ndarray:
        theta = forward_slope(patches)
        if self.locomotion is None:
            return np.stack([m.locomotion(theta) for m in self.models], axis=1)
        return np.stack([np.asarray(self.locomotion(theta, m.theta0, m.theta_min, m.theta_max,
                                                    m.p_u, m.p_d), np.float32)
                         for m in self.models], axis=1)


def slope_costmap(bev: BEVMap, models: list[SlopeModel], n_headings: int = 8, *,
                  locomotion: Callable[..., np.ndarray] | None = None,
                  **kwargs) -> np.ndarray:
    """The slope-based directional costmap (V, K, H, W), same procedure as DGT-Map's
    (``locomotion``: see :class:`SlopePredictor`)."""
    from dgt_lib.mapping.costmap import directional_costmap

    return directional_costmap(bev, SlopePredictor(models, locomotion), n_headings, **kwargs)
