"""Profiles: one switch sizes everything (DESIGN.md → Profiles).

``smoke`` runs every code path in CI in minutes, ``demo`` is the default for a
person stepping through the notebooks, ``paper`` uses the paper's sizes.
Select with the ``DGT_PROFILE`` environment variable or an explicit name::

    from dgt_lib.config import get_profile
    profile = get_profile()          # DGT_PROFILE, default "demo"
    profile = get_profile("smoke")

Each pipeline stage owns one frozen section of :class:`Profile`; the artifact
cache hashes the sections a stage depends on, so changing one field rebuilds
exactly the artifacts it affects.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace

PROFILE_NAMES: tuple[str, ...] = ("smoke", "demo", "paper")
DEFAULT_PROFILE = "demo"
ENV_VAR = "DGT_PROFILE"


VEHICLES: tuple[str, ...] = ("jeep", "vw_van", "mercedes_van", "carla_cola")
"""The four vehicles, in head order (DESIGN.md → Conventions)."""


@dataclass(frozen=True)
class WorldsConfig:
    """World sizes (``dgt_lib.worlds``). Square worlds, side in metres."""

    training_size_m: float = 200.0
    eval_size_m: float = 160.0
    hfield_resolution_m: float = 0.4  # terrain grid cell, metres


@dataclass(frozen=True)
class CollectConfig:
    """Self-supervised data collection (``dgt_lib.collect``)."""

    episodes: tuple[int, int, int, int] = (40, 40, 30, 20)  # per vehicle, VEHICLES order
    episode_duration_s: float = 100.0  # paper: runs end at 100 s or when immobilized


@dataclass(frozen=True)
class TrainConfig:
    """Multi-task training (``dgt_lib.train``)."""

    epochs: int = 10
    batch_size: int = 256
    learning_rate: float = 1e-3


@dataclass(frozen=True)
class CostmapConfig:
    """Directional costmap inference (``dgt_lib.costmap``)."""

    n_headings: int = 8  # K, paper: Spatial and Angular Discretization


@dataclass(frozen=True)
class PlannerConfig:
    """Hybrid A* (``dgt_lib.planner``)."""

    step_m: float = 1.6  # s, paper: Hybrid A*
    beta: float = 150.0  # cost amplification, paper: Directional Cost Lookup


@dataclass(frozen=True)
class ExperimentsConfig:
    """Closed-loop trial counts (``dgt_lib.experiments``)."""

    n_hill: int = 20  # Experiment 1, carla_cola
    n_ridge: int = 50  # Experiment 2, mercedes_van
    n_eval_jeep: int = 100  # Experiment 3
    n_eval_vw_van: int = 99  # Experiment 3


@dataclass(frozen=True)
class Profile:
    """All sizes of one profile, one frozen section per pipeline stage."""

    name: str
    seed: int = 0
    workers: int = 2  # processes for episodes and trials (concurrent.futures)
    worlds: WorldsConfig = field(default_factory=WorldsConfig)
    collect: CollectConfig = field(default_factory=CollectConfig)
    train: TrainConfig = field(default_factory=TrainConfig)
    costmap: CostmapConfig = field(default_factory=CostmapConfig)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    experiments: ExperimentsConfig = field(default_factory=ExperimentsConfig)

    def with_(self, **changes) -> Profile:
        """A copy with some fields changed, e.g. ``p.with_(seed=3)``."""
        return replace(self, **changes)


def _smoke() -> Profile:
    """CI and nbmake: every code path, about a minute per notebook on 2 cores."""
    return Profile(
        name="smoke",
        worlds=WorldsConfig(training_size_m=80.0, eval_size_m=80.0),
        collect=CollectConfig(episodes=(3, 3, 3, 3), episode_duration_s=20.0),
        train=TrainConfig(epochs=2, batch_size=64),
        experiments=ExperimentsConfig(n_hill=2, n_ridge=2, n_eval_jeep=2, n_eval_vw_van=2),
    )


def _demo() -> Profile:
    """Default for a person: minutes per notebook, qualitatively right results."""
    return Profile(
        name="demo",
        worlds=WorldsConfig(training_size_m=160.0, eval_size_m=120.0),
        collect=CollectConfig(episodes=(40, 40, 30, 20)),
        train=TrainConfig(epochs=10),
        experiments=ExperimentsConfig(n_hill=6, n_ridge=6, n_eval_jeep=10, n_eval_vw_van=10),
    )


def _paper() -> Profile:
    """The paper's sizes (Section Experiments → Dataset, Tables I and II)."""
    return Profile(
        name="paper",
        worlds=WorldsConfig(training_size_m=300.0, eval_size_m=200.0),
        # Dataset paragraph: 400 jeep, 400 vw_van, 300 mercedes_van, 200 carla_cola runs.
        collect=CollectConfig(episodes=(400, 400, 300, 200), episode_duration_s=100.0),
        train=TrainConfig(epochs=30),
        # Table I (n=20 hill, n=50 ridge) and Table II (n=100 jeep, n=99 vw_van).
        experiments=ExperimentsConfig(n_hill=20, n_ridge=50, n_eval_jeep=100, n_eval_vw_van=99),
    )


_BUILDERS = {"smoke": _smoke, "demo": _demo, "paper": _paper}


class UnknownProfileError(ValueError):
    """Raised for a profile name that is not one of :data:`PROFILE_NAMES`."""


def profile_name(name: str | None = None) -> str:
    """Resolve a profile name: the argument, else ``$DGT_PROFILE``, else ``demo``."""
    chosen = name if name is not None else os.environ.get(ENV_VAR) or DEFAULT_PROFILE
    chosen = chosen.strip().lower()
    if chosen not in _BUILDERS:
        source = "argument" if name is not None else f"${ENV_VAR}"
        raise UnknownProfileError(
            f"unknown profile {chosen!r} (from {source}); valid profiles: "
            + ", ".join(PROFILE_NAMES)
        )
    return chosen


def get_profile(name: str | None = None) -> Profile:
    """The :class:`Profile` called ``name`` (or from ``$DGT_PROFILE``, default demo)."""
    return _BUILDERS[profile_name(name)]()
