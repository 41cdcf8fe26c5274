"""Command line: ``dgt`` (or ``python -m dgt_lib``).

    dgt reproduce [--profile P] [--stages a b …] [--seeds N | --seed S]
                  [--set NAME=VALUE …] [--executor process|dask] [--address A]
                  [--workers N] [--device auto|cpu|cuda]   run the cached pipeline stages
    dgt stages                                     list the stages
    dgt settings [--profile P] [--set NAME=VALUE …]  every NAME --set takes, its type and value
    dgt plan --world W --vehicle V|FILE.toml --start x,y,yaw --goal x,y [--method M] [--drive]
             [--json] [--set NAME=VALUE …]         plan (and drive) one query
    dgt costmap …, dgt log topics|record|ingest …  costmaps out, drive logs in (--help)

``--set planner.beta=50`` changes one setting of the profile (repeatable; names and types
as in ``dgt_lib/core/config.py``, checked before anything runs; ``dgt settings`` lists them).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import json
import os
import shlex
import sys
import time
from dataclasses import replace

from dgt_lib import __version__
from dgt_lib.app.cli_args import (
    band_arg,
    floats,
    glue_negative_coordinates,
    resolution_arg,
    vehicle_or_file,
)
from dgt_lib.app.log_cli import add_log
from dgt_lib.core import faults
from dgt_lib.core.artifacts import data_root
from dgt_lib.core.config import (
    DEVICES,
    EXECUTORS,
    PROFILE_NAMES,
    VEHICLES,
    Profile,
    UnknownProfileError,
    get_profile,
    profile_name,
)
from dgt_lib.core.faults import Terminated, interrupted_status, sigterm_as_interrupt
from dgt_lib.core.outputs import OutputPathError
from dgt_lib.core.overrides import (
    InvalidOverrideError,
    parse_overrides,
    settings_table,
)
from dgt_lib.core.vehicle_rules import InvalidVehicleError
from dgt_lib.core.vehicles import UnknownVehicleError
from dgt_lib.logs.bag import BadLogError
from dgt_lib.mapping.methods import METHODS
from dgt_lib.stages import registry
from dgt_lib.stages.paths import profile_root
from dgt_lib.world.opengl import check_mujoco_gl

EXIT_INTERRUPTED = 130
"""Exit status after Ctrl-C (128 + SIGINT, as a shell reports it)."""


PIPELINE_BAR_FORMAT = "{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} stages [{elapsed}]"
"""The pipeline bar counts stages and shows the time spent, with no ETA and no rate: the
stages differ in cost by 100× (the dataset takes a second, collection minutes), so an
average over the stages done so far promised "3 s left" after collection."""


def _stopped_message(args: argparse.Namespace, how: str, why: str = "") -> str:
    """What ``dgt`` prints when Ctrl-C (``how`` "interrupted"), SIGTERM ("terminated") or a
    fault ("error", ``why``) stops a command: where — the seed and stage ``dgt reproduce``
    was in (``args.stage``) —, what it kept, and that the same command resumes."""
    seed, stage = getattr(args, "stage", (None, None))
    where = "" if stage is None else f" in seed {seed} · {stage.name}"
    kept = (getattr(args, "kept", None) or "everything finished so far" if stage is None
            else f"the earlier stages' outputs; {stage.kept}")
    said = f": {why}\n" if why else ". "  # a fault's reason on a line of its own
    return f"dgt: {how}{where}{said}Kept: {kept}. Rerun `{args.command_line}` to resume."


def _profile(args: argparse.Namespace) -> Profile:
    """The profile of ``--profile`` with the settings of every ``--set NAME=VALUE``."""
    return get_profile(args.profile).with_overrides(parse_overrides(args.set or []))


class UsageError(ValueError):
    """A command-line value that cannot work here (exit status 2, one line)."""


def _with_execution(profile: Profile, args: argparse.Namespace) -> Profile:
    """``profile`` with ``--executor``, ``--address``, ``--workers`` and ``--device``
    applied (:class:`~dgt_lib.core.config.ExecutionConfig`); raises :class:`UsageError`
    for a combination that cannot run here, before any work starts."""
    ex = profile.execution
    executor = getattr(args, "executor", None) or ex.executor
    address = getattr(args, "address", None)
    if address is None and executor == ex.executor:
        address = ex.address
    try:
        execution = replace(ex, executor=executor, address=address,
                            device=getattr(args, "device", None) or ex.device)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if execution.executor == "dask" and importlib.util.find_spec("distributed") is None:
        raise UsageError("--executor dask needs the 'distributed' package: "
                         "pip install 'dgt-kit[dask]'")
    if execution.device == "cuda":
        from dgt_lib.learning.training import resolve_device

        try:
            resolve_device("cuda")
        except ValueError as exc:
            raise UsageError(f"--device cuda: {exc}") from None
    workers = getattr(args, "workers", None)
    if workers is not None and workers < 1:
        raise UsageError(f"--workers must be ≥ 1, got {workers}")
    return profile.with_(execution=execution,
                         workers=workers if workers is not None else profile.workers)


def _executor_text(profile: Profile) -> str:
    """How the jobs run, for the first line of ``dgt reproduce``."""
    ex = profile.execution
    if ex.executor == "process":
        return f"{profile.workers} worker processes"
    where = ex.address or f"a local cluster of {profile.workers} workers"
    return f"{ex.executor} on {where}"


def _reproduce(args: argparse.Namespace) -> int:
    from dgt_lib.core.executors import use_executor

    profile = _with_execution(_with_seeds(_profile(args), args), args)
    stages = registry.select(args.stages)
    runs = profile.seed_profiles()
    print(f"dgt reproduce — profile {profile.describe()}, seed(s) "
          f"{', '.join(str(p.seed) for p in runs)}, outputs under {profile_root(profile)}; "
          f"jobs: {_executor_text(profile)}, device {profile.execution.device}")
    if not stages:
        print("The pipeline has no stages yet: nothing to run.")
        return 0
    from tqdm.auto import tqdm

    from dgt_lib.stages.timings import (
        machine_load,
        new_run_id,
        record_stage_time,
        stage_times_path,
    )

    rows = []
    invocation = new_run_id()
    jobs = [(run, stage) for run in runs for stage in stages]
    ex = profile.execution
    # one executor for the whole run (one local cluster, started once, stopped after)
    with use_executor(ex.executor, address=ex.address, workers=profile.workers), \
            tqdm(jobs, desc="pipeline", bar_format=PIPELINE_BAR_FORMAT) as bar:
        for run, stage in bar:
            args.stage = (run.seed, stage)  # where Ctrl-C or a fault stops it (main)
            tqdm.write(f"── seed {run.seed} · {stage.name}: {stage.description}")
            started, load, t0 = time.time(), machine_load(), time.perf_counter()
            result = stage.run(run)
            if stage.report:  # figures, tables and recordings: the top level's
                from dgt_lib.app import report

                with faults.report_writes(f"the {stage.name} report"):
                    result = report.report_stage(stage.name, run, result)
            seconds = time.perf_counter() - t0
            record_stage_time(run, stage.name, seconds, run=invocation,
                              started_unix_s=started, load_before=load)
            rows.append((run.seed, stage.name, seconds, result))
            if stage.report and run is not runs[-1]:  # a seed's results before the next's
                later = [r.seed for r in runs[runs.index(run) + 1:]]
                tqdm.write(report.seed_results(run.seed, result, later))
    args.stage = (None, None)
    print("\nSummary")
    for seed, name, seconds, result in rows:
        print(f"  seed {seed} {name:<12} {seconds:8.1f} s  {result.summary}")
        for p in result.paths:
            print(f"  {'':<19} → {p}")
    print(f"Stage wall times (with the load when each started): {stage_times_path(profile)}")
    if "experiments" in [s.name for s in stages]:
        if args.seed is not None:  # one seed alone: the pooled report keeps every seed's
            print(f"\nSeed {args.seed} alone: the pooled results were left as they were; "
                  f"`dgt reproduce --profile {profile.name}` pools every seed.")
            return 0
        from dgt_lib.app.report import write_seeds_report

        print(f"\nResults over {len(runs)} seed(s): {write_seeds_report(profile)}")
    return 0


def _with_seeds(profile: Profile, args: argparse.Namespace) -> Profile:
    """``profile`` with ``--seeds N`` (N seeds, from the profile's first) or
    ``--seed S`` (seed S alone) applied; :class:`UsageError` for a count below 1 or a
    negative seed."""
    if args.seeds is not None:
        if args.seeds < 1:
            raise UsageError(f"--seeds must be ≥ 1, got {args.seeds}")
        return profile.with_(seeds=args.seeds)
    if args.seed is not None:
        if args.seed < 0:
            raise UsageError(f"--seed must be ≥ 0, got {args.seed}")
        return profile.with_(seed=args.seed, seeds=1)
    return profile


def _stages(_: argparse.Namespace) -> int:
    if not registry.STAGES:
        print("(no stages yet)")
    for s in registry.STAGES:
        print(f"{s.name:<14} {s.description}")
    return 0


def _settings(args: argparse.Namespace) -> int:
    profile = _profile(args)
    from dgt_lib.core.constraints import SETTING_RULES

    # every name --set accepts, its type, the profile's value, and what it may be
    rows = [(*row, SETTING_RULES[row[0]].allowed if row[0] in SETTING_RULES else "")
            for row in settings_table(profile)]
    print(f"Settings of profile {profile.describe()} (change one with --set NAME=VALUE):")
    widths = [max(len(r[i]) for r in rows) for i in range(3)]
    for name, kind, value, allowed in rows:
        print(f"  {name:<{widths[0]}}  {kind:<{widths[1]}}  {value:<{widths[2]}}  {allowed}"
              .rstrip())
    return 0


def _profile_arg(text: str) -> str:
    """``--profile``: the rule of ``$DGT_PROFILE`` (:func:`profile_name`, case-insensitive)."""
    try:
        return profile_name(text)
    except UnknownProfileError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


PROFILE_METAVAR = "{" + ",".join(PROFILE_NAMES) + "}"
PROFILE_HELP = "profile (default: $DGT_PROFILE or demo; case-insensitive)"
SET_HELP = ("change one setting of the profile, e.g. planner.beta=50 or "
            "experiments.n_hill=10 (repeatable; SECTION.FIELD of dgt_lib/core/config.py; "
            "dgt settings lists them)")


def _add_profile_options(parser: argparse.ArgumentParser) -> None:
    """``--profile`` and ``--set NAME=VALUE`` (repeatable: :meth:`Profile.with_overrides` on
    the command line); the command reads ``args.profile_value``."""
    parser.add_argument("--profile", type=_profile_arg, default=None, metavar=PROFILE_METAVAR,
                        help=PROFILE_HELP)
    parser.add_argument("--set", action="append", metavar="NAME=VALUE", help=SET_HELP)


@contextlib.contextmanager
def _stdout_to_stderr():
    """Everything written to stdout inside goes to stderr: Python's prints and, at the file
    descriptor, what worker processes and compiled code write (``dgt plan --json`` keeps
    stdout for the JSON alone)."""
    sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:
        saved = None
    try:
        if saved is not None:
            os.dup2(2, 1)
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        sys.stderr.flush()
        if saved is not None:
            os.dup2(saved, 1)
            os.close(saved)


def _plan(args: argparse.Namespace) -> int:
    """``dgt plan``: :func:`dgt_lib.app.plan_one.plan_query` checks the query before any data is
    collected or model trained (:func:`dgt_lib.app.query.check_query`), then says when
    training comes first. ``--json``: the report as one JSON object, alone on stdout."""
    from dgt_lib.app.never_driven import plan_vehicle_query
    from dgt_lib.navigation.planner import InvalidQueryError

    profile = _with_execution(_profile(args), args)
    quiet = _stdout_to_stderr() if args.json else contextlib.nullcontext()
    try:
        with quiet:
            report = plan_vehicle_query(args.world, args.vehicle, args.start, args.goal,
                                method=args.method, profile=profile, drive=args.drive,
                                resolution_m=args.resolution,
                                vertical_scale_m=args.vertical_scale,
                                crs_coords=args.crs_coords, nodata=args.nodata,
                                band=args.band, image=args.image)
    except (InvalidQueryError, FileNotFoundError, ValueError) as exc:
        print(f"dgt plan: error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(report.as_dict()) if args.json else report.summary())
    return PLAN_EXIT[report.plan.failure]


def _device_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--device", choices=DEVICES, default=None,
                        help="where training and costmap inference run: auto (a CUDA GPU "
                             "when there is one, the default), cpu or cuda")


DESCRIPTION = ("dgt-kit: the DGT-Map pipeline (collection, BEV maps, training, directional "
               "costmaps, planning, the experiments) and one-query planning")
"""What ``dgt --help`` opens with (plain text: argparse prints it as it is)."""


def _add_reproduce(sub) -> None:
    rep = sub.add_parser("reproduce", help="run the pipeline stages (cached) for a profile",
                         description="Run the pipeline's stages for every seed of a profile; "
                                     "finished stages are cached, so a rerun resumes.")
    _add_profile_options(rep)
    rep.add_argument("--stages", nargs="+", metavar="STAGE",
                     help="only these stages (see: dgt stages)")
    seeds = rep.add_mutually_exclusive_group()
    seeds.add_argument("--seeds", type=int, default=None, metavar="N",
                       help="run every stage for N seeds (default: the profile's; demo 3) and "
                            "report each seed and the pooled results")
    seeds.add_argument("--seed", type=int, default=None, metavar="S",
                       help="run every stage for seed S alone (its own directory seed-S; the "
                            "pooled results are left as they are)")
    rep.add_argument("--executor", choices=EXECUTORS, default=None,
                     help="what runs collection episodes and trials: a process pool on this "
                          "machine (default) or a Dask cluster (pip install 'dgt-kit[dask]'); "
                          "results do not depend on it")
    rep.add_argument("--address", default=None, metavar="ADDRESS",
                     help="an existing Dask cluster's scheduler (tcp://host:8786); default: "
                          "start a local cluster of --workers workers for the run")
    rep.add_argument("--workers", type=int, default=None, metavar="N",
                     help="worker processes, or local cluster workers (default: the "
                          "profile's, 2)")
    _device_arg(rep)
    rep.set_defaults(func=_reproduce)


WORLD_HELP = ("hill, ridge, eval, training, a .npy / 16-bit .png heightmap, or a DEM: GeoTIFF "
              "(.tif) or ESRI ASCII grid (.asc; pip install 'dgt-kit[geo]')")


def _add_world_options(parser: argparse.ArgumentParser, vehicle_file: bool = False) -> None:
    """``dgt plan``'s and ``dgt costmap``'s: world, vehicle (``vehicle_file``: or a TOML
    file of a vehicle never driven, ``dgt plan``), method, profile, device."""
    parser.add_argument("--world", required=True, help=WORLD_HELP)
    parser.add_argument("--vehicle", required=True, choices=None if vehicle_file else VEHICLES,
                        type=vehicle_or_file if vehicle_file else str,
                        metavar=f"{{{','.join(VEHICLES)}}} or FILE.toml" if vehicle_file else None,
                        help="whose costmap (and footprint, turning radius)" + (
                            "; a file: a vehicle never driven, on the vehicle-conditioned "
                            "network's costmap (docs/vehicles.md)" if vehicle_file else ""))
    parser.add_argument("--method", default="dgt", choices=METHODS)
    _add_profile_options(parser)
    parser.add_argument("--resolution", type=resolution_arg, default=0.4,
                        help="heightmap file: metres per pixel (default 0.4); a DEM is "
                             "resampled to the profile's worlds.hfield_resolution_m")
    parser.add_argument("--vertical-scale", type=float, default=None,
                        help="PNG heightmap: metres at the brightest pixel")
    parser.add_argument("--nodata", choices=("error", "crop"), default="error",
                        help="DEM no-data cells: an error, or keep the largest valid rectangle")
    parser.add_argument("--band", type=band_arg, default=None, metavar="N",
                        help="DEM: the band that holds the heights (default 1; a file of "
                             "several bands says which it read)")
    parser.add_argument("--image", default=None, metavar="ORTHO.tif",
                        help="DEM: an 8-bit RGB GeoTIFF covering it, resampled to its grid "
                             "as the map's colour for the RGB-D model; without it a DEM is "
                             "mapped from its geometry alone")
    _device_arg(parser)


def _add_costmap(sub) -> None:
    cm = sub.add_parser("costmap", help="write a world's directional costmap (GeoTIFF, Nav2)",
                        description="Write a costmap's K heading layers and the occupancy as "
                                    "a GeoTIFF (band k+1 = heading θ_k, last band occupancy) "
                                    "or map_server PGM + YAML files (--format nav2).")
    _add_world_options(cm)
    cm.add_argument("--out", required=True, metavar="FILE",
                    help="the GeoTIFF; nav2: FILE_heading<k>/FILE_occupancy .pgm + .yaml, "
                         "or inside FILE when it is a directory (or ends in /)")
    cm.add_argument("--format", dest="fmt", choices=("geotiff", "nav2"), default="geotiff")
    cm.set_defaults(func=_costmap)


def _costmap(args: argparse.Namespace) -> int:
    from dgt_lib.app.costmap_export import run_command

    return run_command(args, _with_execution(_profile(args), args))


PLAN_STATUS = ("Exit status 0: a path was found; 1: no path exists (every pose the search "
               "can reach was expanded); 2: an invalid query; 3: the search budget ran out "
               "before a path was found, none ruled out (raise planner.max_expansions or "
               "planner.max_time_s with --set, as the report says).")
"""``dgt plan --help``'s exit statuses (docs/usage.md lists them too)."""

PLAN_EXIT = {"": 0, "no_path": 1, "budget": 3}
"""``dgt plan``'s exit status by :attr:`~dgt_lib.navigation.planner.PlanResult.failure` (2 is an
invalid query)."""


def _add_plan(sub) -> None:
    pl = sub.add_parser("plan", help="plan (and drive) one query on a world or your terrain",
                        description="Plan one query with Hybrid A* on a method's directional "
                                    "costmap (building what it needs first), save a figure and "
                                    "a rerun recording, and optionally drive the path in "
                                    "MuJoCo. " + PLAN_STATUS)
    _add_world_options(pl, vehicle_file=True)
    pl.add_argument("--start", required=True, type=lambda t: floats(t, 3, "--start"),
                    help="x,y,yaw [m, m, rad]; negative values are fine (-5,14,0.8)")
    pl.add_argument("--goal", required=True, type=lambda t: floats(t, 2, "--goal"),
                    help="x,y [m]")
    pl.add_argument("--crs-coords", action="store_true",
                    help="DEM: --start/--goal x,y in the file's CRS (e.g. lon,lat in "
                         "degrees), not metres from the map's south-west corner")
    pl.add_argument("--drive", action="store_true", help="drive the path in MuJoCo")
    pl.add_argument("--json", action="store_true",
                    help="print only the report as one JSON object on stdout (the path's rows "
                         "x, y, yaw; length; cost; the named route; the drive's outcome; when "
                         "no path was found, failure: no_path or budget, and the reason); "
                         "progress goes to stderr")
    pl.set_defaults(func=_plan)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dgt", description=DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"dgt {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    _add_reproduce(sub)
    st = sub.add_parser("stages", help="list the pipeline stages",
                        description="List the pipeline's stages in the order they run.")
    st.set_defaults(func=_stages)
    se = sub.add_parser("settings", help="list every setting --set takes, its type and value",
                        description="List every NAME that --set NAME=VALUE accepts, its type "
                                    "and the profile's value (with the --set given applied).")
    _add_profile_options(se)
    se.set_defaults(func=_settings)
    _add_plan(sub)
    _add_costmap(sub)
    add_log(sub, _add_profile_options)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line ``argv`` (default ``sys.argv[1:]``); returns the exit status.

    Ctrl-C ends any command with one line on stderr and status 130 (no traceback), and
    SIGTERM the same way with status 143: what the artifact cache holds stays, and the
    same command resumes from it. A fault from outside (a data directory or renderer that
    cannot work, a full disk, a cluster that gave up: :func:`dgt_lib.core.faults.explain`)
    is one line and status 1. A reader that stops early (``dgt settings | head``) ends it
    quietly.
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser().parse_args(glue_negative_coordinates(argv))
    args.command_line = shlex.join(["dgt", *argv])
    try:
        with sigterm_as_interrupt():  # SIGTERM stops a command as Ctrl-C does
            if args.command in ("reproduce", "plan", "costmap", "log"):  # renderer, data
                check_mujoco_gl()
                faults.prepare_data_dir(data_root())
            if args.command == "log" and args.verb != "topics":
                args.profile_value = _profile(args)
            return args.func(args)
    except (UnknownProfileError, InvalidOverrideError, registry.UnknownStageError,
            UsageError, BadLogError, UnknownVehicleError, InvalidVehicleError,
            OutputPathError) as exc:
        print(f"dgt: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (faults.Terminated)
        how = "terminated" if isinstance(exc, Terminated) else "interrupted"
        print(_stopped_message(args, how), file=sys.stderr)
        return interrupted_status(exc)
    except BrokenPipeError:  # stdout's reader is gone: say nothing more to it
        os.dup2(os.open(os.devnull, os.O_WRONLY), 1)
        return 1
    except Exception as exc:  # no renderer or data directory, a full disk, a cluster gave up
        why = faults.explain(exc)
        if why is None:
            raise
        print(f"dgt: error: {why}" if isinstance(exc, faults.SetupError)
              else _stopped_message(args, "error", why), file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
