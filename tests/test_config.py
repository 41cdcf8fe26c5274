import re

import pytest

from dgt_lib.core.config import (
    PROFILE_NAMES,
    VEHICLES,
    UnknownProfileError,
    get_profile,
    profile_name,
)
from dgt_lib.core.overrides import InvalidOverrideError, parse_overrides


def test_three_profiles_exist_and_are_named():
    assert PROFILE_NAMES == ("smoke", "demo", "paper")
    for name in PROFILE_NAMES:
        assert get_profile(name).name == name


def test_environment_variable_selects_the_profile(monkeypatch):
    monkeypatch.setenv("DGT_PROFILE", "paper")
    assert get_profile().name == "paper"
    monkeypatch.delenv("DGT_PROFILE")
    assert get_profile().name == "demo"  # the default for a person stepping through


def test_explicit_argument_wins_over_environment(monkeypatch):
    monkeypatch.setenv("DGT_PROFILE", "paper")
    assert get_profile("smoke").name == "smoke"


def test_unknown_profile_is_a_clear_error_listing_valid_names(monkeypatch):
    with pytest.raises(UnknownProfileError, match="smoke, demo, paper"):
        get_profile("huge")
    monkeypatch.setenv("DGT_PROFILE", "fast")
    with pytest.raises(UnknownProfileError, match="DGT_PROFILE"):
        profile_name()


def test_paper_profile_records_the_papers_numbers():
    paper = get_profile("paper")
    assert paper.collect.episodes == (400, 400, 300, 200)  # Experiments → Dataset
    ex = paper.experiments
    assert (ex.n_hill, ex.n_ridge, ex.n_eval_jeep, ex.n_eval_vw_van) == (20, 50, 100, 99)
    assert paper.planner.step_m == 1.6 and paper.planner.beta == 150.0
    assert paper.costmap.n_headings == 8


def test_profiles_grow_from_smoke_to_paper():
    smoke, demo, paper = (get_profile(n) for n in PROFILE_NAMES)
    assert sum(smoke.collect.episodes) < sum(demo.collect.episodes) < sum(paper.collect.episodes)
    assert smoke.experiments.n_hill <= demo.experiments.n_hill <= paper.experiments.n_hill


def test_vehicle_order_is_the_head_order():
    assert VEHICLES == ("jeep", "vw_van", "mercedes_van", "carla_cola")


def test_seeds_are_consecutive_run_seeds_on_the_same_worlds():
    from dgt_lib.world.terrain import get_world

    demo = get_profile("demo")
    assert demo.seeds == 3 and get_profile("smoke").seeds == 1
    runs = demo.with_(seed=5).seed_profiles()
    assert [p.seed for p in runs] == [5, 6, 7]
    assert all(p.collect == demo.collect and p.seeds == 3 for p in runs)
    smoke = get_profile("smoke")
    for name in ("training", "eval", "hill"):  # a run seed changes no world
        assert (get_world(name, smoke).heights == get_world(name, smoke.with_(seed=1)).heights
                ).all()
    with pytest.raises(ValueError, match="seeds"):
        demo.with_(seeds=0)


# ----------------------------------------------------------------------------- overrides


def test_overrides_change_settings_typed_by_their_field():
    demo = get_profile("demo")
    p = demo.with_overrides({"planner.beta": 50, "experiments.n_hill": "10",
                             "collect.episodes": "4,4,3,2", "costmap.stride": (8, 4),
                             "train.patience": "none", "train.mirror_augment": "false",
                             "planner.heuristic": "euclidean", "seeds": "2"})
    assert p.planner.beta == 50.0 and isinstance(p.planner.beta, float)
    assert p.experiments.n_hill == 10 and isinstance(p.experiments.n_hill, int)
    assert p.collect.episodes == (4, 4, 3, 2) and p.costmap.stride == (8, 4)
    assert p.train.patience is None and p.train.mirror_augment is False
    assert p.planner.heuristic == "euclidean" and p.seeds == 2
    # everything else is the profile's, and the profile itself is unchanged
    assert p.planner.step_m == demo.planner.step_m and p.train.width == demo.train.width
    assert demo.planner.beta == 150.0 and demo.overrides == ()
    assert p.describe().startswith("'demo' with planner.beta=50.0, experiments.n_hill=10")


def test_overrides_from_the_command_line_syntax():
    items = ["planner.beta=50", "experiments.n_hill=10", "planner.beta=60"]
    assert parse_overrides(items) == {"planner.beta": "60", "experiments.n_hill": "10"}
    p = get_profile("smoke").with_overrides(parse_overrides(items))
    assert (p.planner.beta, p.experiments.n_hill) == (60.0, 10)
    with pytest.raises(InvalidOverrideError, match="NAME=VALUE"):
        parse_overrides(["planner.beta"])


def test_an_unknown_setting_is_an_error_naming_the_valid_ones():
    with pytest.raises(InvalidOverrideError, match="unknown setting 'planner.bta'") as err:
        get_profile("demo").with_overrides({"planner.bta": 50})
    assert "planner.beta" in str(err.value) and "planner.step_m" in str(err.value)
    with pytest.raises(InvalidOverrideError, match="worlds, collect, bev, train, costmap, planner, "
                                                   "experiments, mppi, ground_truth, conditioned, "
                                                   "or one of seed, seeds, workers"):
        get_profile("demo").with_overrides({"plan.beta": 50})
    with pytest.raises(InvalidOverrideError, match="unknown setting 'name'"):
        get_profile("demo").with_overrides(parse_overrides(["name=paper"]))


@pytest.mark.parametrize("key, value, expected", [
    ("planner.beta", "fifty", "planner.beta expects a number (e.g. planner.beta=150.0)"),
    ("experiments.n_hill", "2.5", "experiments.n_hill expects an integer"),
    ("experiments.n_hill", 2.5, "experiments.n_hill expects an integer"),
    ("experiments.n_hill", True, "experiments.n_hill expects an integer"),
    ("train.mirror_augment", "maybe", "train.mirror_augment expects true or false"),
    ("collect.episodes", "1,2", "collect.episodes expects 4 integers separated by commas"),
    ("train.patience", "soon", "train.patience expects an integer or none"),
    ("planner.heuristic", 3, "planner.heuristic expects a string"),
    ("seeds", "0", "seeds=0 is not allowed: seeds must be an integer in [1, 1,000]"),
    # a choice is checked when set, not when training reaches it an hour later
    ("train.conv_taps", "half",
     "train.conv_taps=half is not allowed: train.conv_taps must be one of all, live"),
    ("train.lr_schedule", "step", "train.lr_schedule must be one of constant, cosine"),
])
def test_a_value_of_the_wrong_type_is_a_clear_error(key, value, expected):
    with pytest.raises(InvalidOverrideError, match=re.escape(expected)):
        get_profile("demo").with_overrides({key: value})


def test_a_changed_setting_changes_the_cache_key_of_what_depends_on_it_only(
        tmp_path, monkeypatch):
    """The artifact cache keys each artifact on the settings it uses: a planner or
    experiment setting gives the experiments new keys and keeps the episodes' and BEV
    maps' (so the collection is reused); a collection setting changes the episodes'."""
    from dgt_lib.core.artifacts import config_hash
    from dgt_lib.stages.collect import bev_config, episode_config
    from dgt_lib.stages.experiments import experiment_config

    monkeypatch.setenv("DGT_DATA_DIR", str(tmp_path))
    demo = get_profile("demo")

    def keys(p):
        return {"episode": config_hash(episode_config(p, "jeep", 0)),
                "bev": config_hash(bev_config("hill", p)),
                "experiment1": config_hash(experiment_config("experiment1", p))}

    base = keys(demo)
    for setting in ({"planner.beta": 50}, {"experiments.n_hill": 10}):
        changed = keys(demo.with_overrides(setting))
        assert changed["experiment1"] != base["experiment1"], setting
        assert (changed["episode"], changed["bev"]) == (base["episode"], base["bev"]), setting
    changed = keys(demo.with_overrides({"collect.speed_mps": 4.0}))
    assert changed["episode"] != base["episode"]
    assert keys(demo.with_overrides({"planner.beta": 150})) == base  # the same value


# ----------------------------------------------------------------------------- allowed values

def _rows():
    from dgt_lib.core.constraints import SETTING_RULES

    return [pytest.param(name, rule, id=name) for name, rule in SETTING_RULES.items()]


@pytest.mark.parametrize("name, rule", _rows())
@pytest.mark.parametrize("profile_name_", PROFILE_NAMES)
def test_every_setting_refuses_a_value_just_outside_its_range_and_keeps_the_profile_s(
        profile_name_, name, rule):
    """Generated from the table: the value just outside the allowed range is refused at
    once, in one line naming the setting, the value and what is allowed; the profile's own
    value passes (every shipped profile is valid)."""
    from dgt_lib.core.constraints import _value
    from dgt_lib.core.overrides import format_setting

    profile = get_profile(profile_name_)
    with pytest.raises(InvalidOverrideError) as err:
        profile.with_overrides({name: rule.outside})
    message = str(err.value)
    assert "\n" not in message and message.startswith(f"{name}={format_setting(rule.outside)}")
    assert rule.allowed in message or "valid:" in message  # the table's words or the section's
    own = _value(profile, name)
    assert profile.with_overrides({name: own}).with_(overrides=()) == profile


def test_every_setting_but_a_switch_has_a_rule():
    """A new numeric or text setting cannot be added without saying what it allows."""
    from dataclasses import fields

    from dgt_lib.core.config import Profile
    from dgt_lib.core.constraints import SETTING_RULES
    from dgt_lib.core.overrides import setting_names, setting_type

    switches = {n for n in setting_names(Profile) if setting_type(Profile, n)[2] is bool}
    assert set(SETTING_RULES) == set(setting_names(Profile)) - switches
    assert len(fields(Profile)) > 0


def test_the_planner_heuristic_rule_matches_the_planner_s_heuristics():
    from dgt_lib.core.constraints import SETTING_RULES
    from dgt_lib.navigation.planner.heuristics import HEURISTICS

    rule = SETTING_RULES["planner.heuristic"]
    assert all(rule.check(h) for h in HEURISTICS) and rule.allowed == "one of " + ", ".join(
        HEURISTICS)


@pytest.mark.parametrize("rule", [pytest.param(r, id="+".join(r.names)) for r in
                                  __import__("dgt_lib.core.constraints",
                                             fromlist=["CROSS_RULES"]).CROSS_RULES])
def test_settings_that_must_agree_are_checked_together(rule):
    """A cross-field rule is checked on the whole profile: each setting alone may be fine,
    the pair is refused, naming both values; set together in one call, valid pairs pass
    whatever the order."""
    demo = get_profile("demo")
    with pytest.raises(InvalidOverrideError) as err:
        demo.with_overrides(rule.breaking)
    assert all(name in str(err.value) for name in rule.names)
    assert rule.allowed in str(err.value)


def test_a_pair_valid_together_is_accepted_in_either_order():
    demo = get_profile("demo")  # step 1.6: a substep of 2 is fine only with the longer step
    for order in ({"planner.substep_m": 2.0, "planner.step_m": 3.0},
                  {"planner.step_m": 3.0, "planner.substep_m": 2.0}):
        p = demo.with_overrides(order)
        assert (p.planner.step_m, p.planner.substep_m) == (3.0, 2.0)
    # a rule inside one section too: thinning a vehicle's runs, fraction named first
    for order in ({"train.scarce_fraction": 0.3, "train.scarce_vehicle": "vw_van"},
                  {"train.scarce_vehicle": "vw_van", "train.scarce_fraction": 0.3}):
        p = demo.with_overrides(order)
        assert (p.train.scarce_vehicle, p.train.scarce_fraction) == ("vw_van", 0.3)


@pytest.mark.parametrize("value", ["inf", "-inf", float("inf")])
def test_an_infinite_number_is_refused(value):
    with pytest.raises(InvalidOverrideError, match="planner.beta=inf|planner.beta=-inf"):
        get_profile("demo").with_overrides({"planner.beta": value})


def _bounded() -> list[tuple[str, object]]:
    """Each bounded setting with a value just above its bound (a pair for ``stride``)."""
    from dgt_lib.core.constraints import BOUNDS

    out = []
    for name, rule in BOUNDS.items():
        high = float(rule.allowed.split(", ")[-1].rstrip("])").replace(",", ""))
        over = int(high) + 1 if "integer" in rule.allowed else high * 1.01
        out.append((name, (over, 1) if name == "costmap.stride" else over))
    return out


@pytest.mark.parametrize("name, over", _bounded())
def test_every_setting_that_multiplies_work_or_memory_has_an_upper_bound(name, over):
    with pytest.raises(InvalidOverrideError, match=f"^{re.escape(name)}=.* is not allowed"):
        get_profile("smoke").with_overrides({name: over})


@pytest.mark.parametrize("setting, value", [
    ("costmap.n_headings", 100_000), ("worlds.hfield_resolution_m", 1e-6), ("seed", 10**300),
    ("workers", 10**6), ("seeds", 10**9), ("mppi.batch_size", 10**9),
    ("worlds.training_seed", 2**63),
])
def test_values_that_could_never_fit_in_memory_are_refused_in_one_line(setting, value):
    with pytest.raises(InvalidOverrideError) as err:
        get_profile("smoke").with_overrides({setting: value})
    assert "\n" not in str(err.value) and f"{setting} must be" in str(err.value)


def test_a_world_of_more_height_cells_than_a_machine_holds_is_refused():
    with pytest.raises(InvalidOverrideError, match="at most 16,000,000 height cells"):
        get_profile("smoke").with_overrides({"worlds.training_size_m": 1500.0,
                                             "worlds.hfield_resolution_m": 0.1})
