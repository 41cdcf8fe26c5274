"""Command line: ``dgt`` (or ``python -m dgt_lib``).

    dgt reproduce [--profile P] [--stages a b …]   run the cached pipeline stages
    dgt stages                                     list the stages
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from . import pipeline
from .artifacts import profile_dir
from .config import PROFILE_NAMES, UnknownProfileError, get_profile


def _reproduce(args: argparse.Namespace) -> int:
    profile = get_profile(args.profile)
    stages = pipeline.select(args.stages)
    out_dir = profile_dir(profile.name)
    print(f"dgt reproduce — profile {profile.name!r}, outputs under {out_dir}")
    if not stages:
        print("The pipeline has no stages yet: nothing to run.")
        return 0
    from tqdm.auto import tqdm

    rows = []
    for stage in tqdm(stages, desc="pipeline", unit="stage"):
        tqdm.write(f"── {stage.name}: {stage.description}")
        t0 = time.perf_counter()
        result = stage.load()(profile)
        rows.append((stage.name, time.perf_counter() - t0, result))
    print("\nSummary")
    for name, seconds, result in rows:
        print(f"  {name:<14} {seconds:8.1f} s  {result.summary}")
        for p in result.paths:
            print(f"  {'':<14} → {p}")
    return 0


def _stages(_: argparse.Namespace) -> int:
    if not pipeline.STAGES:
        print("(no stages yet)")
    for s in pipeline.STAGES:
        print(f"{s.name:<14} {s.description}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dgt", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    rep = sub.add_parser("reproduce", help="run the pipeline stages (cached) for a profile")
    rep.add_argument("--profile", choices=PROFILE_NAMES, default=None,
                     help="profile (default: $DGT_PROFILE or demo)")
    rep.add_argument("--stages", nargs="+", metavar="STAGE",
                     help="only these stages (see `dgt stages`)")
    rep.set_defaults(func=_reproduce)
    st = sub.add_parser("stages", help="list the pipeline stages")
    st.set_defaults(func=_stages)
    return parser


def main(argv: list[str] | None = None) -> int:
    os.environ.setdefault("MUJOCO_GL", "egl")
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (UnknownProfileError, pipeline.UnknownStageError) as exc:
        print(f"dgt: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
