"""Speed of data collection: episodes per vehicle, the mapping survey, the whole collection.

Run: ``.venv/bin/python benchmarks/bench_collect.py [--profile paper] [--episodes 2]``.

1. Per vehicle, ``--episodes`` episodes of the profile's configuration on its
   training world, in this process (one worker), once with onboard frames and
   once without, so the rendering share is measured: simulated seconds, wall and
   CPU seconds, frames, BEV cells touched, patches, patches per wall-minute.
2. The mapping survey of every world: frames, wall seconds, coverage, median
   |H̄ − h|.
3. ``--pool K``: K episodes per vehicle through ``collect_episodes`` with the
   default process pool (``profile.workers`` processes) in a temporary data
   directory — the real thing, including process start-up. Its throughput
   (simulated seconds per wall second) and the sample's mean episode length per
   vehicle give the estimate of the whole profile's collection:
   Σ_v episodes_v × mean length_v / throughput.
4. ``--lp-threads 1 0``: the same in-process episodes in a fresh process per value of
   Mesa llvmpipe's ``LP_NUM_THREADS`` (read when a process makes its first OpenGL
   context; the pool's workers use 1, ``dgt_lib.core.executors.THREAD_VARS``),
   alternating ``--repeats`` times: wall and CPU seconds and a digest of every frame's
   RGB and depth, so a setting that changed the frames would show.
5. ``--tile-cache 16 64 256``: would keeping several terrain tiles uploaded pay? Over
   ``--episodes`` per vehicle (interleaved, as a worker gets them), every switch of
   :class:`~dgt_lib.world.rendering.TerrainRenderer`'s tile re-uploads its heightfield
   (~35 ms on llvmpipe); printed: the switches, the distinct tiles, how many switches an
   LRU cache of K uploaded tiles would have served, and the memory one more OpenGL
   context of a tile takes (the cost of holding a tile uploaded).
6. ``--frame-levers N``: levers that would change every frame, timed on N onboard
   poses of the training world: the frame on its collection tile, the same without
   multisampling (``vis.quality.offsamples`` 0: the RGB pass is not antialiased), on a
   crop of the world to the frame's frustum (its horizontal bounding box up to the
   collection's depth), with the heightfield and texture uploads a crop per frame would
   add, and the depth image ray-cast by MuJoCo instead (``mj_multiRay``, one ray through
   each pixel's centre on the same tile, no colour). Medians in ms, and the cells drawn.
7. ``--tile-lattice 16:reach 8:box``: the collection's own episodes (``--episodes`` per
   vehicle) rendered on other terrain tiles — ``S:reach``, tiles on an S m lattice reaching
   the frame's farthest point from the camera in every direction (the collection's, S =
   :data:`~dgt_lib.world.rendering.TILE_STRIDE_M`), ``S:box``, tiles only as large as the
   frustum's horizontal bounding box can get (its half-extent's maximum over camera
   headings, pitch ±45° and roll ±35°); ``:flat`` appended draws the colour without
   multisampling. Printed per lattice: the time inside ``render`` (tile switches
   included), the switches, the frames whose box a tile missed, and against the first
   lattice the in-range depth's median |Δ| and share of pixels off by more than 1 cm, and
   the colour's.

Timings on the shared 2-core machine vary with its load; the load average is printed.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import replace

import numpy as np

from dgt_lib.core.config import VEHICLES, get_profile
from dgt_lib.perception.bev import BEVAccumulator, bev_grid, bev_quality
from dgt_lib.perception.dataset import patch_times
from dgt_lib.perception.episodes import episode_seed, run_episode
from dgt_lib.perception.locomotion import WINDOW_S
from dgt_lib.stages.collect import build_world_bev as build_bev
from dgt_lib.stages.collect import collect_episodes
from dgt_lib.world import rendering
from dgt_lib.world.rendering import survey_poses
from dgt_lib.world.terrain import WORLD_NAMES, get_world


def per_vehicle(prof, n_episodes: int) -> None:
    cfg = prof.collect
    world = get_world("training", prof)
    print(f"{'vehicle':13s} {'sim s':>6s} {'wall s':>7s} {'cpu s':>6s} {'render s':>8s} "
          f"{'frames':>6s} {'cells/ep':>8s} {'patches':>7s} {'patch/min':>9s}  end reasons")
    sparse = []
    for v in VEHICLES:
        sim_s = wall = cpu = wall_norender = 0.0
        frames = cells = patches = 0
        reasons = []
        for i in range(n_episodes):
            seed = episode_seed(prof.seed, v, i)
            t0, c0 = time.perf_counter(), time.process_time()
            ep = run_episode(world, v, seed, cfg, index=i)
            t1, c1 = time.perf_counter(), time.process_time()
            run_episode(world, v, seed, cfg, index=i, render=False)
            wall_norender += time.perf_counter() - t1
            wall += t1 - t0
            cpu += c1 - c0
            sim_s += ep.duration_s
            frames += ep.n_frames
            cells += len(ep.bev["cells"])
            sparse.append(ep.bev)
            patches += len(patch_times(ep.time_s, ep.valid, cfg.patch_interval_s,
                                       cfg.patch_start_s, WINDOW_S))
            reasons.append(ep.end_reason)
        print(f"{v:13s} {sim_s:6.0f} {wall:7.1f} {cpu:6.1f} {wall - wall_norender:8.1f} "
              f"{frames:6d} {cells // n_episodes:8d} {patches:7d} {60 * patches / wall:9.0f}  "
              f"{', '.join(reasons)}")
    acc = BEVAccumulator(bev_grid(world.grid.extent))
    t0 = time.perf_counter()
    for s in sparse:
        acc.add_sparse(s)
    dt = time.perf_counter() - t0
    print(f"merging one episode's BEV statistics into the map: {1e3 * dt / len(sparse):.1f} ms")


def survey(prof) -> None:
    print(f"{'world':9s} {'cells':>11s} {'frames':>6s} {'wall s':>7s} {'coverage':>8s} "
          f"{'|H-h| med':>9s}")
    for name in WORLD_NAMES:
        w = get_world(name, prof)
        t0 = time.perf_counter()
        bev, n, _ = build_bev(w, prof.collect)
        dt = time.perf_counter() - t0
        q = bev_quality(bev, w)
        assert n == len(survey_poses(w, prof.collect))
        print(f"{name:9s} {str(w.grid.shape):>11s} {n:6d} {dt:7.1f} {q['coverage']:8.2%} "
              f"{100 * q['height_median_abs_err_m']:7.2f}cm")


def pooled(prof, k: int) -> None:
    sample = prof.with_(collect=replace(prof.collect, episodes=(k,) * len(VEHICLES)))
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["DGT_DATA_DIR"] = tmp
        t0, c0, k0 = time.perf_counter(), time.process_time(), _children_cpu()
        episodes = collect_episodes(sample, progress=False)  # shuts its pool down
        wall = time.perf_counter() - t0
        cpu = time.process_time() - c0 + _children_cpu() - k0
    sim_s = sum(e.duration_s for e in episodes)
    rate = sim_s / wall
    print(f"{len(episodes)} episodes through a pool of {prof.workers} workers: {wall:.1f} s wall "
          f"for {sim_s:.0f} simulated s = {rate:.1f}× real time; {cpu:.0f} CPU s "
          f"({1e3 * cpu / sim_s:.0f} ms per simulated s)")
    expected = 0.0
    for v, n in zip(VEHICLES, prof.collect.episodes, strict=True):
        mean_s = np.mean([e.duration_s for e in episodes if e.vehicle == v])
        expected += n * mean_s
        print(f"  {v:13s} mean episode {mean_s:5.1f} s")
    print(f"estimated collection of '{prof.name}' ({sum(prof.collect.episodes)} episodes, "
          f"~{expected / 3600:.1f} simulated h) with {prof.workers} workers: "
          f"{expected / rate / 60:.0f} min at this load, "
          f"{expected * cpu / sim_s / prof.workers / 60:.0f} min on idle cores (CPU time)")


def frames_digest(prof, n_episodes: int) -> None:
    """Run ``n_episodes`` per vehicle in this process; print frames, wall and CPU seconds
    and a digest of every onboard frame (what ``--lp-threads`` runs in each subprocess)."""
    world = get_world("training", prof)
    digest, frames = hashlib.sha256(), 0
    render = rendering.TerrainRenderer.render

    def hashed(self, pose):
        nonlocal frames
        frame = render(self, pose)
        digest.update(frame.rgb.tobytes())
        digest.update(frame.depth.tobytes())
        frames += 1
        return frame

    rendering.TerrainRenderer.render = hashed
    t0, c0 = time.perf_counter(), time.process_time()
    for v in VEHICLES:
        for i in range(n_episodes):
            run_episode(world, v, episode_seed(prof.seed, v, i), prof.collect, index=i)
    print(f"{frames} {time.perf_counter() - t0:.3f} {time.process_time() - c0:.3f} "
          f"{digest.hexdigest()[:16]}")


def lp_threads(prof, values: list[str], n_episodes: int, repeats: int) -> None:
    print(f"{n_episodes} episodes per vehicle in a fresh process per LP_NUM_THREADS value, "
          f"{repeats} rounds")
    print(f"{'LP_NUM_THREADS':>14s} {'frames':>6s} {'wall s':>7s} {'cpu s':>6s}  frames digest")
    walls: dict[str, list[float]] = {v: [] for v in values}
    for _ in range(repeats):
        for value in values:
            env = {**os.environ, "LP_NUM_THREADS": value}
            out = subprocess.run([sys.executable, __file__, "--profile", prof.name,
                                  "--episodes", str(n_episodes), "--frames-digest"],
                                 env=env, check=True, capture_output=True, text=True)
            frames, wall, cpu, digest = out.stdout.split()[-4:]
            walls[value].append(float(wall))
            print(f"{value:>14s} {frames:>6s} {float(wall):7.2f} {float(cpu):6.2f}  {digest}")
    base = np.median(walls[values[0]])
    for value in values[1:]:
        print(f"LP_NUM_THREADS={value}: median wall {np.median(walls[value]):.2f} s against "
              f"{base:.2f} s with {values[0]} ({base / np.median(walls[value]):.2f}×)")


def tile_cache(prof, n_episodes: int, sizes: list[int]) -> None:
    import collections

    import mujoco

    from dgt_lib.world.simulator import FrameRenderers

    world = get_world("training", prof)
    switches: list[tuple[int, int]] = []
    tile = rendering.TerrainRenderer._tile

    def recorded(self, key):
        if key != self._current:
            switches.append(key)
        return tile(self, key)

    rendering.TerrainRenderer._tile = recorded
    t0 = time.perf_counter()
    for i in range(n_episodes):
        for v in VEHICLES:
            run_episode(world, v, episode_seed(prof.seed, v, i), prof.collect, index=i)
    wall = time.perf_counter() - t0
    rendering.TerrainRenderer._tile = tile
    renderer = rendering.terrain_renderer(world, prof.collect.frame_max_depth_m)
    sim, r = renderer._tile(renderer._current), renderer._renderers.rgb
    r._gl_context.make_current()
    t0 = time.perf_counter()
    for _ in range(10):
        mujoco.mjr_uploadHField(sim.model, r._mjr_context, sim.model.hfield("terrain").id)
    upload = (time.perf_counter() - t0) / 10
    print(f"{n_episodes} episodes per vehicle in {wall:.1f} s: {len(switches)} tile uploads "
          f"of {1e3 * upload:.0f} ms (~{len(switches) * upload / wall:.0%} of the time), "
          f"{len(set(switches))} distinct tiles of {renderer.tile_shape} cells")
    for k in sizes:
        cache: collections.OrderedDict = collections.OrderedDict()
        served = 0
        for key in switches:
            if key in cache:
                served += 1
                cache.move_to_end(key)
            else:
                cache[key] = None
                if len(cache) > k:
                    cache.popitem(last=False)
        print(f"  {k:4d} tiles kept uploaded: {served} of {len(switches)} uploads saved "
              f"({served / len(switches):.0%})")

    def rss_mb() -> float:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20

    grown, kept = [], []
    for key in list(dict.fromkeys(switches))[:4]:
        sim = renderer._tile(key)
        before = rss_mb()
        r = FrameRenderers.create(sim.model, renderer.camera.height, renderer.camera.width)
        r.rgb.update_scene(sim.data)
        r.rgb.render()
        grown.append(rss_mb() - before)
        kept.append(r)
    print(f"one more OpenGL context of a tile: +{min(grown):.0f} to +{max(grown):.0f} MB "
          f"resident ({len(grown)} contexts)")


def _ms(fn, *args, **kwargs) -> float:
    """Milliseconds ``fn(*args, **kwargs)`` took."""
    t0 = time.perf_counter()
    fn(*args, **kwargs)
    return 1e3 * (time.perf_counter() - t0)


def frame_levers(prof, n_poses: int) -> None:
    import mujoco

    from dgt_lib.world.simulator import FrameRenderers, Simulator

    world = get_world("training", prof)
    tiles = rendering.TerrainRenderer(world, prof.collect.frame_max_depth_m)
    cam, res = tiles.camera, world.grid.resolution
    driver, rng = Simulator(world, "jeep"), np.random.default_rng(0)
    x0, x1, y0, y1 = world.extent
    ms: dict[str, list[float]] = {"tile": [], "tile, no multisampling": [],
                                  "frustum crop": [], "crop's uploads": [],
                                  "ray-cast depth": []}
    tan_v = np.tan(0.5 * cam.fovy_rad)  # a ray through each pixel's centre, camera frame
    u = ((np.arange(cam.width) + 0.5) / cam.width * 2 - 1) * tan_v * cam.width / cam.height
    v = (1 - (np.arange(cam.height) + 0.5) / cam.height * 2) * tan_v
    rays = np.stack(np.broadcast_arrays(u[None, :], v[:, None], -1.0), -1).reshape(-1, 3)
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    hit, dist = np.zeros(len(rays), np.int32), np.zeros(len(rays))
    cells = []
    for _ in range(n_poses):
        driver.reset(rng.uniform(x0 + 40, x1 - 40), rng.uniform(y0 + 40, y1 - 40),
                     rng.uniform(0, 2 * np.pi))
        for _ in range(10):
            driver.step(speed_cmd_mps=5.0, steer=0.2)
        pose = rendering.onboard_camera_pose(driver)
        tiles.render(pose)  # the tile uploaded: a frame that needs no switch
        ms["tile"].append(_ms(tiles.render, pose))
        sim = tiles._tile(tiles._current)
        samples, sim.model.vis.quality.offsamples = sim.model.vis.quality.offsamples, 0
        plain = FrameRenderers.create(sim.model, cam.height, cam.width, separate_depth=False)
        sim.share_renderers(plain)
        sim.render_rgbd(pose, intrinsics=cam, show_vehicle=False)
        ms["tile, no multisampling"].append(
            _ms(sim.render_rgbd, pose, intrinsics=cam, show_vehicle=False))
        plain.close()
        sim.model.vis.quality.offsamples = samples  # read only when a context is made
        ms["ray-cast depth"].append(_ms(
            mujoco.mj_multiRay, sim.model, sim.data, np.asarray(pose[0], np.float64),
            (rays @ np.asarray(pose[1]).T).ravel(), None, 1, -1, hit, dist, None, len(rays),
            tiles.max_depth_m))
        sim.share_renderers(tiles._renderers)
        bx0, bx1, by0, by1 = tiles.footprint(pose)  # the crop: a renderer of its own size
        crop = rendering.TerrainRenderer(world, tiles.max_depth_m)
        rows, cols = world.grid.xy_to_rc(np.array([bx0, bx1]), np.array([by0, by1]))
        r0, c0 = max(0, int(rows.min()) - 1), max(0, int(cols.min()) - 1)
        crop.tile_shape = (min(int(rows.max()) + 2, world.grid.height) - r0,
                           min(int(cols.max()) + 2, world.grid.width) - c0)
        cropped = crop._tile((r0, c0))
        own = FrameRenderers.create(cropped.model, cam.height, cam.width)
        cropped.share_renderers(own)
        cropped.render_rgbd(pose, intrinsics=cam, show_vehicle=False)
        ms["frustum crop"].append(
            _ms(cropped.render_rgbd, pose, intrinsics=cam, show_vehicle=False))
        own.rgb._gl_context.make_current()
        m, context = cropped.model, own.rgb._mjr_context
        ms["crop's uploads"].append(
            _ms(mujoco.mjr_uploadHField, m, context, m.hfield("terrain").id)
            + _ms(mujoco.mjr_uploadTexture, m, context, m.texture("terrain_tex").id))
        own.close()
        cells.append(crop.tile_shape[0] * crop.tile_shape[1])
    print(f"{n_poses} onboard frames on the training world ({prof.collect.frame_max_depth_m:g} m "
          f"depth); tile {tiles.tile_shape[0] * tiles.tile_shape[1]:,} cells, frustum crop "
          f"median {np.median(cells):,.0f} cells ({res} m)")
    for name, values in ms.items():
        print(f"  {name:24s} {np.median(values):6.1f} ms")


def box_half_extent_m(max_depth_m: float, cam) -> float:
    """The largest horizontal half-extent [m] of a frame's frustum box (camera and far
    corners at ``max_depth_m``) over camera yaw, pitch ±45° and roll ±35°."""
    tan_x, tan_y = rendering._tan_half_fov(cam)
    corners = np.array([[sx * tan_x, sy * tan_y, -1.0] for sx in (-1, 1) for sy in (-1, 1)])
    corners *= max_depth_m
    forward = np.array([[0, 0, -1], [-1, 0, 0], [0, 1, 0]], float)  # looking along +x
    best = 0.0
    for yaw in np.radians(np.arange(0, 360, 5)):
        for pitch in np.radians(np.arange(-45, 46, 5)):
            for roll in np.radians(np.arange(-35, 36, 5)):
                cy, sy, cp, sp, cr, sr = (np.cos(yaw), np.sin(yaw), np.cos(pitch),
                                          np.sin(pitch), np.cos(roll), np.sin(roll))
                rot = (np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
                       @ np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
                       @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]]) @ forward)
                pts = np.vstack([np.zeros(3), corners @ rot.T])[:, :2]
                best = max(best, float((pts.max(0) - pts.min(0)).max()) / 2)
    return best


def tile_lattice(prof, n_episodes: int, specs: list[str]) -> None:
    import math

    from dgt_lib.world.simulator import FrameRenderers

    world = get_world("training", prof)
    depth_m, res = prof.collect.frame_max_depth_m, world.grid.resolution
    box = box_half_extent_m(depth_m, rendering.CAMERA)
    print(f"{n_episodes} collection episodes per vehicle on the {world.grid.shape} training "
          f"world; frame reach {rendering.frame_reach_m(depth_m):.1f} m, frustum box "
          f"half-extent ≤ {box:.1f} m; load average {os.getloadavg()[0]:.1f}")
    render, create, stride = rendering.TerrainRenderer.render, FrameRenderers.create, \
        rendering.TILE_STRIDE_M
    base: list = []
    for spec in specs:
        step, bound, *flat = spec.split(":")
        frames, spent, missed, switches = [], [0.0], [0], [0]
        rendering.TILE_STRIDE_M = float(step)
        rendering._RENDERERS.clear()
        renderer = rendering.terrain_renderer(world, depth_m)
        if bound == "box":
            n = int(math.ceil(2 * (box + 0.5 * float(step) + res) / res))
            renderer.tile_shape = tuple(min(n, m) for m in world.grid.shape)

        def timed(self, pose, frames=frames, spent=spent, missed=missed, switches=switches):
            before, t0 = self._current, time.perf_counter()
            frame = render(self, pose)
            spent[0] += time.perf_counter() - t0
            switches[0] += self._current != before
            missed[0] += not self._covers(self._current, self.footprint(pose))
            frames.append((frame.rgb, frame.depth))
            return frame

        def plain(model, height, width, separate_depth=None):
            samples, model.vis.quality.offsamples = model.vis.quality.offsamples, 0
            try:
                return create(model, height, width, separate_depth)
            finally:
                model.vis.quality.offsamples = samples

        rendering.TerrainRenderer.render = timed
        FrameRenderers.create = staticmethod(plain) if flat else create
        try:
            for i in range(n_episodes):
                for v in VEHICLES:
                    run_episode(world, v, episode_seed(prof.seed, v, i), prof.collect, index=i)
        finally:
            rendering.TerrainRenderer.render, FrameRenderers.create = render, create
            rendering.TILE_STRIDE_M = stride
            renderer._renderers.close()
            rendering._RENDERERS.clear()
        line = (f"  {spec:14s} tile {renderer.tile_shape[0]}×{renderer.tile_shape[1]}: "
                f"{1e3 * spent[0] / len(frames):5.1f} ms a frame ({len(frames)} frames, "
                f"{switches[0]} switches, {missed[0]} boxes missed)")
        if base:
            d_depth, off, d_rgb = [], 0, []
            for (rgb0, d0), (rgb1, d1) in zip(base, frames, strict=True):
                both = (d0 <= depth_m) & (d1 <= depth_m)  # NaN compares False
                d_depth.append(np.abs(d0[both] - d1[both]))
                off += int((np.abs(d0[both] - d1[both]) > 0.01).sum())
                d_rgb.append(np.abs(rgb0[both].astype(int) - rgb1[both].astype(int)))
            d_depth, d_rgb = np.concatenate(d_depth), np.concatenate(d_rgb)
            line += (f"; depth median |Δ| {np.median(d_depth):.1e} m, {off / d_depth.size:.2%}"
                     f" of pixels off > 1 cm; colour mean |Δ| {d_rgb.mean():.2f} of 255")
        else:
            base = frames
        print(line, flush=True)


def _children_cpu() -> float:
    """User + system CPU seconds of this process's reaped child processes."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="demo")
    parser.add_argument("--episodes", type=int, default=2, help="per vehicle, in-process")
    parser.add_argument("--pool", type=int, default=0, help="per vehicle, through the pool")
    parser.add_argument("--skip-survey", action="store_true")
    parser.add_argument("--lp-threads", nargs="+", metavar="N",
                        help="compare llvmpipe thread counts (e.g. 1 0) on --episodes")
    parser.add_argument("--repeats", type=int, default=2, help="rounds of --lp-threads")
    parser.add_argument("--tile-cache", nargs="+", type=int, metavar="K",
                        help="tile uploads an LRU cache of K tiles would save, on --episodes")
    parser.add_argument("--frame-levers", type=int, default=0, metavar="N",
                        help="time N onboard frames on their tile, without multisampling, "
                             "on a crop to their frustum, and their depth ray-cast")
    parser.add_argument("--tile-lattice", nargs="+", metavar="S:reach|S:box[:flat]",
                        help="render --episodes on other tile lattices (the first is the "
                             "reference), e.g. 16:reach 8:box 8:box:flat")
    parser.add_argument("--frames-digest", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    prof = get_profile(args.profile)
    if args.frames_digest:
        return frames_digest(prof, args.episodes)
    if args.lp_threads:
        return lp_threads(prof, args.lp_threads, args.episodes, args.repeats)
    if args.tile_cache:
        return tile_cache(prof, args.episodes, args.tile_cache)
    if args.frame_levers:
        return frame_levers(prof, args.frame_levers)
    if args.tile_lattice:
        return tile_lattice(prof, args.episodes, args.tile_lattice)
    cfg = prof.collect
    print(f"profile {prof.name}: training world {get_world('training', prof).grid.shape} "
          f"cells, {cfg.episode_duration_s:.0f} s episodes, a frame every "
          f"{cfg.frame_spacing_m} m, a patch every {cfg.patch_interval_s} s; "
          f"load average {os.getloadavg()[0]:.1f}")
    if args.episodes:
        per_vehicle(prof, args.episodes)
    if not args.skip_survey:
        survey(prof)
    if args.pool:
        pooled(prof, args.pool)
    print(f"load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
