"""``dgt log``: drive logs in (docs/usage.md → Your robot's drive log).

    dgt log topics BAG                         the log's topics, types, rates, duration
    dgt log record --world W --vehicle V --out drive.mcap [--seed S] [--duration S]
                   [--compressed] [--pose-source odom|tf]
    dgt log ingest BAG --vehicle ROBOT.toml [--rgb T] [--depth T] [--camera-info T]
                   [--odom T | --pose-source tf] [--cmd T] [--world-frame F] [--base-frame F]
    dgt log costmap BAG --vehicle ROBOT.toml --out FILE [--format geotiff|nav2]
                   [--head few-shot|zero-shot] [the topic options of ingest]
    dgt log plan BAG --vehicle ROBOT.toml --world W --start X,Y,YAW --goal X,Y [--drive]
                   [--head few-shot|zero-shot] [the topic options of ingest]

A log the kit cannot use ends with one line naming the problem (and the topics the log
has) and exit status 2; nothing half-written stays in the data directory.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import fields, replace
from typing import Any

from dgt_lib.app.cli_args import floats
from dgt_lib.core.config import Profile
from dgt_lib.core.vehicle_range import resolve_vehicle
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.logs.streams import LogTopics


def add_log(sub, profile_options) -> None:
    """The ``log`` command and its sub-commands; ``profile_options(parser)`` adds the
    kit's ``--profile``/``--set`` options (the collection settings a log is read with)."""
    log = sub.add_parser("log", help="a robot's drive log (ROS bag) in: map, labels, costmap",
                         description="A robot's drive log (a ROS 1 or 2 bag: MCAP, sqlite3) "
                                     "in: its topics, BEV map and labelled patches, the "
                                     "robot's head, costmap and plans; or the simulator's "
                                     "drive written as one. A bad log: one line, exit 2.")
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
    _log_options(ing, profile_options)
    ing.set_defaults(func=_ingest)
    cm = verbs.add_parser("costmap", help="the robot's directional costmap of the log's map",
                          description="Ingest the log (cached), map it for the robot with a "
                                      "head fitted to the log's training runs on the shared "
                                      "backbone (few-shot) or the vehicle-conditioned "
                                      "network's answer for its spec (zero-shot), print "
                                      "both heads' error on the held-out runs, and write "
                                      "the costmap (GeoTIFF or Nav2, the log's world frame).")
    _log_options(cm, profile_options)
    cm.add_argument("--out", required=True, help="FILE.tif, or a Nav2 stem or directory")
    cm.add_argument("--format", dest="fmt", choices=("geotiff", "nav2"), default="geotiff")
    cm.add_argument("--head", choices=("few-shot", "zero-shot"), default="few-shot")
    cm.set_defaults(func=_costmap)
    pl = verbs.add_parser("plan", help="plan with the robot's head on a world or your terrain",
                          description="Ingest the log (cached), give the robot a head as "
                                      "`dgt log costmap` does, map --world with it and plan "
                                      "one query with Hybrid A* (optionally drive it). Exit "
                                      "status 0: a path; 1: none; 2: a bad log or query.")
    _log_options(pl, profile_options)
    pl.add_argument("--world", required=True, help="a kit world's name or a heightmap file")
    pl.add_argument("--start", required=True, type=lambda t: floats(t, 3, "--start"),
                    metavar="X,Y,YAW")
    pl.add_argument("--goal", required=True, type=lambda t: floats(t, 2, "--goal"),
                    metavar="X,Y")
    pl.add_argument("--head", choices=("few-shot", "zero-shot"), default="few-shot")
    pl.add_argument("--drive", action="store_true", help="drive the path in MuJoCo")
    pl.set_defaults(func=_plan)


def _log_options(parser: argparse.ArgumentParser, profile_options) -> None:
    """A log to read: the bag, the robot's vehicle file, the topics, the profile."""
    parser.add_argument("bag")
    parser.add_argument("--vehicle", required=True, help="the robot's vehicle file (TOML)")
    for f in fields(LogTopics):
        parser.add_argument(f"--{f.name.replace('_', '-')}", default=f.default,
                            help=f"default {f.default}")
    parser.add_argument("--pose-source", choices=("odom", "tf"), default="odom")
    profile_options(parser)


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
    from dgt_lib.logs.ingest import ingest, summary_text

    summary = ingest(args.bag, resolve_vehicle(args.vehicle), _topics_of(args),
                     args.profile_value.collect)
    print(summary_text(summary))
    return 0


def _costmap(args: argparse.Namespace) -> int:
    from dgt_lib.app.costmap_export import output_target
    from dgt_lib.logs.heads import robot_costmap
    from dgt_lib.mapping.export import write_geotiff, write_nav2
    from dgt_lib.world.dem import import_rasterio

    spec = resolve_vehicle(args.vehicle)
    target = output_target(args.out, args.fmt, f"{spec.name}_{args.head}", inputs=(args.bag,))
    if args.fmt == "geotiff":
        import_rasterio()  # missing: one line now, not after the map is built
    try:
        summary, head = _head(args, spec, args.profile_value)
        bev, cost, occupancy = robot_costmap(summary, head, args.profile_value)
    except ValueError as exc:  # e.g. a log with no training patches
        print(f"dgt log costmap: error: {exc}", file=sys.stderr)
        return 2
    write = write_geotiff if args.fmt == "geotiff" else write_nav2
    written = write(target, cost, occupancy, bev.grid)
    for path in written if isinstance(written, list) else [written]:
        print(path)
    return 0


def _head(args: argparse.Namespace, spec: VehicleSpec, prof: Profile) -> tuple[dict, Any]:
    """The log ingested, the robot's head on ``prof``'s networks, both heads' held-out
    errors printed."""
    from dgt_lib.logs.heads import log_heads
    from dgt_lib.logs.ingest import ingest, summary_text

    summary = ingest(args.bag, spec, _topics_of(args), args.profile_value.collect)
    print(summary_text(summary))
    head, errors = log_heads(summary, spec, prof, args.head)
    for name, e in errors.items():
        print(f"held-out runs, {name:>9}: MAE {e['mae']:.3f} over {e['n']} patches")
    if not errors:
        print("no held-out run: the heads' errors need a log of several runs")
    return summary, head


def _plan(args: argparse.Namespace) -> int:
    from dgt_lib.app.plan_one import costmap_profile, load_world
    from dgt_lib.app.query import CostmapSource, plan_on_world
    from dgt_lib.logs.heads import world_maps
    from dgt_lib.navigation.planner import InvalidQueryError

    spec = resolve_vehicle(args.vehicle)
    try:  # a terrain file without imagery: the heads of the geometry-only networks
        prof, inputs = costmap_profile(args.world, "dgt", args.profile_value, None)
        world, _ = load_world(args.world, prof)  # a bad world: an error before any work
        _, head = _head(args, spec, prof)
        source = CostmapSource(lambda w: world_maps(w, head, prof),
                               None, f"{args.head} head from the log {args.bag}")
        report = plan_on_world(world, spec, args.start, args.goal, profile=prof,
                               drive=args.drive, source=source, inputs=inputs)
    except (InvalidQueryError, FileNotFoundError, ValueError) as exc:
        print(f"dgt log plan: error: {exc}", file=sys.stderr)
        return 2
    print(report.summary())
    return 0 if report.plan.success else 1
