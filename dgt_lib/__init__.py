"""dgt-kit: a teaching and reproduction kit of DGT-Map on MuJoCo.

The sub-packages read as the paper's pipeline; each imports only those before it:

==============  ===========================================================
``core``        geometry, profiles, vehicles, the artifact cache, executors
``world``       terrain worlds, the MuJoCo simulator, rendering, speed control
``perception``  BEV maps, patches, locomotion labels, episodes, the dataset
``learning``    DGTNet, training, checkpoints
``mapping``     directional costmaps, baselines, occupancy and τ_s, methods
``navigation``  Hybrid A*, MPPI, the drive loop and its outcome rule
``evaluation``  queries, trials and their journal, experiments, statistics, the
                ground truth and costmap accuracy
``stages``      every ``ensure_*``: the only code that touches the cache
==============  ===========================================================

and on top ``viz`` (figures, one module per notebook, and the rerun recordings),
``exercises`` (the notebooks' graded exercises) and ``app`` (the command line ``dgt``: its
report, ``dgt plan``, ``dgt costmap``, the README's figures). This module sets
``MUJOCO_GL=egl`` (headless rendering) before anything imports mujoco, and offers the few
names a notebook starts with — imported on first use, so ``import dgt_lib`` stays light::

    import dgt_lib as dgt
    profile = dgt.get_profile()                  # $DGT_PROFILE: smoke | demo | paper
    hill = dgt.get_world("hill", profile)
    maps = dgt.ensure_world_costmaps("hill", ("carla_cola",), profile)
"""

import importlib as _importlib
import os as _os

_os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"

_API = {
    # profiles, vehicles, worlds
    "Profile": "dgt_lib.core.config", "get_profile": "dgt_lib.core.config",
    "VEHICLES": "dgt_lib.core.config", "get_vehicle": "dgt_lib.core.vehicles",
    "WORLD_NAMES": "dgt_lib.world.terrain", "get_world": "dgt_lib.world.terrain",
    "from_heightmap": "dgt_lib.world.worlds",
    # the stages: every artifact through the cache
    "collect_episodes": "dgt_lib.stages.collect", "ensure_bev": "dgt_lib.stages.collect",
    "ensure_dataset": "dgt_lib.stages.dataset", "ensure_model": "dgt_lib.stages.train",
    "load_model": "dgt_lib.stages.costmaps",
    "ensure_world_costmaps": "dgt_lib.stages.costmaps",
    "ensure_experiment": "dgt_lib.stages.experiments", "data_dir": "dgt_lib.stages.paths",
    "ensure_ground_truth": "dgt_lib.stages.ground_truth",
    "ensure_costmap_accuracy": "dgt_lib.stages.ground_truth",
    # one query on any terrain
    "plan_query": "dgt_lib.app.plan_one",
    # where the work runs (docs/scale-out.md): executors and devices
    "ExecutionConfig": "dgt_lib.core.config", "make_executor": "dgt_lib.core.executors",
    "use_executor": "dgt_lib.core.executors",
}
__all__ = sorted(_API)


def __getattr__(name: str):
    """Import a public name from its module on first use (PEP 562)."""
    if name in _API:
        value = getattr(_importlib.import_module(_API[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'dgt_lib' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
