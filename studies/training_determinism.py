"""Is training bit-reproducible from one process to the next on this machine?

    .venv/bin/python studies/training_determinism.py --profile paper --processes 6
    .venv/bin/python studies/training_determinism.py --profile demo --kind single:jeep

Trains the profile's model ``--kind`` (default the multi-task one) for the first epoch —
the profile's recipe, the run seed's cached dataset (run ``dgt reproduce`` first), the
stage's training seed and ImageNet weights — in ``--processes`` fresh Python processes one
after another, and compares what each saw: every step's training loss, the epoch's
training and validation loss. On one machine with the same thread count these should be
equal to the bit; the table says in which process and at which step they first differ.
Environment variables pass to every process (e.g. ``MKL_CBWR=AVX512`` to pin MKL's code
path; the table shows it). ``--steps N`` stops each process after N steps (a quicker check:
where processes diverged, they did from the second step).
The run is one epoch long, so a cosine learning-rate schedule (``demo``) decays over that
epoch: the check is whether processes agree, not the recipe's first epoch.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

from runner import Study


class _Stop(Exception):
    """Raised from the batch callback to end training after ``--steps`` steps."""


def child(profile_name: str, seed: int, kind: str, steps: int | None) -> None:
    """Train in this process and print one JSON line: losses and epoch metrics."""
    import dataclasses

    import torch

    from dgt_lib.core import artifacts
    from dgt_lib.core.config import get_profile
    from dgt_lib.learning.run import train_model
    from dgt_lib.perception.dataset import PatchDataset
    from dgt_lib.stages.dataset import DATASET_RELPATH
    from dgt_lib.stages.paths import data_dir
    from dgt_lib.stages.train import parse_kind, rgb_weights_for

    prof = get_profile(profile_name).with_(seed=seed)
    dataset = PatchDataset.from_arrays(artifacts.load(data_dir(prof) / DATASET_RELPATH))
    cfg = dataclasses.replace(prof.train, epochs=1)
    rgb = rgb_weights_for(cfg)
    losses: list[float] = []

    def on_batch_end(epoch: int, step: int, loss: float) -> None:
        losses.append(loss)
        if steps is not None and len(losses) >= steps:
            raise _Stop

    out = {"pid": os.getpid(), "threads": torch.get_num_threads(),
           "mkl_cbwr": os.environ.get("MKL_CBWR")}
    try:
        result = train_model(dataset, cfg, vehicles=parse_kind(kind), seed=prof.seed,
                             device="cpu", progress=False, rgb_weights=rgb,
                             on_batch_end=on_batch_end, keep_best_on_interrupt=False)
        out.update(train_loss=result.history[0]["train_loss"],
                   val_loss=result.history[0]["val_loss"],
                   seconds=result.history[0]["seconds"])
    except _Stop:
        pass
    out["losses"] = losses
    print(json.dumps(out))


def _first_difference(a: list[float], b: list[float]) -> int | None:
    """Index of the first step whose loss differs (or where one sequence ends), or None."""
    for i, (x, y) in enumerate(zip(a, b, strict=False)):
        if x != y:
            return i
    return None if len(a) == len(b) else min(len(a), len(b))


def main() -> None:
    study = Study("training_determinism", __doc__, profile="demo", seeds=1, publishes=False)
    parser = study.parser
    parser.add_argument("--kind", default="multitask", help="multitask or single:<vehicle>")
    parser.add_argument("--processes", type=int, default=4)
    parser.add_argument("--steps", type=int, default=None,
                        help="stop each process after this many steps (default: the epoch)")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = study.parse()
    if len(study.seeds) != 1:
        parser.error("one run seed (its cached dataset): --seed S")
    seed = study.seeds[0]
    if args.child:
        child(args.profile, seed, args.kind, args.steps)
        return
    print(f"{args.profile} seed {seed}, {args.kind}, first epoch"
          + (f" (first {args.steps} steps)" if args.steps else "")
          + f", {args.processes} fresh processes one after another; "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f} at the start\n")
    command = [sys.executable, __file__, "--child", "--profile", args.profile,
               "--seed", str(seed), "--kind", args.kind]
    if args.steps:
        command += ["--steps", str(args.steps)]
    runs = []
    print("| process | torch threads | MKL_CBWR | steps | epoch train loss | val loss | "
          "first step ≠ process 1 | wall [s] |\n| --- | --- | --- | --- | --- | --- | --- | --- |")
    for i in range(args.processes):
        t0 = time.perf_counter()
        done = subprocess.run(command, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            raise SystemExit(f"process {i + 1} failed:\n{done.stderr[-2000:]}")
        run = json.loads(done.stdout.strip().splitlines()[-1])
        runs.append(run)
        diff = _first_difference(runs[0]["losses"], run["losses"])
        print(f"| {i + 1} | {run['threads']} | {run['mkl_cbwr'] or '—'} | "
              f"{len(run['losses'])} | "
              f"{run.get('train_loss', float('nan')):.10f} | "
              f"{run.get('val_loss', float('nan')):.10f} | {'—' if diff is None else diff} | "
              f"{time.perf_counter() - t0:.0f} |", flush=True)
    outcomes = {json.dumps(r["losses"]) for r in runs}
    print(f"\n{len(outcomes)} distinct loss sequence(s) in {len(runs)} processes")


if __name__ == "__main__":
    main()
