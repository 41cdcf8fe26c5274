"""What resuming an interrupted training costs, and that it changes nothing.

    .venv/bin/python benchmarks/bench_resume.py --profile demo --seed 0 --check-interval 20
    .venv/bin/python benchmarks/bench_resume.py --profile demo --intervals 1e9 30 0 --repeats 2
    .venv/bin/python benchmarks/bench_resume.py --profile paper --interrupt-after 60 --intervals
    .venv/bin/python benchmarks/bench_resume.py --profile paper --kinds single:vw_van \
        --intervals 1e9 30 --interrupt-after -1

Needs the seed's dataset (``dgt reproduce --profile P --stages dataset``, or a whole run).
Each run is the real training stage (``dgt_lib.stages.train.models_stage``: the multi-task
model and the four single-task ones, or the ``--kinds`` given) in a fresh process, on a
temporary data directory that links the seed's episodes, BEV maps and dataset, so nothing
of ``data/`` is written.

1. ``--intervals``: the whole stage once per snapshot interval (``SNAPSHOT_EVERY_S``; 1e9
   = never, 0 = after every epoch), wall time each: what snapshots cost.
2. ``--interrupt-after S``: the stage with the default interval (or ``--check-interval``),
   SIGINT (as Ctrl-C) S seconds after its first snapshot appeared, then run again to the
   end; prints what each run said about the snapshot and compares every model's digest with the
   recorded seed's models (when ``data/<profile>/seed-<seed>/models`` has them) and with
   the uninterrupted run of 1.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dgt_lib.core import artifacts
from dgt_lib.stages.train import MODEL_KINDS

LINKED = ("episodes", "bev", "dataset.npz", "dataset.npz.meta.json")
STAGE = """
import signal, sys
signal.signal(signal.SIGINT, signal.default_int_handler)  # a background job ignores it
from dgt_lib.core.config import get_profile
from dgt_lib.stages import train
if sys.argv[1] != "default":
    train.SNAPSHOT_EVERY_S = float(sys.argv[1])
from dgt_lib.stages.dataset import ensure_dataset
profile = get_profile(sys.argv[2]).with_(seed=int(sys.argv[3]))
train.models_stage(profile, ensure_dataset(profile), kinds=tuple(sys.argv[4].split(",")))
"""


def fingerprints(models: Path) -> dict[str, str]:
    """{model file: prediction digest} of the models cached in ``models``."""
    return {p.name.removesuffix(".meta.json"): json.loads(p.read_text())["fingerprint"]
            for p in sorted(models.glob("*.pt.meta.json"))}


def run_stage(data: Path, interval: str, args, interrupt_after: float | None = None
              ) -> tuple[float, str]:
    """The training stage in a fresh process (wall time [s], its [dgt] lines); with
    ``interrupt_after``, SIGINT that many seconds after a snapshot file appeared."""
    env = {**os.environ, artifacts.DATA_ENV_VAR: str(data)}
    t0 = time.perf_counter()
    with tempfile.TemporaryFile("w+") as log:
        proc = subprocess.Popen([sys.executable, "-c", STAGE, interval, args.profile,
                                 str(args.seed), ",".join(args.kinds)], env=env, stdout=log,
                                stderr=subprocess.STDOUT)
        if interrupt_after is not None:
            while proc.poll() is None and not list(data.glob("*/*/models/*.resume.pt")):
                time.sleep(0.5)
            time.sleep(interrupt_after)
            proc.send_signal(signal.SIGINT)
        proc.wait()
        log.seek(0)
        said = "\n  ".join(re.findall(r"\[dgt\][^\r\n]*", log.read()))
    return time.perf_counter() - t0, said


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--profile", default="demo")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--intervals", nargs="*", default=["1e9", "30", "0"],
                    help="snapshot intervals [s] to time the whole stage with")
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--kinds", nargs="+", default=list(MODEL_KINDS),
                    help=f"the models to train (default all: {' '.join(MODEL_KINDS)})")
    ap.add_argument("--interrupt-after", type=float, default=1.0,
                    help="seconds from the first snapshot to the SIGINT of the resume check "
                         "(negative: no check)")
    ap.add_argument("--check-interval", default="default",
                    help="snapshot interval [s] of the resume check (default: the stage's, "
                         "60 s; `demo`'s models train faster than that)")
    args = ap.parse_args()
    seed_dir = artifacts.profile_dir(f"{args.profile}/seed-{args.seed}")
    missing = [name for name in LINKED if not (seed_dir / name).exists()]
    if missing:
        sys.exit(f"{seed_dir} lacks {missing}: run `dgt reproduce --profile {args.profile} "
                 f"--stages dataset` first")
    print(f"{args.profile} seed {args.seed}, {os.cpu_count()} CPUs, load average "
          f"{os.getloadavg()[0]:.1f}")
    recorded = fingerprints(seed_dir / "models")
    with tempfile.TemporaryDirectory(prefix="bench_resume_") as tmp:
        data = Path(tmp)
        run = data / args.profile / f"seed-{args.seed}"
        run.mkdir(parents=True)
        for name in LINKED:
            (run / name).symlink_to(seed_dir / name)
        models = run / "models"
        uninterrupted = None
        for _ in range(args.repeats):
            for interval in args.intervals:
                shutil.rmtree(models, ignore_errors=True)
                wall, _ = run_stage(data, interval, args)
                uninterrupted = uninterrupted or fingerprints(models)
                print(f"training stage, snapshot every {interval} s: {wall:.1f} s wall",
                      flush=True)
        if args.interrupt_after >= 0:
            shutil.rmtree(models, ignore_errors=True)
            wall1, said1 = run_stage(data, args.check_interval, args, args.interrupt_after)
            if not list(models.glob("*.resume.pt")):
                print(f"interrupted after {wall1:.0f} s, but no snapshot was left: the model "
                      "it was saved for had finished (try a smaller --interrupt-after)")
                return
            wall2, said2 = run_stage(data, args.check_interval, args)
            print(f"interrupted after {wall1:.0f} s:\n  {said1 or '(said nothing)'}\n"
                  f"run again: {wall2:.0f} s\n  {said2 or '(said nothing)'}")
            resumed = fingerprints(models)
            left = sorted(p.name for p in models.glob("*.resume.pt"))
            print(f"snapshots left: {left or 'none'}")
            refs = {"the recorded seed's": recorded, "the uninterrupted run's": uninterrupted}
            for name, digest in resumed.items():
                verdicts = [f"{'same as' if ref[name] == digest else 'DIFFERS from'} {label}"
                            for label, ref in refs.items() if ref and name in ref]
                print(f"  {name}: {', '.join(verdicts) or 'nothing to compare with'}")


if __name__ == "__main__":
    main()
