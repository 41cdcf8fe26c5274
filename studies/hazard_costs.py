"""Does a learned costmap price the hazards of ``eval_hazard``? Its cost on the cells the
ditches add (cells a vehicle cannot cross there, by the query rule's test, that ``eval`` does
not have) beside its cost on the cells the vehicle can cross, per run seed.

    .venv/bin/python studies/hazard_costs.py --profile demo --seeds 3

Reads (or builds) the ``eval_hazard`` costmaps of the profile's models; the cost of a cell is
its maximum over the heading layers. ``--publish`` writes the record docs/controller.md
quotes.
"""

from __future__ import annotations

from runner import Study

from dgt_lib.core.config import get_profile
from dgt_lib.evaluation.hazards import vehicle_hazards
from dgt_lib.mapping.methods import METHOD_LABELS
from dgt_lib.records.study import table
from dgt_lib.stages.experiments import trial_maps
from dgt_lib.world.terrain import get_world


def main() -> None:
    study = Study("hazard_costs", __doc__, profile="demo", seeds=3)
    ap = study.parser
    ap.add_argument("--vehicle", action="append", default=None,
                    help="Experiment 3's vehicles (default: jeep and vw_van)")
    ap.add_argument("--method", action="append", default=None,
                    help="default: dgt and single-task")
    args = study.parse()
    rows = []
    for seed in study.seeds:
        prof = get_profile(args.profile).with_(seed=seed)
        hazard_world, eval_world = get_world("eval_hazard", prof), get_world("eval", prof)
        for vehicle in args.vehicle or ["jeep", "vw_van"]:
            hazard = vehicle_hazards(hazard_world, vehicle)
            ditches = hazard & ~vehicle_hazards(eval_world, vehicle)
            for method in args.method or ["dgt", "single-task"]:
                cost = trial_maps("eval_hazard", method, vehicle, prof).costmap(
                    method, vehicle).max(axis=0)
                rows.append([str(seed), vehicle, METHOD_LABELS[method],
                             f"{cost[ditches].mean():.2f}", str(int(ditches.sum())),
                             f"{cost[~hazard].mean():.2f}"])
    study.finish({"costs": table(
        "Cost on the ditches' cells against the crossable cells (max over the headings)",
        ["seed", "vehicle", "method", "ditch cells", "how many", "crossable cells"], rows)})


if __name__ == "__main__":
    main()
