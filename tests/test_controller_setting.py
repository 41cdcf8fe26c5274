"""``experiments.controller``: the trials' MPPI by name. The paper's (the default) leaves every
trial and every cache key as it was; another one is a variant of its own."""

import numpy as np
import pytest

from dgt_lib.core.config import get_profile
from dgt_lib.evaluation.trials import trial_controller
from dgt_lib.navigation.control.mppi_config import MPPIConfig
from dgt_lib.navigation.control.profiles import CONTROLLERS, controller_settings
from dgt_lib.stages.experiments import experiment_config, experiment_stem

SMOKE = get_profile("smoke")


def test_the_default_controller_is_the_papers_and_stays_out_of_the_cache_key():
    assert SMOKE.experiments.controller == CONTROLLERS[0] == "paper"
    assert "controller" not in experiment_config("experiment1", SMOKE)["experiments"]
    assert trial_controller(SMOKE, np.zeros((8, 4, 4), np.float32)) == {}
    # every new MPPIConfig field is off by default: the paper's controller to the bit
    for name in ("breakaway_speed_mps", "first_step_weight", "roll_limit_fraction",
                 "terrain_weight"):
        assert getattr(MPPIConfig(), name) == 0.0


@pytest.mark.parametrize("name", ["robust", "terrain"])
def test_another_controller_is_a_variant_with_its_settings(name):
    prof = SMOKE.with_overrides({"experiments.controller": name})
    assert experiment_config("experiment1", prof)["experiments"]["controller"] == name
    assert experiment_stem("experiment1", prof) != experiment_stem("experiment1", SMOKE)
    # the key holds what the name sets: other settings under the same name are other trials
    assert experiment_config("experiment1", prof)["mppi"] == controller_settings(name)
    cost = np.random.default_rng(0).random((8, 4, 4)).astype(np.float32)
    args = trial_controller(prof, cost)
    assert args["mppi_settings"] == controller_settings(name)
    MPPIConfig(**args["mppi_settings"])  # valid settings
    # the terrain controller reads the method's own costmap (Binary's is zeros)
    assert ("costmap" in args) == (name == "terrain")
    if name == "terrain":
        assert args["costmap"] is cost and args["mppi_settings"]["terrain_weight"] > 0


def test_an_unknown_controller_is_refused():
    with pytest.raises(ValueError, match="controller"):
        SMOKE.with_overrides({"experiments.controller": "fast"})
    with pytest.raises(ValueError, match="unknown controller"):
        controller_settings("fast")


def test_the_robust_model_steps_the_period_the_trials_execute():
    # drive holds each command for MPPI_DT_S rounded to whole physics steps; the paper's
    # MPPI models 50 ms a step, the robust one the executed period (its warm start shifts by
    # exactly the time that passed)
    from dgt_lib.navigation.drive import MPPI_DT_S
    from dgt_lib.world.mujoco_model import TIMESTEP_S

    executed = round(MPPI_DT_S / TIMESTEP_S) * TIMESTEP_S
    assert MPPIConfig().model_dt == MPPI_DT_S != pytest.approx(executed)
    for name in ("robust", "terrain"):
        assert controller_settings(name)["model_dt"] == pytest.approx(executed, abs=1e-12)
