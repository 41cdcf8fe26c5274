"""``dgt log``: drive logs in (docs/usage.md → Your robot's drive log).

    dgt log topics BAG                         the log's topics, types, rates, duration
    dgt log record --world W --vehicle V --out drive.mcap [--seed S] [--duration S]
                   [--compressed] [--pose-source odom|tf]
    dgt log ingest BAG --vehicle ROBOT.toml [--rgb T] [--depth T] [--camera-info T]
                   [--odom T | --pose-source tf] [--cmd T] [--world-frame F] [--base-frame F]

A log the kit cannot use ends with one line naming the problem (and the topics the log
has) and exit status 2; nothing half-written stays in the data directory.
"""

from __future__ import annotations

import argparse
from dataclasses import fields, replace

from dgt_lib.logs.streams import LogTopics


def add_log(sub, profile_options) -> None:
    """The ``log`` command and its three sub-commands; ``profile_options(parser)`` adds the
    kit's ``--profile``/``--set`` options (the collection settings a log is read with)."""
    log = sub.add_parser("log", help="drive logs (ROS bags) in: topics, record, ingest",
                         description="A robot's drive log (a ROS 1 or ROS 2 bag: MCAP, "
                                     "sqlite3) in: its topics, the BEV map and labelled "
                                     "patches of its drive; or the simulator's drive written "
                                     "as one. A log that cannot be used: one line, exit 2.")
    verbs = log.add_subparsers(dest="verb", required=True)
    top = verbs.add_parser("topics", help="list a log's topics, types and rates")
    top.add_argument("bag")
    top.set_defaults(func=_topics)
    rec = verbs.add_parser("record", help="drive the simulator and write a ROS 2 bag")
    rec.add_argument("--world", default="training")
    rec.add_argument("--vehicle", required=True, help="a named vehicle or a vehicle file")
    rec.add_argument("--out", required=True, help="FILE.mcap, FILE.db3 or a bag directory")
    rec.add_argument("--seed", type=int, default=0)
    rec.add_argument("--duration", type=float, default=None, metavar="S",
                     help="seconds of driving (default: the profile's episode duration)")
    rec.add_argument("--runs", type=_at_least_one, default=1, metavar="N",
                     help="drives in the log, the robot standing 3 s between them (default 1)")
    rec.add_argument("--compressed", action="store_true", help="colour as JPEG")
    rec.add_argument("--pose-source", choices=("odom", "tf"), default="odom")
    profile_options(rec)
    rec.set_defaults(func=_record)
    ing = verbs.add_parser("ingest", help="a log to a BEV map and labelled patches")
    ing.add_argument("bag")
    ing.add_argument("--vehicle", required=True, help="the robot's vehicle file (TOML)")
    for f in fields(LogTopics):
        ing.add_argument(f"--{f.name.replace('_', '-')}", default=f.default,
                         help=f"default {f.default}")
    ing.add_argument("--pose-source", choices=("odom", "tf"), default="odom")
    profile_options(ing)
    ing.set_defaults(func=_ingest)


def _at_least_one(text: str) -> int:
    """``--runs``: a whole number ≥ 1."""
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number ≥ 1, got {text!r}")
    return int(text)


def _topics(args: argparse.Namespace) -> int:
    from dgt_lib.logs.bag import log_topics, open_log

    with open_log(args.bag) as reader:
        rows = log_topics(reader)
        print(f"{args.bag}: {reader.duration * 1e-9:.1f} s, {reader.message_count:,} messages")
    width = max(len(r.name) for r in rows)
    for r in rows:
        print(f"  {r.name:<{width}}  {r.msgtype:<32} {r.count:>7,}  {r.rate_hz:6.1f} Hz")
    return 0


def _topics_of(args: argparse.Namespace) -> LogTopics:
    given = {f.name: getattr(args, f.name, f.default) for f in fields(LogTopics)}
    return replace(LogTopics(**given), odom="" if args.pose_source == "tf" else given["odom"])


def _record(args: argparse.Namespace) -> int:
    from dgt_lib.core.outputs import check_output_path
    from dgt_lib.core.vehicle_range import resolve_vehicle
    from dgt_lib.logs.record import record_log
    from dgt_lib.world.terrain import get_world

    prof = args.profile_value
    cfg = prof.collect if args.duration is None else replace(
        prof.collect, episode_duration_s=args.duration)
    out = check_output_path(args.out) if args.out.endswith((".mcap", ".db3")) else args.out
    path, episodes = record_log(get_world(args.world, prof), resolve_vehicle(args.vehicle),
                                out, seed=args.seed, config=cfg, topics=_topics_of(args),
                                compressed=args.compressed, runs=args.runs)
    print(f"wrote {path}: {len(episodes)} run(s) of {episodes[0].vehicle} on {args.world}, "
          + ", ".join(f"{e.duration_s:.1f} s (ended: {e.end_reason})" for e in episodes))
    return 0


def _ingest(args: argparse.Namespace) -> int:
    from dgt_lib.core.vehicle_range import resolve_vehicle
    from dgt_lib.logs.ingest import ingest, summary_text

    summary = ingest(args.bag, resolve_vehicle(args.vehicle), _topics_of(args),
                     args.profile_value.collect)
    print(summary_text(summary))
    return 0
