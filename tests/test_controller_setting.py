"""The trials' MPPI is the Profile's ``mppi`` section; ``experiments.controller`` puts a named
preset in it. The paper's (the default) leaves every trial and every cache key as it was;
another preset, or any ``mppi.*`` setting, is a variant of its own."""

import dataclasses

import numpy as np
import pytest

from dgt_lib.core.config import get_profile
from dgt_lib.core.controller import CONTROLLERS, MPPIConfig, controller_settings, with_controller
from dgt_lib.core.overrides import setting_names
from dgt_lib.evaluation.trials import trial_controller
from dgt_lib.stages.experiments import experiment_config, experiment_stem

SMOKE = get_profile("smoke")


def test_the_default_controller_is_the_papers_and_stays_out_of_the_cache_key():
    from dgt_lib.core.cache_keys import jsonable

    assert SMOKE.experiments.controller == CONTROLLERS[0] == "paper"
    assert get_profile("demo").mppi == get_profile("paper").mppi == MPPIConfig()
    key = jsonable(experiment_config("experiment1", get_profile("demo")))
    assert "mppi" not in key and "controller" not in key["experiments"]
    assert trial_controller(SMOKE, np.zeros((8, 4, 4), np.float32)) == {"mppi": SMOKE.mppi}
    # every option of ours is off by default: the paper's controller to the bit
    for name in ("breakaway_speed_mps", "roll_limit_fraction", "terrain_weight",
                 "ancillary_fraction"):
        assert getattr(MPPIConfig(), name) == 0.0


@pytest.mark.parametrize("name", ["robust", "terrain"])
def test_another_controller_is_a_variant_with_its_settings(name):
    prof = SMOKE.with_overrides({"experiments.controller": name})
    assert experiment_stem("experiment1", prof) != experiment_stem("experiment1", SMOKE)
    for field, value in controller_settings(name).items():
        assert getattr(prof.mppi, field) == value
    assert prof.mppi.batch_size == SMOKE.mppi.batch_size  # the profile's sample count stays
    cost = np.random.default_rng(0).random((8, 4, 4)).astype(np.float32)
    args = trial_controller(prof, cost)
    assert args["mppi"] == prof.mppi
    # the terrain critic reads the method's own costmap (Binary's is zeros)
    assert ("costmap" in args) == (name == "terrain")
    if name == "terrain":
        assert args["costmap"] is cost and args["mppi"].terrain_weight > 0


def test_a_preset_with_one_of_its_settings_changed_on_top():
    """``--set experiments.controller=robust --set mppi.w_rate_std=1.0``, in either order:
    the preset first, then the setting; back to ``paper`` undoes the preset."""
    for order in ({"experiments.controller": "robust", "mppi.w_rate_std": 1.0},
                  {"mppi.w_rate_std": 1.0, "experiments.controller": "robust"}):
        prof = SMOKE.with_overrides(order)
        assert prof.mppi.w_rate_std == 1.0
        assert prof.mppi.ancillary_fraction == controller_settings("robust")["ancillary_fraction"]
    back = prof.with_overrides({"experiments.controller": "paper"})
    assert back.mppi == SMOKE.mppi
    tuned = SMOKE.with_overrides({"mppi.temperature": 0.5})
    assert tuned.mppi.temperature == 0.5
    assert experiment_stem("experiment1", tuned) != experiment_stem("experiment1", SMOKE)


def test_every_mppi_setting_can_be_set_and_is_checked():
    names = setting_names(type(SMOKE), "mppi")
    assert names == [f"mppi.{f.name}" for f in dataclasses.fields(MPPIConfig)]
    with pytest.raises(ValueError, match="temperature"):
        SMOKE.with_overrides({"mppi.temperature": 0.0})


@pytest.mark.parametrize("name, value", [("mppi.collision_radius_m", 2.0),
                                         ("mppi.footprint_offsets_m", "0,1")])
def test_what_each_drive_takes_from_its_vehicle_cannot_be_set(name, value):
    """The footprint circles come from the driven vehicle: a value given for them would be
    replaced at every drive, so it is refused in one line instead of being ignored."""
    with pytest.raises(ValueError, match=f"^{name}=.*footprint for every drive"):
        SMOKE.with_overrides({name: value})


def test_an_unknown_controller_is_refused():
    with pytest.raises(ValueError, match="controller"):
        SMOKE.with_overrides({"experiments.controller": "fast"})
    with pytest.raises(ValueError, match="unknown controller"):
        controller_settings("fast")
    with pytest.raises(ValueError, match="unknown controller"):
        with_controller(MPPIConfig(), "fast")


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


def test_a_trial_stored_before_the_mppi_section_existed_loads_with_the_paper_s():
    """Stored trials keep their profile (pickled): one from before the section has none,
    and gets the MPPI its run drove (the paper's, the only one then at its defaults)."""
    import pickle

    state = dict(SMOKE.__dict__)
    del state["mppi"]
    old = object.__new__(type(SMOKE))
    old.__setstate__(state)
    assert old.mppi == MPPIConfig()
    assert pickle.loads(pickle.dumps(SMOKE)) == SMOKE
