"""Speed of the self-supervised data stages: BEV accumulation, patches, locomotion.

Run: ``.venv/bin/python benchmarks/bench_bev.py``. Sizes are the paper profile's:
a 300 m world (750 × 750 cells at 0.4 m), 52k patches, 1,300 runs of 100 s.
Frames are synthetic (a camera 2 m above a tilted plane), so only our code is timed.
"""

from __future__ import annotations

import time

import numpy as np

from dgt_lib.core.camera import CameraIntrinsics, RGBDFrame
from dgt_lib.core.geometry import GridSpec
from dgt_lib.perception.bev import BEVAccumulator
from dgt_lib.perception.locomotion import locomotion_signal
from dgt_lib.perception.patches import extract_patches, rotate_map, unrotate_map


def synthetic_frame(width: int, height: int, rng: np.random.Generator) -> RGBDFrame:
    """A camera 2 m above flat ground at a random place, pitched 25° down."""
    intr = CameraIntrinsics(width, height, np.deg2rad(60))
    heading, pitch = rng.uniform(0, 2 * np.pi), np.deg2rad(25)
    fwd = np.array([np.cos(pitch) * np.cos(heading), np.cos(pitch) * np.sin(heading),
                    -np.sin(pitch)])
    x = np.array([np.sin(heading), -np.cos(heading), 0.0])
    z = -fwd
    rot = np.stack([x, np.cross(z, x), z], axis=1)  # world_from_camera
    f = intr.focal_px
    v, u = np.mgrid[0:height, 0:width] + 0.5
    d = np.stack([(u - width / 2) / f, -(v - height / 2) / f, -np.ones_like(u)], -1) @ rot.T
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -2.0 / d[..., 2]
    depth = np.where((t > 0) & (t < 40), t, np.nan).astype(np.float32)
    rgb = rng.integers(0, 255, (height, width, 3), dtype=np.uint8)
    pos = np.array([rng.uniform(20, 280), rng.uniform(20, 280), 2.0])
    return RGBDFrame(rgb, depth, intr, pos, rot)


def timed(label: str, fn, repeat: int = 3) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    print(f"{label:58s} {best * 1e3:9.1f} ms")
    return best


def main() -> None:
    rng = np.random.default_rng(0)
    grid = GridSpec((0.0, 0.0), 0.4, (750, 750))
    acc = BEVAccumulator(grid)
    for w, h in ((128, 96), (320, 240)):
        frames = [synthetic_frame(w, h, rng) for _ in range(20)]
        dt = timed(f"add_frame {w}x{h}, 20 frames, 750x750 grid",
                   lambda frames=frames: [acc.add_frame(f) for f in frames])
        print(f"{'':58s} {20 / dt:9.0f} frames/s")
    timed("result() 750x750", acc.result)
    bev = acc.result()
    bev.observed[:] = True  # time the full-map paths

    poses = np.column_stack([rng.uniform(5, 295, 52_000), rng.uniform(5, 295, 52_000),
                             rng.uniform(0, 2 * np.pi, 52_000)])
    dt = timed("extract_patches, 52k poses", lambda: extract_patches(bev, poses))
    print(f"{'':58s} {52_000 / dt:9.0f} patches/s")
    rotated = rotate_map(bev, 0.7)
    timed(f"rotate_map 750x750 -> {rotated.transform.shape}", lambda: rotate_map(bev, 0.7))
    timed("unrotate_map, 1 layer", lambda: unrotate_map(rotated.channels[3], rotated.transform))

    t = np.arange(0, 100, 0.04)
    runs = [np.cumsum(rng.uniform(0, 0.2, (len(t), 2)), axis=0) for _ in range(50)]
    dt = timed("locomotion_signal, 50 runs x 2500 samples",
               lambda: [locomotion_signal(t, p) for p in runs])
    print(f"{'':58s} {50 / dt:9.0f} runs/s")


if __name__ == "__main__":
    main()
