"""``python -m dgt_lib.records``: publish a run's records, render the docs from them.

    python -m dgt_lib.records publish --profile demo --seeds 8   # → docs/runs/<run>/
    python -m dgt_lib.records render    # make docs: every generated block
    python -m dgt_lib.records check     # exit 1 when a block is stale
"""

from __future__ import annotations

import argparse
import sys

from dgt_lib.core.config import get_profile
from dgt_lib.records.documents import CITED, stale, write_all
from dgt_lib.records.provenance import ROOT
from dgt_lib.records.publish import publish


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m dgt_lib.records", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True)
    pub = sub.add_parser("publish", help="copy a profile's seed records into docs/runs/")
    pub.add_argument("--profile", required=True)
    pub.add_argument("--seeds", type=int, default=None,
                     help="how many seeds the run had (default: the profile's)")
    sub.add_parser("render", help="rewrite every generated block from the records")
    sub.add_parser("check", help="exit 1 when a generated block differs from its records")
    args = ap.parse_args(argv)
    try:
        if args.command == "publish":
            prof = get_profile(args.profile)
            folder = publish(prof if args.seeds is None else prof.with_(seeds=args.seeds))
            print(f"published {folder.relative_to(ROOT)}; to cite it, name it in {CITED} "
                  "and run `make docs`")
        elif args.command == "render":
            for path in write_all():
                print(f"rendered {path.relative_to(ROOT)}")
        else:
            paths = stale()
            for path in paths:
                print(f"stale: {path.relative_to(ROOT)} (run `make docs`)", file=sys.stderr)
            return 1 if paths else 0
    except (FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
