"""Profiles: one switch sizes everything (docs/ARCHITECTURE.md → Profiles).

``smoke`` runs every code path in CI in minutes, ``demo`` is the default for a
person stepping through the notebooks, ``paper`` uses the paper's sizes.
Select with the ``DGT_PROFILE`` environment variable or an explicit name (one rule for
both, and for ``dgt --profile``: case and surrounding blanks do not matter)::

    from dgt_lib.core.config import get_profile
    profile = get_profile()          # DGT_PROFILE, default "demo"
    profile = get_profile("smoke")

Each pipeline stage owns one frozen section of :class:`Profile`; the artifact
cache hashes the sections a stage depends on, so changing one field rebuilds
exactly the artifacts it affects.

Any field can be changed without editing code, by its dotted name; the value is typed
by the field's annotation and checked (an unknown name lists the valid ones)::

    profile = get_profile("demo").with_overrides({"planner.beta": 50, "experiments.n_hill": 10})
    profile = get_profile("demo").with_overrides(parse_overrides(["planner.beta=50"]))

(the command line's ``dgt reproduce --set planner.beta=50``; the rules live in
:mod:`dgt_lib.core.overrides`). Every profile made is checked against the allowed values
of :mod:`dgt_lib.core.constraints`, so a value that cannot work fails at once.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import MISSING, dataclass, field, fields, replace

from dgt_lib.core.constraints import (  # noqa: F401 - the vehicles and the text settings'
    CONV_TAPS,  # choices, re-exported: `from dgt_lib.core.config import VEHICLES`
    HEAD_INITS,
    INPUTS,
    LR_SCHEDULES,
    SELECTIONS,
    VEHICLES,
    check_section,
    check_settings,
)
from dgt_lib.core.controller import MPPIConfig, mppi_before_overrides
from dgt_lib.core.overrides import apply_overrides, format_setting

PROFILE_NAMES: tuple[str, ...] = ("smoke", "demo", "paper")
DEFAULT_PROFILE = "demo"
ENV_VAR = "DGT_PROFILE"


@dataclass(frozen=True)
class WorldsConfig:
    """World sizes (``dgt_lib.world.worlds``). Square worlds, side in metres."""

    training_size_m: float = 200.0
    eval_size_m: float = 160.0
    hfield_resolution_m: float = 0.4  # terrain grid cell, metres (MuJoCo behaves at 0.2–0.4)
    training_seed: int = 0  # the training world's terrain seed (the same for every run seed)
    eval_seed: int = 1000  # eval world: a different seed, never used in training


@dataclass(frozen=True)
class CollectConfig:
    """Self-supervised data collection (``dgt_lib.stages.collect``, ``dgt_lib.perception.dataset``).

    Episodes: spawn at a random free pose, drive at ``speed_mps`` with smooth
    random (Ornstein–Uhlenbeck) steering until ``episode_duration_s`` or a simulator
    end (flipped, off_map, diverged); ``immobilized_limit_s`` below the simulator's
    immobile speed ends the run. The steering and spawn rules are constants of
    ``dgt_lib.perception.episodes``, the glitch threshold one of ``perception.locomotion``.
    Survey: nadir frames of the same camera from ``survey_altitude_m`` above the terrain on
    a lattice (complete BEV maps).
    """

    episodes: tuple[int, int, int, int] = (40, 40, 30, 20)  # per vehicle, VEHICLES order
    episode_duration_s: float = 100.0  # the paper's source: runs end at 100 s or when stuck
    speed_mps: float = 5.0  # u, commanded speed (paper: Locomotion)
    immobilized_limit_s: float = 5.0  # stuck this long ends a run (ours; evaluation uses 10 s)
    frame_spacing_m: float = 5.0  # onboard RGB-D frame every 5 m driven (≈1 Hz at u) [m]
    frame_max_depth_m: float = 20.0  # onboard pixels farther than this are not mapped [m]
    patch_interval_s: float = 1.33  # one patch every this many seconds of a run [s]
    patch_start_s: float = 3.0  # no patches while accelerating from rest [s]
    survey_altitude_m: float = 20.0  # survey camera above the highest point it sees [m]
    survey_overlap: float = 0.2  # overlap of neighbouring survey footprints (fraction)




@dataclass(frozen=True)
class TrainConfig:
    """Multi-task training (``dgt_lib.learning.training``) and the network's size
    (``dgt_lib.learning.model``).

    The paper gives the architecture (two ResNet-18, i.e. width 64) but not the
    optimiser settings or epochs; Adam at 1e-3 with the best validation epoch
    kept is our choice, and so is the head initialisation ``head_init``.
    """

    epochs: int = 10
    batch_size: int = 256
    learning_rate: float = 1e-3  # Adam
    width: int = 64  # channels of the first ResNet stage; 64 = ResNet-18 (paper)
    fc_hidden: int = 256  # units of the FC layer between the branches and the heads
    patience: int | None = None  # stop after this many epochs without a better val loss
    mirror_augment: bool = True  # flip half of each batch left ↔ right (ours, label-preserving)
    # "prior": each head starts at logit(mean training label of its vehicle) with its weights
    # × 0.1 (DGTNet.init_heads; ours); "default": PyTorch's init, which let the jeep head
    # (97 % of labels ≈ 1) saturate at L̂ = 1 in the first epoch. One of HEAD_INITS.
    head_init: str = "prior"
    # "constant": Adam at learning_rate throughout; "cosine": the rate falls from
    # learning_rate to 0 along a half cosine over the whole run, step by step (ours). One of
    # LR_SCHEDULES.
    lr_schedule: str = "constant"
    # Which epoch's weights are kept: "best_val", the lowest validation loss (stops early
    # after `patience` epochs without a better one); "last", the final epoch (patience
    # ignored: with a cosine schedule the weights have settled there). One of SELECTIONS.
    selection: str = "best_val"
    # How DGTNet's convolutions run while training: "all", every tap of every kernel (as the
    # recorded results were trained); "live", only the taps that meet the patch
    # (model.PatchConv2d): the same network, ~1.35× faster training steps at width 64 on
    # two CPU cores, trained weights equal in all but the last bits. One of CONV_TAPS.
    conv_taps: str = "all"
    # What the network sees: "rgbd", every channel (the paper); "geometry", only H̄, σ_H and
    # ‖∇H̄‖; "rgb", only the colours. The channels left out enter as their training mean
    # (the input attribution study, README). One of INPUTS.
    inputs: str = "rgbd"
    # Data scarcity (the Claim 4 study, learning/scarcity.py): train on only a fraction
    # ``scarce_fraction`` of ``scarce_vehicle``'s training runs (whole runs, drawn by the run
    # seed; validation and test splits untouched). "none" = every run (the paper).
    scarce_vehicle: str = "none"
    scarce_fraction: float = 1.0

    def __post_init__(self):
        check_section(self, "train")  # each field's rule (core/constraints.py)


@dataclass(frozen=True)
class BEVConfig:
    """How the frames are placed in the global BEV map (``dgt_lib.perception.pose_noise``):
    the localisation error a real robot's frames would carry, and, for the input
    attribution study, colours made independent of the geometry. The defaults are the
    paper's: simulator ground-truth poses and the colours the camera saw.

    The same settings apply to every frame the map is built from, the episodes' onboard
    frames (the training data) and the surveys of the evaluation worlds.
    """

    pose_sigma_xy_m: float = 0.0  # per-frame position error, std of each of x and y [m]
    pose_sigma_yaw_deg: float = 0.0  # per-frame heading error, std [deg]
    # odometry drift: a position bias that random-walks from frame to frame, std of each
    # step along x and y (after n frames the bias's std is √n × this) [m]
    pose_drift_m: float = 0.0
    # "observed": the colours the camera saw (the paper); "shuffled": the map's colour
    # layer cut into 6.4 m tiles and the tiles permuted, so colour keeps its statistics
    # but cannot mark where the terrain is steep or sharp (input attribution). One of
    # BEV_COLOURS.
    colour: str = "observed"


@dataclass(frozen=True)
class CostmapConfig:
    """Directional costmap inference (``dgt_lib.mapping.costmap``), baselines and occupancy."""

    n_headings: int = 8  # K, paper: Spatial and Angular Discretization
    stride: tuple[int, int] = (6, 3)  # fast path: window centres every (along, across) cells
    batch_size: int = 2048  # patches per network call
    slope_trials: int = 200  # Optuna trials per vehicle for the slope-based baseline
    tau_s_margin: float = 1.05  # τ_s = margin × the steepest traversed-terrain gradient


@dataclass(frozen=True)
class PlannerConfig:
    """Hybrid A* (``dgt_lib.navigation.planner``).

    The paper gives s and β; the rest (closed-set discretisation, sub-steps,
    tolerances, caps, the stronger heuristic, the analytic shot) are ours.
    """

    step_m: float = 1.6  # s [m], arc length of one primitive, paper: Hybrid A*
    beta: float = 150.0  # β, cost amplification C(1 + βC), paper: Directional Cost Lookup
    heuristic: str = "cost_to_go"  # "euclidean" (the paper's) or "cost_to_go" (admissible 2D)
    heuristic_weight: float = 1.0  # w ≥ 1: weighted A*, cost ≤ w × optimum; 1 keeps it exact
    goal_tolerance_m: float = 1.0  # a node this close to the goal position reaches it [m]
    goal_heading_tolerance_rad: float = 0.26  # when the goal has a heading (~15°) [rad]
    theta_bins: int = 36  # heading bins of the closed set (10°)
    closed_cell_m: float = 1.6  # xy cell of the closed set [m] (one step)
    substep_m: float = 0.2  # collision-check spacing along a primitive [m]
    analytic_shot: bool = True  # try a Dubins / turn-then-straight shot near the goal (shots.py)
    max_expansions: int = 200_000  # search cap (expanded nodes)
    max_time_s: float = 20.0  # search cap (wall time) [s]


@dataclass(frozen=True)
class ExperimentsConfig:
    """Closed-loop trials (``dgt_lib.evaluation.experiments``): counts, queries, time limits."""

    n_hill: int = 20  # Experiment 1, carla_cola
    n_ridge: int = 50  # Experiment 2, mercedes_van
    n_eval_jeep: int = 100  # Experiment 3
    n_eval_vw_van: int = 99  # Experiment 3
    start_jitter_m: float = 2.0  # starts and goals vary this much around the landmarks [m]
    heading_jitter_deg: float = 20.0  # start headings vary this much [deg]
    eval_distance_m: tuple[float, float] = (40.0, 90.0)  # random start–goal distance range [m]
    # Experiment 3's rule, fixed before any method ran (dgt_lib/evaluation/hazards.py): keep a
    # random query only when its straight segment start → goal crosses at least this much
    # terrain that one of the experiment's vehicles cannot cross, from the TRUE heights (slope
    # above its max climb, or a crest above its ground clearance between its axles) [m];
    # about one vehicle length (jeep 4.3 m, vw_van 4.5 m). 0 = no rule (the paper's draw).
    eval_min_hazard_m: float = 4.0
    time_limit_base_s: float = 30.0  # time limit = base + factor × planned length / 5 m/s
    time_limit_factor: float = 2.0
    # Experiment 3 on ``eval_hazard`` (the eval world plus V-ditches sized by the jeep's spec,
    # dgt_lib/world/terrain.py, docs/worlds.md) instead of ``eval``; False = the paper's setup
    eval_hazard_world: bool = False
    # The trials' controller, a preset of the ``mppi`` section (core/controller.py,
    # docs/controller.md): "paper" (MPPI as the paper runs it), "robust" (no crawl, corners
    # below the roll limit) or "terrain" (robust plus the terrain critic on each method's
    # own costmap)
    controller: str = "paper"


@dataclass(frozen=True)
class ConditionedConfig:
    """The vehicle-conditioned network's training data (``dgt_lib.stages.conditioned``,
    docs/vehicles.md → Training the network on generated vehicles)."""

    # N procedurally generated vehicles (core/vehicle_generator.py, drawn by the run seed)
    # driven on the training world like the named ones and added to the conditioned
    # network's training; 0 = the named vehicles only. Nothing else uses them.
    generated_vehicles: int = 0


EXECUTORS: tuple[str, ...] = ("process", "dask")
"""Valid ``ExecutionConfig.executor`` values (``dgt reproduce --executor``)."""

DEVICES: tuple[str, ...] = ("auto", "cpu", "cuda")
"""Valid ``ExecutionConfig.device`` values (``dgt reproduce --device``)."""


@dataclass(frozen=True)
class ExecutionConfig:
    """Where the work runs — never what it computes (docs/scale-out.md).

    executor: what runs the independent jobs (collection episodes, closed-loop trials):
    ``"process"`` a pool of ``Profile.workers`` processes on this machine; ``"dask"`` a
    Dask cluster, on this machine or many (``pip install 'dgt-kit[dask]'``). address: the
    scheduler of an existing Dask cluster (``tcp://host:8786``); None starts a local
    cluster of ``Profile.workers`` single-threaded workers for the run and stops it after.
    device: where training and costmap inference run, ``"auto"`` (a CUDA GPU when
    torch sees one, else the CPU), ``"cpu"`` or ``"cuda"``.

    No artifact's cache key includes this section and two profiles that differ only here
    compare equal, so a run resumed on another executor or device reuses everything.
    """

    executor: str = "process"
    address: str | None = None
    device: str = "auto"

    def __post_init__(self) -> None:
        if self.executor not in EXECUTORS:
            raise ValueError(f"unknown executor {self.executor!r}; valid: {', '.join(EXECUTORS)}")
        if self.device not in DEVICES:
            raise ValueError(f"unknown device {self.device!r}; valid: {', '.join(DEVICES)}")
        if self.address is not None and self.executor == "process":
            raise ValueError("an address needs executor 'dask' (the process pool runs on "
                             "this machine)")


@dataclass(frozen=True)
class GroundTruthConfig:
    """Ground-truth directional locomotion (``dgt_lib.evaluation.ground_truth``): cells of
    the hill, ridge and eval worlds, stratified by slope and roughness, each driven at the
    K headings by every vehicle an experiment uses; the costmaps are scored against it
    (``dgt_lib.evaluation.accuracy``). The drive: ``run_up_m`` of straight run-up at the
    collection's commanded speed, through the cell, ``past_m`` beyond it.
    """

    cells: int = 48  # cells per world (every vehicle of the world drives the same cells)
    run_up_m: float = 15.0  # start this far before the cell; ≥ 12 m reaches 5 m/s on flat [m]
    past_m: float = 4.4  # drive on this far past the cell: the patch's forward reach [m]
    edge_margin_m: float = 20.0  # cells this far from the map edge: run-ups stay on the map [m]
    tree_clearance_m: float = 2.0  # cells at least this far from a trunk [m]
    max_slope_deg: float = 30.0  # steeper cells (the hill's cliffs) are not sampled [deg]
    slope_edges_deg: tuple[float, ...] = (4.0, 10.0, 18.0)  # slope strata: 0–4–10–18–30° [deg]
    roughness_edge_m: float = 0.04  # rough / smooth strata: RMS relief about a 1 m blur [m]
    contrast_threshold: float = 0.3  # directional contrast on pairs with |C*(θ) − C*(θ+π)| > it
    seed: int = 0  # the cells drawn (not the run seed: the physics does not depend on it)


@dataclass(frozen=True)
class Profile:
    """All sizes of one profile, one frozen section per pipeline stage."""

    name: str
    seed: int = 0  # the run's seed: collection, training, queries, controller noise
    seeds: int = 1  # `dgt reproduce` runs seeds seed, seed + 1, …, seed + seeds − 1
    # processes (or local cluster workers) for episodes and trials; like `execution`, not
    # compared: it changes how fast, not what, so a resumed run may use another count
    workers: int = field(default=2, compare=False)
    worlds: WorldsConfig = field(default_factory=WorldsConfig)
    collect: CollectConfig = field(default_factory=CollectConfig)
    bev: BEVConfig = field(default_factory=BEVConfig)
    train: TrainConfig = field(default_factory=TrainConfig)
    costmap: CostmapConfig = field(default_factory=CostmapConfig)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    experiments: ExperimentsConfig = field(default_factory=ExperimentsConfig)
    mppi: MPPIConfig = field(default_factory=MPPIConfig)  # the preset experiments.controller
    # names, with any mppi.* setting changed on top (core/controller.py)
    # where jobs and networks run, not what they compute: left out of comparisons (and of
    # every cache key), so the same run on another executor or device is the same Profile
    execution: ExecutionConfig = field(default=ExecutionConfig(), compare=False)
    ground_truth: GroundTruthConfig = field(default_factory=GroundTruthConfig)
    conditioned: ConditionedConfig = field(default_factory=ConditionedConfig)
    overrides: tuple[tuple[str, object], ...] = ()
    """The settings changed by :meth:`with_overrides`, ``(dotted name, value)`` in the order
    given: what the reports print beside the profile's name. No cache key reads it (each
    artifact is keyed by the fields it uses)."""

    def __post_init__(self) -> None:
        check_settings(self)  # every setting in its range, on the whole profile (cross-field)

    def __setstate__(self, state: dict[str, object]) -> None:
        """Unpickle (a stored trial keeps its profile): a section added since the profile
        was stored gets its default, as the run that stored it had."""
        missing = {f.name: f.default_factory() for f in fields(self)
                   if f.name not in state and f.default_factory is not MISSING}
        self.__dict__.update({**missing, **state})

    def with_(self, **changes) -> Profile:
        """A copy with some fields changed, e.g. ``p.with_(seed=3)``."""
        return replace(self, **changes)

    def with_overrides(self, overrides: Mapping[str, object]) -> Profile:
        """A copy with settings changed by dotted name, e.g.
        ``p.with_overrides({"planner.beta": 50, "collect.episodes": "10,10,10,10"})``.

        A name is ``section.field`` (a field of a section: ``worlds``, ``collect``, ``bev``,
        ``train``, ``costmap``, ``planner``, ``experiments``, ``mppi``, ``ground_truth``,
        ``conditioned``) or ``seed``,
        ``seeds``, ``workers``. A value is converted to the field's type: a string as it
        would be typed on the command line, or a Python value of that type. An unknown name
        or a value that does not fit raises ``InvalidOverrideError`` naming the valid fields
        or the type expected. The rules: :mod:`dgt_lib.core.overrides`. A new
        ``experiments.controller`` puts its preset in the ``mppi`` section first
        (:func:`~dgt_lib.core.controller.with_controller`); ``mppi.*`` settings apply on top."""
        base = replace(self, mppi=mppi_before_overrides(self.mppi, overrides))
        return apply_overrides(base, overrides)

    def describe(self) -> str:
        """The profile's name and its overrides: ``'demo'`` or
        ``'demo' with planner.beta=50.0``."""
        text = repr(self.name)
        if self.overrides:
            text += " with " + ", ".join(f"{k}={format_setting(v)}" for k, v in self.overrides)
        return text

    def seed_profiles(self) -> list[Profile]:
        """One profile per run seed: ``seed``, ``seed + 1``, … (``seeds`` of them).

        Seeds change everything random in a run — the episodes (spawn poses, steering),
        the dataset split, weight initialisation and batch order, the slope-baseline fit,
        the queries and the controller's samples — and nothing else: the worlds are the
        same in every seed, so a seed is "the same experiment, run again", as on another
        machine."""
        return [self.with_(seed=self.seed + i) for i in range(self.seeds)]


def _smoke() -> Profile:
    """CI and nbmake: every code path, about a minute per notebook on 2 cores."""
    return Profile(
        name="smoke",
        worlds=WorldsConfig(training_size_m=80.0, eval_size_m=80.0),
        collect=CollectConfig(episodes=(3, 3, 3, 3), episode_duration_s=20.0),
        # width 8: trains in seconds; exercises the same code as the paper's width 64.
        train=TrainConfig(epochs=2, batch_size=64, width=8, fc_hidden=64),
        experiments=ExperimentsConfig(n_hill=2, n_ridge=2, n_eval_jeep=2, n_eval_vw_van=2),
        mppi=MPPIConfig(batch_size=256),
        costmap=CostmapConfig(slope_trials=60),
        # weighted A* (cost ≤ 1.5 × optimum): ~10× fewer expansions (benchmarks/bench_planner.py)
        planner=PlannerConfig(heuristic_weight=1.5, max_time_s=10.0),
        # 4 cells × 8 headings × 5 world–vehicle pairs = 160 drives, ~15 s on 2 cores.
        ground_truth=GroundTruthConfig(cells=4),
    )


def _demo() -> Profile:
    """Default for a person: minutes per notebook, qualitatively right results."""
    return Profile(
        name="demo",
        seeds=3,  # conclusions are reported over seeds (README: per seed and pooled)
        worlds=WorldsConfig(training_size_m=160.0, eval_size_m=120.0),
        collect=CollectConfig(episodes=(40, 40, 30, 20)),
        # width 32: ~3× faster training and inference than 64 (benchmarks/bench_train.py).
        # cosine schedule, last epoch kept: the smaller vehicles' validation splits are a
        # few runs' patches, too few to pick an epoch by (docs/training.md → The `demo`
        # recipe; studies/training_recipes.py).
        train=TrainConfig(epochs=15, batch_size=128, width=32, lr_schedule="cosine",
                          selection="last"),
        # stride 4×2: ~9× faster than the literal procedure, mean |ΔC| 0.004 (6×3: 18×, 0.006;
        # benchmarks/bench_costmap.py); the README's demo results were made with it.
        costmap=CostmapConfig(stride=(4, 2)),
        experiments=ExperimentsConfig(n_hill=6, n_ridge=6, n_eval_jeep=10, n_eval_vw_van=10),
        # exact (unweighted) Hybrid A*, as the paper: the compiled search plans the experiment
        # queries in 0.01–0.07 s median (docs/speed.md → Hybrid A*); weighting is no longer needed.
        planner=PlannerConfig(heuristic_weight=1.0),
        # 48 cells × 8 headings × 5 world–vehicle pairs = 1,920 drives, once for all three
        # seeds: 39 s on 2 otherwise idle cores (a fresh clone's `make reproduce`).
        ground_truth=GroundTruthConfig(cells=48),
    )


def _paper() -> Profile:
    """The paper's sizes (Section Experiments → Dataset, Tables I and II)."""
    return Profile(
        name="paper",
        seeds=3,  # the README's `paper` results rest on these three run seeds
        # Dataset / Experiment 3: the paper gives no map sizes; 300 m × 300 m holds
        # 1,300 runs of ≤ 100 s at 5 m/s, 200 m × 200 m 100 random start/goal pairs.
        worlds=WorldsConfig(training_size_m=300.0, eval_size_m=200.0),
        # Dataset paragraph: 400 jeep, 400 vw_van, 300 mercedes_van, 200 carla_cola runs;
        # 30,000 jeep patches / 400 runs ≈ 75 per 100 s run ⇒ one patch every 1.33 s.
        collect=CollectConfig(episodes=(400, 400, 300, 200), episode_duration_s=100.0,
                              patch_interval_s=1.33),
        # Network Architecture: two ResNet-18 (width 64). The paper gives no epochs, batch
        # size or learning rate: Adam 1e-3, batch 256, ≤ 15 epochs (stop after 4 without a
        # better val loss), best val epoch kept. The epoch budget is set by the ≤ 3 h target:
        # one epoch of all five models took ~2.7 min on 2 idle cores (81 + 32 + 29 + 10 + 9 s).
        train=TrainConfig(epochs=15, batch_size=256, learning_rate=1e-3, width=64,
                          fc_hidden=256, patience=4),
        # Table I (n=20 hill, n=50 ridge) and Table II (n=100 jeep, n=99 vw_van).
        experiments=ExperimentsConfig(n_hill=20, n_ridge=50, n_eval_jeep=100, n_eval_vw_van=99),
        # Hybrid A* / Directional Cost Lookup: s = 1.6 m, β = 150, an admissible heuristic
        # (the paper's Euclidean distance, here maxed with the 2D cost-to-go), unweighted.
        planner=PlannerConfig(step_m=1.6, beta=150.0, heuristic_weight=1.0, max_time_s=60.0,
                              max_expansions=500_000),
        # 96 cells: 3,840 drives, once for all seeds: 94 s on 2 idle cores (README: "The
        # `paper` run").
        ground_truth=GroundTruthConfig(cells=96),
    )


_BUILDERS = {"smoke": _smoke, "demo": _demo, "paper": _paper}


class UnknownProfileError(ValueError):
    """Raised for a profile name that is not one of :data:`PROFILE_NAMES`."""


def profile_name(name: str | None = None) -> str:
    """Resolve a profile name: the argument, else ``$DGT_PROFILE``, else ``demo``.

    Case-insensitive, surrounding blanks ignored ("Smoke " is "smoke"); the command
    line's ``--profile`` goes through here too, so the two accept the same names.
    Raises :class:`UnknownProfileError` naming the valid profiles."""
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


def as_profile(profile: Profile | str | None) -> Profile:
    """A :class:`Profile` as it is, else :func:`get_profile` of the name (or of
    ``$DGT_PROFILE`` for None): what every stage entry point accepts."""
    return profile if isinstance(profile, Profile) else get_profile(profile)
