"""Self-supervised data collection: one driving episode of one vehicle
(paper: Methodology → Data Collection).

A vehicle spawns at a random free pose (:func:`spawn_pose`), drives forward at u = 5 m/s
under the simulator's PID speed controller with smooth random steering (an
Ornstein–Uhlenbeck process, :class:`OUSteering`, turned home near the map edge and around
trunks ahead), and ends after ``episode_duration_s`` (100 s in the paper's source), when
immobilized, or at a simulator end. The pose is recorded at 25 Hz; an onboard RGB-D frame
every 5 m driven is accumulated into the episode's BEV; samples above 100°/s are simulator
glitches (the pre-filtering in the paper's source, left out of its text). Stalls and why a
run ends at the first: docs/stages.md → Collection. Caching and parallel runs are
:mod:`dgt_lib.stages.collect`'s job.
"""

from __future__ import annotations

import math  # noqa: E402
import zlib  # noqa: E402
from collections import Counter  # noqa: E402
from collections.abc import Callable  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, CollectConfig
from dgt_lib.core.geometry import GridSpec
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.perception.bev import BEVAccumulator, bev_grid
from dgt_lib.perception.locomotion import MAX_ANGULAR_RATE_DPS
from dgt_lib.perception.pose_noise import Localiser
from dgt_lib.world.rendering import onboard_camera_pose, simulator, terrain_renderer
from dgt_lib.world.simulator import CONTROL_DT_S, VehicleState
from dgt_lib.world.worlds import World

END_REASONS: tuple[str, ...] = ("timeout", "immobilized", "flipped", "off_map", "diverged",
                                "stopped")
"""Why an episode ended: its duration, stuck, a simulator ``done_reason``, or the caller's
``stop`` condition (:func:`run_episode`; the ground-truth drives, never collection)."""

STEER_TAU_S = 2.0  # OU steering correlation time τ [s]
STEER_SIGMA = 0.3  # OU stationary std σ of the normalised steer (of [−1, 1])
EDGE_MARGIN_M = 15.0  # closer to the map edge than this, steer back toward the centre [m]
TREE_LOOKAHEAD_M = 10.0  # steer around trunks this close ahead [m]
SPAWN_MARGIN_M = 10.0  # spawn this far from the map edge [m]
SPAWN_MAX_SLOPE_DEG = 15.0  # no spawning on steeper ground [deg]


@dataclass
class OUSteering:
    """Smooth random steering: an Ornstein–Uhlenbeck process on the normalised steer,

        s_{k+1} = a·s_k + σ·√(1 − a²)·ξ_k,   a = exp(−Δt/τ),   ξ_k ~ N(0, 1),

    (the exact discretisation of ds = −s/τ dt + σ√(2/τ) dW: stationary std σ =
    :data:`STEER_SIGMA`, correlation time τ = :data:`STEER_TAU_S`), clipped to [−1, 1].
    Within :data:`EDGE_MARGIN_M` of the map edge the steer blends, linearly in the
    distance, toward a full turn to the map centre (fully at half the margin) so runs
    explore the map instead of leaving it; a trunk in the corridor ahead makes the driver
    swerve (:data:`TREE_LOOKAHEAD_M`).
    """

    rng: np.random.Generator
    value: float = 0.0

    def __call__(self, dt_s: float) -> float:
        a = math.exp(-dt_s / STEER_TAU_S)
        noise = STEER_SIGMA * math.sqrt(1 - a * a) * self.rng.standard_normal()
        self.value = a * self.value + noise
        return float(np.clip(self.value, -1.0, 1.0))


def _homing(steer: float, x: float, y: float, yaw: float, grid: GridSpec) -> float:
    """Blend ``steer`` toward the map centre near the edge (see :class:`OUSteering`)."""
    x0, x1, y0, y1 = grid.extent
    d_edge = min(x - x0, x1 - x, y - y0, y1 - y)
    w = float(np.clip(2.0 * (EDGE_MARGIN_M - d_edge) / EDGE_MARGIN_M, 0.0, 1.0))
    if w == 0.0:
        return steer
    to_centre = math.atan2(0.5 * (y0 + y1) - y, 0.5 * (x0 + x1) - x)
    err = (to_centre - yaw + math.pi) % (2 * math.pi) - math.pi
    home = float(np.clip(2.0 * err, -1.0, 1.0))
    return (1 - w) * steer + w * home


def _avoid_trees(steer: float, x: float, y: float, yaw: float, trees: np.ndarray,
                 half_width_m: float) -> float:
    """Steer fully away from the nearest trunk in the corridor ahead, else ``steer``.

    trees: (N, 4) x, y, radius, height. A trunk is in the corridor when it lies
    0–:data:`TREE_LOOKAHEAD_M` ahead and its edge comes within ``half_width_m`` + 1 m of
    the vehicle's centre line; the vehicle turns away from its side."""
    if len(trees) == 0:
        return steer
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = trees[:, 0] - x, trees[:, 1] - y
    ahead, left = dx * c + dy * s, -dx * s + dy * c
    threat = (ahead > 0) & (ahead < TREE_LOOKAHEAD_M) & (np.abs(left) < half_width_m + 1.0
                                                          + trees[:, 2])
    if not threat.any():
        return steer
    i = np.flatnonzero(threat)[np.argmin(ahead[threat])]
    return -1.0 if left[i] >= 0 else 1.0


def spawn_pose(world: World, vehicle: str | VehicleSpec, rng: np.random.Generator,
               max_tries: int = 10_000) -> np.ndarray:
    """A random free start pose (x [m], y [m], yaw [rad]) on ``world``.

    Free: at least :data:`SPAWN_MARGIN_M` from the map edge, the vehicle's
    half-length plus 1 m clear of every trunk, and the steepest slope within the
    vehicle's half-length at most :data:`SPAWN_MAX_SLOPE_DEG`. Raises RuntimeError if
    no such pose is found in ``max_tries`` draws.
    """
    spec = get_vehicle(vehicle)
    x0, x1, y0, y1 = world.grid.extent
    m = SPAWN_MARGIN_M
    if x1 - x0 <= 2 * m or y1 - y0 <= 2 * m:
        raise ValueError(f"world {world.name!r} is too small for a spawn margin of {m} m")
    slope = world.slope_deg()
    reach = 0.5 * spec.length_m
    trees = np.asarray(world.trees, np.float64).reshape(-1, 4)
    offsets = reach * np.array([[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1],
                                [0.7, 0.7], [-0.7, 0.7], [0.7, -0.7], [-0.7, -0.7]])
    for _ in range(max_tries):
        x, y = rng.uniform(x0 + m, x1 - m), rng.uniform(y0 + m, y1 - m)
        if len(trees) and np.any(np.hypot(trees[:, 0] - x, trees[:, 1] - y)
                                 < trees[:, 2] + reach + 1.0):
            continue
        r, c = world.grid.xy_to_cell(x + offsets[:, 0], y + offsets[:, 1])
        r = np.clip(r, 0, world.grid.height - 1)
        c = np.clip(c, 0, world.grid.width - 1)
        if slope[r, c].max() > SPAWN_MAX_SLOPE_DEG:
            continue
        return np.array([x, y, rng.uniform(0.0, 2 * np.pi)])
    raise RuntimeError(f"no free spawn pose for {spec.name} on {world.name!r} "
                       f"in {max_tries} tries")


@dataclass
class Episode:
    """One recorded run of one vehicle on the training world.

    time_s: (T,) [s] from 0 at the 25 Hz control rate. pose: (T, 3) x [m], y [m],
    yaw [rad]. z: (T,) chassis height [m]. speed_mps: (T,) signed speed along the
    heading. angular_rate_dps: (T,) body angular-rate magnitude [°/s].
    valid: (T,) bool, False where the angular rate exceeds the glitch threshold.
    end_reason: one of :data:`END_REASONS`.
    n_frames: onboard frames rendered.
    bev: the frames' accumulated BEV statistics in sparse form (``None`` when
    loaded without it), see :meth:`BEVAccumulator.to_sparse`.
    """

    vehicle: str
    index: int
    seed: int
    time_s: np.ndarray
    pose: np.ndarray
    z: np.ndarray
    speed_mps: np.ndarray
    angular_rate_dps: np.ndarray
    valid: np.ndarray
    end_reason: str
    n_frames: int
    bev: dict[str, np.ndarray] | None = None

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1] - self.time_s[0]) if len(self.time_s) else 0.0

    def to_arrays(self) -> dict[str, np.ndarray]:
        """A dict of arrays for an ``.npz`` artifact (no pickled objects)."""
        out = {
            "vehicle": np.array(self.vehicle), "index": np.array(self.index),
            "seed": np.array(self.seed), "time_s": self.time_s, "pose": self.pose,
            "z": self.z, "speed_mps": self.speed_mps,
            "angular_rate_dps": self.angular_rate_dps, "valid": self.valid,
            "end_reason": np.array(self.end_reason), "n_frames": np.array(self.n_frames),
        }
        for k, v in (self.bev or {}).items():
            out[f"bev_{k}"] = v
        return out

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], with_bev: bool = True) -> Episode:
        bev = {k[4:]: v for k, v in arrays.items() if k.startswith("bev_")}
        return cls(
            vehicle=str(arrays["vehicle"]), index=int(arrays["index"]),
            seed=int(arrays["seed"]), time_s=arrays["time_s"], pose=arrays["pose"],
            z=arrays["z"], speed_mps=arrays["speed_mps"],
            angular_rate_dps=arrays["angular_rate_dps"], valid=arrays["valid"],
            end_reason=str(arrays["end_reason"]), n_frames=int(arrays["n_frames"]),
            bev=bev if with_bev and bev else None,
        )


def episode_seed(profile_seed: int, vehicle: str | VehicleSpec, index: int) -> int:
    """The seed of episode ``index`` of ``vehicle``: independent streams per vehicle,
    so changing one vehicle's episode count changes no other episode. A named vehicle's
    stream is its index in ``VEHICLES``, any other's (a generated one) its name's CRC-32."""
    name = get_vehicle(vehicle).name
    stream = VEHICLES.index(name) if name in VEHICLES else zlib.crc32(name.encode())
    ss = np.random.SeedSequence([int(profile_seed), stream, int(index)])
    return int(ss.generate_state(1)[0])


def random_steer(st: VehicleState, ou: OUSteering, world: World, trees: np.ndarray,
                 spec: VehicleSpec) -> float:
    """The collection's steering: OU noise, turned home near the world's edge and away
    from trees ahead."""
    x, y = st.position[0], st.position[1]
    s = _homing(ou(CONTROL_DT_S), x, y, st.yaw, world.grid)
    return _avoid_trees(s, x, y, st.yaw, trees, 0.5 * spec.width_m)


def run_episode(
    world: World,
    vehicle: str | VehicleSpec,
    seed: int,
    config: CollectConfig | None = None,
    *,
    start_pose: np.ndarray | None = None,
    steer: Callable[[VehicleState], float] | None = None,
    index: int = 0,
    render: bool = True,
    stop: Callable[[VehicleState], bool] | None = None,
    localise: Localiser | None = None,
) -> Episode:
    """Drive one episode and record it (see the module docstring); deterministic in
    ``seed`` (spawn pose, steering noise). ``start_pose`` (x, y, yaw) replaces the random
    spawn, ``steer(state) -> [−1, 1]`` the OU steering; ``render`` adds an onboard frame
    every ``frame_spacing_m`` driven to the episode's BEV; ``stop(state)`` ends it early
    (reason ``"stopped"``: the ground-truth drives stop a few metres past their cell);
    ``localise`` places each frame at an estimated pose before it is mapped
    (:mod:`~dgt_lib.perception.pose_noise`; the physics does not change)."""
    cfg = config or CollectConfig()
    spec = get_vehicle(vehicle)
    rng = np.random.default_rng(seed)
    pose0 = spawn_pose(world, spec, rng) if start_pose is None else np.asarray(
        start_pose, np.float64)
    ou = OUSteering(rng)
    trees = np.asarray(world.trees, np.float64).reshape(-1, 4)
    sim = simulator(world, spec)
    grid = bev_grid(world.grid.extent)
    acc = BEVAccumulator(grid) if render else None
    renderer = terrain_renderer(world, cfg.frame_max_depth_m) if render else None
    if renderer is not None:
        renderer.restart()
    st = sim.reset(float(pose0[0]), float(pose0[1]), float(pose0[2]))
    n_max = int(round(cfg.episode_duration_s / CONTROL_DT_S)) + 1
    rows = np.empty((n_max, 7))  # t, x, y, yaw, z, speed, |ω| [°/s]
    n, n_frames, reason = 0, 0, "timeout"
    travelled, next_frame_m, last_xy = 0.0, 0.0, st.position[:2].copy()
    while True:
        rate = math.degrees(float(np.linalg.norm(st.angular_rate)))
        rows[n] = (st.time_s, st.position[0], st.position[1], st.yaw, st.position[2],
                   st.speed_mps, rate)
        n += 1
        travelled += float(np.hypot(*(st.position[:2] - last_xy)))
        last_xy = st.position[:2].copy()
        if render and travelled >= next_frame_m and rate <= MAX_ANGULAR_RATE_DPS:
            frame = renderer.render(onboard_camera_pose(sim))
            if localise is not None:
                frame = localise(frame)
            acc.add_frame(frame, max_depth_m=cfg.frame_max_depth_m)
            n_frames += 1  # (no frames during glitches)
            next_frame_m = travelled + cfg.frame_spacing_m
        if st.done_reason is not None:
            reason = st.done_reason
            break
        if n >= n_max or st.time_s >= cfg.episode_duration_s - 1e-9:
            break
        if stop is not None and stop(st):
            reason = "stopped"
            break
        if st.immobilized_s > cfg.immobilized_limit_s:  # paper: a run ends when immobilised
            reason = "immobilized"
            break
        s = steer(st) if steer is not None else random_steer(st, ou, world, trees, spec)
        st = sim.step(speed_cmd_mps=cfg.speed_mps, steer=s)
    rows = rows[:n]
    if reason == "diverged":  # the simulator repeats the last good state: drop it
        rows = rows[:-1] if n > 1 else rows
    return _episode(rows, spec.name, index, seed, reason, n_frames,
                    acc.to_sparse() if render else None)


def _episode(rows: np.ndarray, vehicle: str, index: int, seed: int, reason: str,
             n_frames: int, bev: dict[str, np.ndarray] | None) -> Episode:
    """The :class:`Episode` of a drive's rows (t, x, y, yaw, z, speed, |ω| [°/s]), with the
    rows whose time does not increase dropped."""
    keep = np.concatenate([[True], np.diff(rows[:, 0]) > 0])  # strictly increasing time
    rows = rows[keep]
    return Episode(
        vehicle=vehicle, index=int(index), seed=int(seed),
        time_s=rows[:, 0].astype(np.float32), pose=rows[:, 1:4].astype(np.float32),
        z=rows[:, 4].astype(np.float32), speed_mps=rows[:, 5].astype(np.float32),
        angular_rate_dps=rows[:, 6].astype(np.float32),
        valid=rows[:, 6] <= MAX_ANGULAR_RATE_DPS, end_reason=reason,
        n_frames=n_frames, bev=bev,
    )


def load_episode(path: Path, with_bev: bool = False) -> Episode:
    """Read an episode artifact (the trajectory; its sparse BEV sums if ``with_bev``)."""
    return Episode.from_arrays(artifacts.load(path), with_bev=with_bev)


def episode_summary(episodes: list[Episode]) -> str:
    """One line: episodes per vehicle with their end reasons and mean duration."""
    parts = []
    for v in VEHICLES:
        eps = [e for e in episodes if e.vehicle == v]
        if not eps:
            continue
        reasons = Counter(e.end_reason for e in eps)
        why = ", ".join(f"{r} {reasons[r]}" for r in END_REASONS if reasons[r])
        mean_s = np.mean([e.duration_s for e in eps])
        parts.append(f"{v} {len(eps)} ({why}; mean {mean_s:.0f} s)")
    return "; ".join(parts)
