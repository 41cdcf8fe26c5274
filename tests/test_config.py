import pytest

from dgt_lib.core.config import (
    PROFILE_NAMES,
    VEHICLES,
    UnknownProfileError,
    get_profile,
    profile_name,
)


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
