"""MPPI control rate on one core: Nav2's defaults (1000 samples × 56 steps, 0.05 s).

Target ≥ 50 Hz (Nav2's C++ MPPI runs at 50–100 Hz). Run: ``python benchmarks/bench_control.py``.
Prints the time per ``compute`` of both backends (``compiled``, the default, and the numpy
reference) without and with an occupancy grid — with one footprint circle and with the
three of the mercedes_van that closed-loop trials use — checks that both return the same
commands, times the noise draw (``noise_compiled.NormalStream`` against numpy's generator,
and whether they draw the same numbers), and the closed-loop tracking error on the
kinematic bicycle.

``--terrain-weight W`` adds the terrain critic (``MPPIConfig.terrain_weight`` W, a random
8-heading costmap on the grid) to the trials' case, times it on and off in the same run
and prints the ratio: ``python benchmarks/bench_control.py --terrain-weight 0.05``.
``--controller NAME`` runs that case with a named trials' controller
(``experiments.controller``: ``robust`` adds the breakaway model, the first-step critic and
the roll limit): ``python benchmarks/bench_control.py --terrain-weight 0.05 --controller robust``.
``--cpu-time`` times each call by this thread's CPU time instead of the wall clock: on
cores shared with other work, the compute without the waits for a core. ``--publish``
writes the per-call table's record (``benchmarks/publish.py``) for docs/speed.md.
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one core: set before numpy loads its BLAS

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from publish import Benchmark  # noqa: E402

from dgt_lib.core.controller import CONTROLLERS, MPPIConfig, controller_settings  # noqa: E402
from dgt_lib.core.geometry import GridSpec  # noqa: E402
from dgt_lib.core.vehicles import get_vehicle  # noqa: E402
from dgt_lib.navigation.control.bicycle import (  # noqa: E402
    KinematicBicycle,
    cross_track_errors,
    simulate_tracking,
)
from dgt_lib.navigation.control.mppi import BACKENDS, MPPIController  # noqa: E402
from dgt_lib.navigation.control.mppi_config import vehicle_footprint  # noqa: E402
from dgt_lib.navigation.control.noise_compiled import NormalStream  # noqa: E402
from dgt_lib.navigation.control.sampling import draw_noise  # noqa: E402
from dgt_lib.records.study import table  # noqa: E402

WHEELBASE_M, MAX_STEER_RAD = 2.46, math.radians(35.0)  # the jeep
CLOCK = {"now": time.perf_counter}  # ``--cpu-time``: time.thread_time


def s_curve(length_m: float = 120.0, amplitude_m: float = 4.0, wavelength_m: float = 40.0):
    x = np.linspace(0.0, length_m, 600)
    k = 2 * np.pi / wavelength_m
    return np.stack([x, amplitude_m * np.sin(k * x), np.arctan(amplitude_m * k * np.cos(k * x))], 1)


def time_compute(cfg: MPPIConfig, occupancy=None, grid=None, calls: int = 200,
                 backend: str = "compiled", costmap=None) -> tuple[np.ndarray, np.ndarray]:
    """Seconds per compute() call while driving along the path (pose advanced by the
    commands, so the path window and warm start behave as in a loop), and the commands."""
    ctrl = MPPIController(cfg, wheelbase_m=WHEELBASE_M, max_steer_rad=MAX_STEER_RAD, seed=0,
                          backend=backend, roll_accel_mps2=get_vehicle("jeep").rollover_accel_mps2)
    ctrl.set_path(s_curve())
    x, y, yaw, v = 0.0, 0.0, 0.3, 4.0
    times, commands = [], []
    for _ in range(calls):
        t0 = CLOCK["now"]()
        v_cmd, w_cmd = ctrl.compute((x, y, yaw), v, occupancy, grid, costmap)
        times.append(CLOCK["now"]() - t0)
        commands.append((v_cmd, w_cmd))
        x += v_cmd * math.cos(yaw) * cfg.model_dt
        y += v_cmd * math.sin(yaw) * cfg.model_dt
        yaw += w_cmd * cfg.model_dt
        v = v_cmd
    return np.asarray(times[10:]), np.asarray(commands)  # without the warm-up calls


def time_noise(cfg: MPPIConfig, generator, calls: int = 200) -> tuple[float, np.ndarray]:
    """Median milliseconds of one ``compute``'s noise draw (``sampling.draw_noise``) with
    ``generator(seed)`` (MPPI's ``noise_compiled.NormalStream`` or numpy's
    ``default_rng``), and the last call's noise."""
    rng, shape = generator(0), (cfg.time_steps, cfg.batch_size)
    eps_v, eps_w = np.empty(shape, np.float32), np.empty(shape, np.float32)
    times = []
    for _ in range(calls):
        t0 = CLOCK["now"]()
        noise = draw_noise(rng, eps_v, eps_w)
        times.append(CLOCK["now"]() - t0)
    return 1e3 * float(np.median(times[10:])), np.stack(noise)


def report(label: str, t: np.ndarray) -> None:
    med = float(np.median(t))
    print(
        f"{label:<50} median {1e3 * med:6.2f} ms  p90 {1e3 * np.percentile(t, 90):6.2f} ms"
        f"  → {1.0 / med:6.1f} Hz"
    )


def terrain_case(van: MPPIConfig, occ, grid, weight: float, rounds: int = 4) -> None:
    """The trials' case with the terrain critic off and on (compiled), timed in rounds
    that alternate the two so that a change of load hits both; and whether both backends
    give the same commands with it on."""
    costmap = np.random.default_rng(1).random((8, *grid.shape), np.float32)
    cases = {"off": van, f"on (w {weight:g})": dataclasses.replace(van, terrain_weight=weight)}
    on = list(cases.values())[1]
    same = np.array_equal(*(time_compute(on, occ, grid, 60, b, costmap)[1] for b in BACKENDS))
    times: dict[str, list[np.ndarray]] = {k: [] for k in cases}
    for _ in range(rounds):
        for label, c in cases.items():
            times[label].append(time_compute(c, occ, grid, costmap=costmap)[0])
    for label, t in times.items():
        report(f"compiled trials + terrain critic {label}", np.concatenate(t))
    off_med, on_med = (float(np.median(np.concatenate(t))) for t in times.values())
    print(f"{'':<9}critic on / off = {on_med / off_med:.2f} ({rounds} × 190 calls each); "
          f"numpy and compiled give the same commands with it on: {same}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--terrain-weight", type=float, default=None,
                    help="also time the terrain critic with this weight (on against off)")
    ap.add_argument("--controller", choices=CONTROLLERS[:2], default="paper",
                    help="the terrain case's controller (its critic is the --terrain-weight)")
    ap.add_argument("--cpu-time", action="store_true",
                    help="time calls by the thread's CPU time (on busy cores)")
    bench = Benchmark("bench_control", ap)
    args = ap.parse_args()
    if args.cpu_time:
        CLOCK["now"] = time.thread_time
    cfg = MPPIConfig()
    print(f"MPPI {cfg.batch_size} samples × {cfg.time_steps} steps, model_dt {cfg.model_dt} s,"
          f" one thread, {'CPU time' if args.cpu_time else 'wall clock'}")
    grid = GridSpec((-20.0, -40.0), 0.4, (200, 400))  # 160 m × 80 m at 0.4 m
    occ = np.zeros(grid.shape, np.uint8)
    rng = np.random.default_rng(0)
    r, c = rng.integers(0, grid.height, 300), rng.integers(0, grid.width, 300)
    X, Y = grid.cell_to_xy(r, c)
    keep = np.abs(Y - 4.0 * np.sin(2 * np.pi * X / 40.0)) > 4.0  # trees away from the path
    occ[r[keep], c[keep]] = 1
    van = dataclasses.replace(cfg, **vehicle_footprint(get_vehicle("mercedes_van")))
    cases = [("no occupancy", cfg, None, None),
             ("occupancy 200×400 grid, 1 circle", cfg, occ, grid),
             (f"occupancy, {len(van.footprint_offsets_m)} circles (trials)", van, occ, grid),
             ("batch 300 (tests)", MPPIConfig(batch_size=300), None, None)]
    rows = []
    for label, c, o, g in cases:
        runs = {b: time_compute(c, o, g, backend=b) for b in BACKENDS}
        for b, (t, _) in runs.items():
            report(f"{b:<8} {label}", t)
        same = np.array_equal(runs["compiled"][1], runs["numpy"][1])
        compiled, numpy_ = (float(np.median(runs[b][0])) for b in ("compiled", "numpy"))
        print(f"{'':<9}compiled {numpy_ / compiled:.1f}× faster; the same commands: {same}")
        rows.append([label, f"{1e3 * compiled:.2f} ms", f"**{1 / compiled:,.0f} Hz**",
                     f"{1e3 * numpy_:.2f} ms", f"{numpy_ / compiled:.1f}×",
                     "yes" if same else "**no**"])

    if args.terrain_weight is not None:
        terrain_case(dataclasses.replace(van, **controller_settings(args.controller)), occ,
                     grid, args.terrain_weight)

    (compiled, ours), (numpy_, theirs) = (time_noise(van, g) for g in (NormalStream,
                                                                      np.random.default_rng))
    same = np.array_equal(ours, theirs)
    print(f"{'':<9}of which the noise draw (2 × {van.time_steps} × {van.batch_size} float32 "
          f"normals): {compiled:.2f} ms compiled, {numpy_:.2f} ms numpy's generator "
          f"({numpy_ / compiled:.1f}×); the same numbers: {same}")
    rows.append([f"of which the noise draw (2 × {van.time_steps} × {van.batch_size:,} "
                 "normals; numpy's generator in the reference column)", f"{compiled:.2f} ms",
                 "", f"{numpy_:.2f} ms", f"{numpy_ / compiled:.1f}×", "yes" if same else "**no**"])
    clock = "this thread's CPU time" if args.cpu_time else "wall clock"
    bench.finish({"mppi": table(
        f"MPPI per `compute` call, {cfg.batch_size} samples × {cfg.time_steps} steps, one "
        f"thread, {clock} (median of 190 calls along an S-curve)",
        ["case", "compiled (default)", "rate", "numpy reference", "speed-up",
         "the same commands"], rows)}, args.publish)

    path = s_curve()
    ctrl = MPPIController(cfg, wheelbase_m=WHEELBASE_M, max_steer_rad=MAX_STEER_RAD, seed=0)
    plant = KinematicBicycle(WHEELBASE_M, MAX_STEER_RAD, steer_noise_std_rad=0.02, seed=1)
    t0 = time.perf_counter()
    tr = simulate_tracking(ctrl, plant, path, duration_s=60.0)
    wall = time.perf_counter() - t0
    cte = cross_track_errors(path, tr["pose"])
    print(
        f"closed loop, 120 m S-curve (kinematic bicycle, lag + noise): {len(cte)} steps in"
        f" {wall:.1f} s; cross-track mean {cte.mean():.3f} m, max {cte.max():.3f} m;"
        f" mean speed {tr['speed'].mean():.2f} m/s"
    )


if __name__ == "__main__":
    main()
