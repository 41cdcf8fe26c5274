"""Simulator speed: physics real-time factor per vehicle and RGB-D frames/s.

Run: ``.venv/bin/python benchmarks/bench_sim.py [--profile demo] [--seconds 60]``.

Real-time factor = simulated seconds / wall seconds while driving the training
world at 5 m/s with the PID speed controller at 25 Hz (the data-collection
controller), 20 s episodes from random poses, ended early like collection runs
(immobilized > 10 s, flipped, off the map). Physics share = the part of those wall
seconds spent inside ``mujoco.mj_step``: the kit's step runs at that fraction of the
speed of MuJoCo's own stepping of the same model with the same collisions (the rest
is the kit's control, the underside gate, the checks and the state read-out). "Of raw
stepping" checks it in the same run: the same drive (same seed, so the same steps) runs
three ways — with ``mj_step`` timed, for the physics share; with every ``mj_step`` call
recorded (its input state and the model fields the kit sets while driving: the
underside's collision bits, the brakes' friction); and bare, for the kit's driving time.
The recorded calls are replayed bare, one after another, on a fresh ``MjData``; bare
drives and replays alternate ``--repeats`` times, and the fastest replay over the fastest
bare drive is the kit's speed as a fraction of raw MuJoCo stepping of the very same steps.
RGB-D frames/s at the onboard camera's resolution (``sim.CAMERA``), RGB and depth
each rendered, on the training, hill and ridge worlds. ``--publish`` writes both tables'
record (``benchmarks/publish.py``) for docs/speed.md.
"""

from __future__ import annotations

import argparse
import math
import os
import time

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from publish import Benchmark  # noqa: E402

from dgt_lib.core.config import VEHICLES, get_profile
from dgt_lib.records.study import table
from dgt_lib.world.mujoco_model import CAMERA
from dgt_lib.world.simulator import CONTROL_DT_S, Simulator
from dgt_lib.world.terrain import get_world

FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS | mujoco.mjtState.mjSTATE_CTRL
"""What a replayed ``mj_step`` call starts from: the physics state and the controls."""


class PhysicsClock:
    """Wall seconds spent inside ``mujoco.mj_step`` while :attr:`on` (wraps it while in
    a ``with`` block) or, with ``record``, each such call's input state and the model
    fields the kit changes while driving, to replay the same calls bare (:meth:`replay_s`)."""

    def __init__(self, record: bool = False) -> None:
        self.seconds, self.driving_s, self.on, self._step = 0.0, 0.0, False, mujoco.mj_step
        self.record = record
        self.calls: list[tuple[np.ndarray, int, np.ndarray, np.ndarray]] = []
        self.model = None

    def _timed(self, m, d, nstep=1):
        if self.on and self.record:
            state = np.empty(mujoco.mj_stateSize(m, FULL))
            mujoco.mj_getState(m, d, state, FULL)
            self.calls.append((state, nstep, m.geom_conaffinity.copy(),
                               m.dof_frictionloss.copy()))
            self.model = m
        t = time.perf_counter()
        self._step(m, d, nstep=nstep)
        if self.on:
            self.seconds += time.perf_counter() - t

    def replay_s(self) -> float:
        """Wall seconds of the recorded ``mj_step`` calls run again one after another on a
        fresh ``MjData`` of the same model, each from its recorded state: raw MuJoCo
        stepping of the very steps the kit drove, without the kit around it."""
        m = self.model
        d = mujoco.MjData(m)
        total = 0.0
        for state, nstep, affinity, friction in self.calls:
            m.geom_conaffinity[:], m.dof_frictionloss[:] = affinity, friction
            mujoco.mj_setState(m, d, state, FULL)
            t = time.perf_counter()
            self._step(self.model, d, nstep=nstep)
            total += time.perf_counter() - t
        return total

    def __enter__(self) -> PhysicsClock:
        mujoco.mj_step = self._timed
        return self

    def __exit__(self, *exc) -> None:
        mujoco.mj_step = self._step


def physics_rtf(world, vehicle: str, sim_seconds: float,
                clock: PhysicsClock | None = None) -> tuple[float, float, float, float]:
    """(real-time factor per wall second, per CPU second, model build seconds, driving
    wall seconds) for driving ``sim_seconds`` at 5 m/s; ``clock`` counts the physics'
    part of the driving (not of the resets)."""
    t0 = time.perf_counter()
    sim = Simulator(world, vehicle)
    build_s = time.perf_counter() - t0
    rng = np.random.default_rng(0)
    x0, x1, y0, y1 = world.extent
    simulated, wall, cpu = 0.0, 0.0, 0.0
    while simulated < sim_seconds:
        st = sim.reset(rng.uniform(x0 + 15, x1 - 15), rng.uniform(y0 + 15, y1 - 15),
                       rng.uniform(0, 2 * np.pi))
        t, c = time.perf_counter(), time.process_time()
        if clock:
            clock.on = True
        for _ in range(int(20.0 / CONTROL_DT_S)):  # 20 s episodes, ended early if done
            st = sim.step(speed_cmd_mps=5.0, steer=0.2 * math.sin(0.2 * st.time_s))
            if st.done or st.immobilized_s > 10.0:  # collection respawns (paper: 10 s)
                break
        if clock:
            clock.on = False
        wall += time.perf_counter() - t
        cpu += time.process_time() - c
        simulated += st.time_s
    if clock:
        clock.driving_s = wall
    return simulated / wall, simulated / cpu, build_s, wall


def render_fps(world, frames: int = 30) -> tuple[float, float]:
    """RGB-D frames per wall second and per CPU second (plus one 25 Hz control step
    between frames)."""
    sim = Simulator(world, "jeep")
    x0, x1, y0, y1 = world.extent
    sim.reset((x0 + x1) / 2, (y0 + y1) / 2, 0.5)
    sim.render_rgbd()  # warm-up: creates the GL context and uploads the textures
    t, c = time.perf_counter(), time.process_time()
    for _ in range(frames):
        sim.step(speed_cmd_mps=5.0)
        sim.render_rgbd()
    fps = frames / (time.perf_counter() - t), frames / (time.process_time() - c)
    sim.close()
    return fps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--profile", default=None, help="smoke | demo | paper (default $DGT_PROFILE)")
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated seconds per vehicle")
    ap.add_argument("--repeats", type=int, default=5,
                    help="bare drives and replays per vehicle, the fastest of each kept")
    bench = Benchmark("bench_sim", ap)
    args = ap.parse_args()
    profile = get_profile(args.profile)
    world = get_world("training", profile)
    print(f"profile {profile.name}: training world {world.grid.shape[1]}×{world.grid.shape[0]} "
          f"cells at {world.resolution} m, {len(world.trees)} trees")
    physics_rtf(world, VEHICLES[0], 2.0)  # warm-up: the compiled gate loads once
    physics = []
    for name in VEHICLES:
        with PhysicsClock() as clock:
            physics_rtf(world, name, args.seconds, clock)
        with PhysicsClock(record=True) as calls:
            physics_rtf(world, name, args.seconds, calls)
        runs, replays = [], []
        for _ in range(args.repeats):  # alternating, so that both meet the same load
            runs.append(physics_rtf(world, name, args.seconds))
            replays.append(calls.replay_s())
        rtf, rtf_cpu, build_s, bare_s = max(runs)  # the fastest of the bare drives
        physics.append([name, f"**{rtf:.0f}×**", f"{rtf_cpu:.0f}×",
                        f"{clock.seconds / clock.driving_s:.2f}",
                        f"{min(replays) / bare_s:.2f}", f"{build_s:.2f} s"])
        print(" | ".join(physics[-1]), flush=True)
    frames = []
    for name in ("training", "hill", "ridge"):
        w = get_world(name, profile)
        fps, fps_cpu = render_fps(w)
        frames.append([name, f"{w.grid.shape[1]}×{w.grid.shape[0]}", f"**{fps:.1f}**",
                       f"{fps_cpu:.1f}"])
        print(" | ".join(frames[-1]), flush=True)
    bench.finish({
        "physics": table(
            f"Physics on the training world ({world.grid.shape[1]}×{world.grid.shape[0]} cells), "
            f"{args.seconds:g} simulated s per vehicle at 5 m/s, PID at "
            f"{1 / CONTROL_DT_S:.0f} Hz; physics share: the part of the wall time inside "
            "`mujoco.mj_step`; of raw stepping: the same `mj_step` calls replayed bare from "
            "their recorded states (with each call's collision bits and brake friction), "
            f"their time over the kit's uninstrumented drive (fastest of {args.repeats} each)",
            ["vehicle", "real time per wall second", "per CPU second", "physics share",
             "of raw stepping", "model build"], physics),
        "frames": table(
            f"RGB-D frames at {CAMERA.width}×{CAMERA.height} (RGB + depth) while driving the jeep",
            ["world", "cells", "frames per wall second", "per CPU second"], frames)},
        args.publish, profile=profile.name)

if __name__ == "__main__":
    main()
