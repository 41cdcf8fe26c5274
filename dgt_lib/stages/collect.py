"""Stages ``collect`` and ``bev``: the driving episodes and the global BEV maps, cached
(paper: Methodology → Data Collection, Global Map).

Two sources of RGB-D frames feed the global BEV maps: the **episodes** on the training
world (:mod:`dgt_lib.perception.episodes`: random driving at u = 5 m/s, an onboard frame
every 5 m) and the **mapping survey** of every world (:mod:`dgt_lib.world.rendering`:
nadir frames on a lattice, which makes every map complete and independent of any one
trajectory, as the paper's aggregate over all runs does).

Each episode is its own artifact ``episodes/<vehicle>_<index>.npz`` (written atomically
as it completes), so an interrupted collection resumes: completed episodes are loaded,
only the missing ones run. Episodes run through any :class:`concurrent.futures.Executor`
— a process pool of ``profile.workers`` by default, a Dask cluster with
``profile.execution`` (or :func:`~dgt_lib.core.executors.use_executor`), or an executor
passed in; workers return the episode's arrays and this process saves them, so workers
need no access to the data directory.
The dataset built from them is :func:`dgt_lib.stages.dataset.ensure_dataset`.

Example::

    from dgt_lib.stages.collect import collect_episodes, ensure_bev
    episodes = collect_episodes("smoke")        # list[Episode], cached per episode
    bev = ensure_bev("hill", "smoke")           # BEVMap, bev/hill.npz
"""

from __future__ import annotations

import functools
import warnings
import zlib
from collections.abc import Callable
from concurrent.futures import Executor
from pathlib import Path

import numpy as np

from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, CollectConfig, Profile, as_profile
from dgt_lib.core.executors import SerialExecutor, current_executor, limit_threads, run_jobs
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.perception import episodes as driver
from dgt_lib.perception.bev import BEV_FORMAT, BEVAccumulator, BEVMap, bev_grid, bev_quality
from dgt_lib.perception.colour_shuffle import shuffled_colours
from dgt_lib.perception.episodes import (
    Episode,
    episode_seed,
    episode_summary,
    load_episode,
    run_episode,
)
from dgt_lib.perception.locomotion import MAX_ANGULAR_RATE_DPS
from dgt_lib.perception.pose_noise import Localiser, pose_noise
from dgt_lib.stages.output import StageOutput
from dgt_lib.stages.paths import cache_dir, data_dir
from dgt_lib.world.mujoco_model import CAMERA, LIGHTING, MAX_DEPTH_M, PHYSICS
from dgt_lib.world.rendering import survey_frames, survey_poses
from dgt_lib.world.terrain import EXTRA_WORLD_NAMES, WORLD_NAMES, get_world
from dgt_lib.world.worlds import World

EPISODE_FIELDS: tuple[str, ...] = ("episode_duration_s", "speed_mps", "immobilized_limit_s",
                                   "frame_spacing_m", "frame_max_depth_m")
"""The :class:`CollectConfig` fields an episode depends on (its cache key)."""
EPISODE_CONSTANTS: dict[str, float] = {
    "steer_tau_s": driver.STEER_TAU_S, "steer_sigma": driver.STEER_SIGMA,
    "edge_margin_m": driver.EDGE_MARGIN_M, "tree_lookahead_m": driver.TREE_LOOKAHEAD_M,
    "spawn_margin_m": driver.SPAWN_MARGIN_M, "spawn_max_slope_deg": driver.SPAWN_MAX_SLOPE_DEG,
    "max_angular_rate_dps": MAX_ANGULAR_RATE_DPS}
"""The driver's constants an episode depends on, in its key beside :data:`EPISODE_FIELDS`
under the names they had as collection settings: the keys of stored episodes stay valid."""

EPISODE_FORMAT = 3
"""Version of the episode artifact's layout (part of its cache key). 2: per-sample segment
(turn-arounds after stalls); 3: the sparse BEV statistics hold per-cell plane moments
(:data:`~dgt_lib.perception.bev.BEV_FORMAT`)."""

SURVEY_FIELDS: tuple[str, ...] = ("survey_altitude_m", "survey_overlap")
"""The :class:`CollectConfig` fields the mapping survey depends on."""


def _fields(config: CollectConfig, names: tuple[str, ...]) -> dict[str, object]:
    return {name: getattr(config, name) for name in names}


# ----------------------------------------------------------------------------- episodes


def episode_relpath(vehicle: str, index: int) -> str:
    """``episodes/<vehicle>_<index>.npz`` under the profile's data directory."""
    return f"episodes/{vehicle}_{index:04d}.npz"


def episode_config(profile: Profile, vehicle: str | VehicleSpec, index: int
                   ) -> dict[str, object]:
    """What one episode depends on (its artifact's cache key; the pose noise is left out
    while there is none, :mod:`dgt_lib.core.cache_keys`)."""
    return {"format": EPISODE_FORMAT, "bev_format": BEV_FORMAT,
           "episode": {**_fields(profile.collect, EPISODE_FIELDS), **EPISODE_CONSTANTS},
           "worlds": profile.worlds, "seed": profile.seed, "vehicle": get_vehicle(vehicle),
           "index": int(index), "camera": CAMERA, "lighting": LIGHTING, "physics": PHYSICS,
            "pose_noise": pose_noise(profile.bev)}


def _run_training_episode(profile: Profile, vehicle: str | VehicleSpec, index: int) -> Episode:
    """One collection run on the training world, its frames mapped at the poses the
    profile's localisation gives (``bev`` settings)."""
    seed = episode_seed(profile.seed, vehicle, index)
    noise = pose_noise(profile.bev)
    return run_episode(get_world("training", profile), vehicle, seed, profile.collect,
                       index=index, localise=noise.localiser(seed) if noise.active else None)


def _episode_job(profile: Profile, vehicle: str | VehicleSpec, index: int
                 ) -> dict[str, np.ndarray]:
    """Worker entry point: run one episode of the training world, return its arrays."""
    limit_threads()  # a Dask worker has no initializer of ours
    return _run_training_episode(profile, vehicle, index).to_arrays()


def _serial_job(profile: Profile, vehicle: str | VehicleSpec, index: int
                ) -> dict[str, np.ndarray]:
    """:func:`_episode_job` in this process (its thread settings stay as they are)."""
    return _run_training_episode(profile, vehicle, index).to_arrays()


def collect_episodes(
    profile: Profile | str | None = None,
    *,
    executor: Executor | None = None,
    progress: bool = True,
    on_episode: Callable[[Episode], None] | None = None,
    max_in_flight: int | None = None,
) -> list[Episode]:
    """All episodes of ``profile`` (``profile.collect.episodes`` per vehicle), each
    loaded from its artifact when it is there and built otherwise.

    executor: any :class:`concurrent.futures.Executor`; default the one of an enclosing
    :func:`~dgt_lib.core.executors.use_executor` block, else ``profile.execution``'s
    (a process pool of ``profile.workers``, or a Dask cluster:
    :func:`~dgt_lib.core.executors.run_jobs`). The episodes do not depend on it. Each
    missing episode is written as soon as it completes, so an interruption (or a worker
    that dies) loses only the episodes in flight.
    on_episode: called in this process with every newly computed episode (after it is
    saved). Returns the episodes in :data:`VEHICLES` order, by index, *without* their
    sparse BEV sums (see :func:`~dgt_lib.perception.episodes.load_episode`) to keep
    memory small.
    """
    prof = as_profile(profile)
    jobs = [(v, i) for v, n in zip(VEHICLES, prof.collect.episodes, strict=True)
            for i in range(n)]
    return collect_jobs(prof, jobs, episode_relpath, executor=executor, progress=progress,
                        on_episode=on_episode, max_in_flight=max_in_flight,
                        desc=f"episodes ({prof.name})")


def collect_jobs(prof: Profile, jobs: list[tuple[str | VehicleSpec, int]],
                 relpath: Callable[[str, int], str], *, executor: Executor | None = None,
                 progress: bool = True, on_episode: Callable[[Episode], None] | None = None,
                 max_in_flight: int | None = None, desc: str = "episodes") -> list[Episode]:
    """The episodes ``jobs`` ((vehicle or spec, index) pairs) of the training world, each
    stored as ``relpath(vehicle name, index)`` and keyed by :func:`episode_config`: loaded
    when there, run otherwise (:func:`collect_episodes`' rules); returned in ``jobs``
    order."""
    key = cache_dir(prof)
    root = artifacts.profile_dir(key)
    done: dict[tuple[str, int], Episode] = {}
    todo, reasons = [], []
    for v, i in jobs:
        rel = relpath(get_vehicle(v).name, i)
        why = artifacts.staleness(rel, episode_config(prof, v, i), profile=key)
        if why is None:
            try:
                done[(v, i)] = load_episode(root / rel)
                continue
            except Exception as exc:  # noqa: BLE001 - unreadable: recompute it
                why = f"corrupt ({type(exc).__name__})"
        todo.append((v, i))
        reasons.append(why)
    artifacts.report_rebuilds(reasons, desc)

    def save(job: tuple, arrays: dict[str, np.ndarray]) -> None:
        _, v, i = job
        artifacts.ensure(relpath(get_vehicle(v).name, i), episode_config(prof, v, i),
                         lambda: arrays, profile=key, log=lambda _: None)  # reported above
        done[(v, i)] = ep = Episode.from_arrays(arrays, with_bev=False)
        if on_episode is not None:
            on_episode(ep)

    serial = isinstance(executor, SerialExecutor) or (
        executor is None and current_executor() is None and prof.workers <= 1
        and prof.execution.executor == "process")
    run_jobs(_serial_job if serial else _episode_job, [(prof, v, i) for v, i in todo],
             executor=executor, workers=prof.workers, backend=prof.execution.executor,
             address=prof.execution.address, max_in_flight=max_in_flight,
             on_result=save, progress=progress, desc=desc, unit="ep")
    return [done[job] for job in jobs]


# ----------------------------------------------------------------------------- BEV maps


def bev_config(world_name: str, profile: Profile) -> dict[str, object]:
    """What the BEV of ``world_name`` depends on: the world, the survey, the BEV's
    definition (:data:`~dgt_lib.perception.bev.BEV_FORMAT`) and, for the training world,
    the episodes."""
    cfg: dict[str, object] = {"world": world_name, "bev_format": BEV_FORMAT,
                              "worlds": profile.worlds, "seed": profile.seed, "camera": CAMERA,
                              "lighting": LIGHTING, "physics": PHYSICS,
                              "survey": _fields(profile.collect, SURVEY_FIELDS),
                              "bev_settings": profile.bev}  # left out while at its defaults
    if world_name == "training":  # one digest, not 1,300 configurations in the metadata
        cfg["episodes"] = _episodes_digest(profile)
    return cfg


@functools.lru_cache(maxsize=8)
def _episodes_digest(profile: Profile) -> str:
    """The hash of every episode's :func:`episode_config` (~0.1 s for `paper`'s 1,300; a
    query checks the training BEV's key more than once)."""
    return artifacts.config_hash(
        [episode_config(profile, v, i)
         for v, n in zip(VEHICLES, profile.collect.episodes, strict=True) for i in range(n)])


def build_world_bev(world: World, config: CollectConfig | None = None,
                    episode_paths: list[Path] = (), progress: bool = False,
                    localise: Localiser | None = None) -> tuple[BEVMap, int, int]:
    """The BEV map of ``world`` from its survey plus the stored frames of episodes;
    ``localise`` places each survey frame at an estimated pose
    (:mod:`~dgt_lib.perception.pose_noise`).

    Returns the map, the number of survey frames and of episode frames."""
    acc = BEVAccumulator(bev_grid(world.grid.extent))
    frames = survey_frames(world, config)
    if localise is not None:
        frames = map(localise, frames)
    if progress:
        from tqdm.auto import tqdm

        frames = tqdm(frames, total=len(survey_poses(world, config)),
                      desc=f"survey {world.name}", unit="frame")
    n_survey = 0
    for frame in frames:
        acc.add_frame(frame)
        n_survey += 1
    n_episode = 0
    for path in episode_paths:
        ep = load_episode(path, with_bev=True)
        if ep.bev is not None:
            acc.add_sparse(ep.bev)
        n_episode += ep.n_frames
    return acc.result(), n_survey, n_episode


UNOBSERVED_WARN_FRACTION = 0.10
"""Warn when more than this fraction of a world's interior is unobserved in its BEV map
(the kit's own worlds leave a few percent at most: ``bev_quality``'s coverage)."""


class UnobservedMapWarning(UserWarning):
    """Much of a world's BEV map is unobserved; the planner treats those cells as obstacles."""


def warn_if_unobserved(bev: BEVMap, world: World, config: CollectConfig | None = None
                       ) -> float:
    """The fraction of ``world``'s interior that ``bev`` left unobserved; warns
    (:class:`UnobservedMapWarning`) with the likely cause when it exceeds
    :data:`UNOBSERVED_WARN_FRACTION`.

    The usual cause is relief: each survey view looks down from ``survey_altitude_m``
    above the highest terrain inside it and the camera sees :data:`MAX_DEPTH_M` deep, so
    ground more than MAX_DEPTH_M − survey_altitude_m [m] below a view's highest point is
    never mapped (e.g. heights given in centimetres instead of metres)."""
    cfg = config or CollectConfig()
    unobserved = 1.0 - bev_quality(bev, world)["coverage"]
    if unobserved <= UNOBSERVED_WARN_FRACTION:
        return unobserved
    lo, hi = float(world.heights.min()), float(world.heights.max())
    reach = MAX_DEPTH_M - cfg.survey_altitude_m
    if hi - lo > reach:
        why = (f"Its heights span {lo:.1f} to {hi:.1f} m: each survey view looks down from "
               f"{cfg.survey_altitude_m:.0f} m above the highest terrain in it and sees "
               f"{MAX_DEPTH_M:.0f} m deep, so ground more than {reach:.0f} m below a view's "
               "highest point is not mapped. Are the heights in metres? Scale them down (a "
               "PNG: a smaller --vertical-scale / vertical_scale_m).")
    else:
        why = (f"Its relief ({hi - lo:.1f} m) is within the survey's {reach:.0f} m depth "
               "reach, so something else hid the ground (dense trees, a tiny map?).")
    warnings.warn(f"{unobserved:.0%} of world {world.name!r} is unobserved in its BEV map; "
                  "the planner treats unobserved cells as obstacles (a start or goal there "
                  f"is 'in an obstacle'). {why}", UnobservedMapWarning, stacklevel=2)
    return unobserved


def world_seed(world_name: str, run_seed: int) -> int:
    """A random stream's seed for one world in one run (the survey's localisation error,
    the colour shuffle): each world and run seed its own."""
    return zlib.crc32(f"{world_name}/{run_seed}".encode())


def mapped_world_bev(world: World, prof: Profile, episode_paths: list[Path] = (),
                     progress: bool = False) -> tuple[BEVMap, int, int]:
    """:func:`build_world_bev` under the profile's ``bev`` settings: survey frames at the
    poses its localisation gives, colours shuffled when ``bev.colour`` says so."""
    noise = pose_noise(prof.bev)
    seed = world_seed(world.name, prof.seed)
    bev, n_survey, n_episode = build_world_bev(
        world, prof.collect, episode_paths, progress=progress,
        localise=noise.localiser(seed) if noise.active else None)
    if prof.bev.colour == "shuffled":
        bev = shuffled_colours(bev, seed)
    return bev, n_survey, n_episode


def ensure_bev(world_name: str, profile: Profile | str | None = None, *,
               executor: Executor | None = None, progress: bool = True) -> BEVMap:
    """The global BEV map of a world, cached as ``bev/<world>.npz``.

    Every world is mapped by the survey; the training world's map also
    aggregates the onboard frames of all episodes (collected first if needed,
    through ``executor``).
    """
    return BEVMap.from_arrays(_ensure_bev_arrays(world_name, profile, executor, progress))


def _ensure_bev_arrays(world_name: str, profile: Profile | str | None,
                       executor: Executor | None, progress: bool) -> dict[str, np.ndarray]:
    """The BEV artifact's arrays (the map plus ``survey_frames``, ``episode_frames``)."""
    if world_name not in WORLD_NAMES + EXTRA_WORLD_NAMES:
        raise ValueError(f"unknown world {world_name!r}; valid worlds: "
                         f"{', '.join(WORLD_NAMES + EXTRA_WORLD_NAMES)}")
    prof = as_profile(profile)

    def build() -> dict[str, np.ndarray]:
        world = get_world(world_name, prof)  # only to build: a cached map's key needs no world
        paths: list[Path] = []
        if world_name == "training":
            collect_episodes(prof, executor=executor, progress=progress)
            paths = [data_dir(prof) / episode_relpath(v, i)
                     for v, n in zip(VEHICLES, prof.collect.episodes, strict=True)
                     for i in range(n)]
        bev, n_survey, n_episode = mapped_world_bev(world, prof, paths, progress)
        return {**bev.to_arrays(), "survey_frames": np.array(n_survey),
                "episode_frames": np.array(n_episode)}

    return artifacts.ensure(bev_relpath(world_name), bev_config(world_name, prof), build,
                            profile=cache_dir(prof))


def bev_relpath(world_name: str) -> str:
    """``bev/<world>.npz`` under the profile's data directory."""
    return f"bev/{world_name}.npz"


# ----------------------------------------------------------------------------- stages


def stage_collect(profile: Profile) -> StageOutput:
    """``dgt reproduce`` stage: all collection episodes (cached per episode)."""
    episodes = collect_episodes(profile)
    return StageOutput([data_dir(profile) / "episodes"],
                       f"{len(episodes)} episodes: {episode_summary(episodes)}")


def stage_bev(profile: Profile) -> StageOutput:
    """``dgt reproduce`` stage: BEV maps of the training, hill, ridge and eval worlds."""
    prof = as_profile(profile)
    paths, parts = [], []
    for name in WORLD_NAMES:
        meta = _ensure_bev_arrays(name, prof, None, True)
        q = bev_quality(BEVMap.from_arrays(meta), get_world(name, prof))
        paths.append(data_dir(prof) / bev_relpath(name))
        parts.append(f"{name} {q['coverage']:.1%} observed, |H̄−h| median "
                     f"{q['height_median_abs_err_m'] * 100:.1f} cm "
                     f"({int(meta['survey_frames'])}+{int(meta['episode_frames'])} frames)")
    return StageOutput(paths, "; ".join(parts))
