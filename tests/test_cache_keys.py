"""Cache keys leave settings at their defaults out, and every default is reviewed when it
changes (:mod:`dgt_lib.core.cache_keys`).

When ``test_every_default_and_stage_version_is_the_reviewed_one`` fails, a default or a stage
version changed. A changed default alters the results of every run that did not set it:
bump the version of each stage it feeds (docs/ARCHITECTURE.md → Artifacts), then record
the new values with ``.venv/bin/python tests/test_cache_keys.py``.
"""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from dgt_lib.core import artifacts, cache_keys
from dgt_lib.core import config as config_module
from dgt_lib.core.config import CollectConfig, TrainConfig, get_profile

SNAPSHOT = Path(__file__).parent / "data" / "setting_defaults.json"


def _versions() -> dict[str, object]:
    from dgt_lib.learning.checkpoints import CHECKPOINT_VERSION
    from dgt_lib.perception.bev import BEV_FORMAT
    from dgt_lib.stages import collect, conditioned, costmaps, dataset, experiments, ground_truth

    return {"episodes": collect.EPISODE_FORMAT, "bev": BEV_FORMAT,
            "dataset": dataset.DATASET_FORMAT, "models": CHECKPOINT_VERSION,
            "costmaps": costmaps.COSTMAP_FORMAT, "ground_truth": ground_truth.GROUND_TRUTH_FORMAT,
            "accuracy": ground_truth.ACCURACY_FORMAT, "conditioned": conditioned.CONDITIONED_FORMAT,
            "experiments": experiments.EXPERIMENT_FORMAT}


def _defaults() -> dict[str, dict[str, object]]:
    classes = [c for c in vars(config_module).values() if isinstance(c, type)
               and dataclasses.is_dataclass(c) and c.__name__.endswith("Config")]
    return {c.__name__: {k: cache_keys.jsonable(v) for k, v in cache_keys.defaults(c).items()}
            for c in sorted(classes, key=lambda c: c.__name__)}


def current() -> dict[str, object]:
    return {"versions": _versions(), "defaults": _defaults()}


def test_every_default_and_stage_version_is_the_reviewed_one():
    recorded = json.loads(SNAPSHOT.read_text())
    now = current()
    changed = [f"{cls}.{k}: {recorded['defaults'].get(cls, {}).get(k, '(new)')!r} → {v!r}"
               for cls, fields in now["defaults"].items() for k, v in fields.items()
               if recorded["defaults"].get(cls, {}).get(k, v) != v]
    assert not changed, ("defaults changed — bump the versions of the stages they feed, then "
                         "rerun `python tests/test_cache_keys.py`:\n" + "\n".join(changed))
    assert now == recorded, "versions or settings changed: `python tests/test_cache_keys.py`"


def test_a_new_setting_at_its_old_behaviour_keeps_every_stored_key():
    """A setting added with the default that computes as before (a field the key never
    had) leaves the key as it was: no list of late fields to remember."""

    @dataclasses.dataclass(frozen=True)
    class Before:
        epochs: int = 10

    @dataclasses.dataclass(frozen=True)
    class After:
        epochs: int = 10
        schedule: str = "constant"

    before, after = {"train": Before(epochs=3)}, {"train": After(epochs=3)}
    assert cache_keys.jsonable(before)["train"] == {"__type__": "Before", "epochs": 3}
    assert cache_keys.jsonable(after)["train"] == {"__type__": "After", "epochs": 3}
    assert cache_keys.jsonable({"train": After(epochs=3, schedule="cosine")})["train"] == {
        "__type__": "After", "epochs": 3, "schedule": "cosine"}


def test_a_section_left_at_its_defaults_is_not_in_the_key():
    prof = get_profile("smoke")
    assert "bev" not in cache_keys.jsonable({"bev": prof.bev, "seed": 0})
    noisy = prof.with_overrides({"bev.pose_sigma_xy_m": 0.2})
    assert cache_keys.jsonable({"bev": noisy.bev})["bev"]["pose_sigma_xy_m"] == 0.2


def _legacy_meta(config: object) -> dict[str, object]:
    """A key as the kit stored it before defaults were left out: every field of every
    settings object (``dataclasses.asdict``, tagged), nothing dropped."""

    def every_field(obj: object) -> object:
        if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
            return {"__type__": type(obj).__name__,
                    **{k: every_field(v) for k, v in dataclasses.asdict(obj).items()}}
        if isinstance(obj, dict):
            return {str(k): every_field(v) for k, v in obj.items()}
        if isinstance(obj, (list, tuple)):
            return [every_field(v) for v in obj]
        return obj

    return every_field(config)


def _store(data_dir: Path, config: object, meta: dict[str, object]) -> Path:
    artifacts.ensure("x.json", config, lambda: {"value": 1}, profile="p", log=lambda _: None)
    path = data_dir / "p" / "x.json.meta.json"
    stored = json.loads(path.read_text())
    del stored["key_form"]  # written before keys had a form
    stored.update(meta)
    path.write_text(json.dumps(stored))
    return path


def test_an_artifact_stored_by_an_older_kit_with_an_every_field_key_is_rebuilt(tmp_path,
                                                                               monkeypatch):
    """Metadata written before keys left defaults out holds every field and no
    ``key_form``: the artifact is rebuilt once, and the reason says why."""
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    prof = get_profile("smoke")
    config = {"stage": "train", "format": 1, "train": prof.train}
    _store(tmp_path, config, {"config_hash": "0" * 16,
                              "config": _legacy_meta({"stage": "train", "train": prof.train})})
    assert "older kit" in artifacts.staleness("x.json", config, profile="p")
    artifacts.ensure("x.json", config, lambda: {"value": 2}, profile="p", log=lambda _: None)
    assert artifacts.staleness("x.json", config, profile="p") is None


def test_keys_written_now_are_in_key_form(tmp_path, monkeypatch):
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    cfg = {"collect": CollectConfig(speed_mps=4.0), "train": TrainConfig(), "a": np.arange(3)}
    artifacts.ensure("y.json", cfg, lambda: {"v": 1}, profile="p", log=lambda _: None)
    meta = json.loads((tmp_path / "p" / "y.json.meta.json").read_text())
    assert meta["key_form"] == cache_keys.KEY_FORM
    assert meta["config"]["collect"] == {"__type__": "CollectConfig", "speed_mps": 4.0}
    assert "train" not in meta["config"]


@pytest.mark.parametrize("name", ["smoke", "demo", "paper"])
def test_the_stages_keys_read_the_profile_s_changed_settings(name):
    """A profile's own settings (not the defaults) are what its keys hold."""
    prof = get_profile(name)
    from dgt_lib.stages.experiments import experiment_config

    key = cache_keys.jsonable(experiment_config("experiment1", prof))
    assert key["format"] == 1 and key["seed"] == prof.seed
    planner = {f.name: getattr(prof.planner, f.name) for f in dataclasses.fields(prof.planner)}
    defaults = cache_keys.defaults(type(prof.planner))
    assert {k for k in key.get("planner", {}) if k != "__type__"} == {
        k for k, v in planner.items() if cache_keys.jsonable(v) != cache_keys.jsonable(defaults[k])}


if __name__ == "__main__":  # record today's defaults and versions as the reviewed ones
    SNAPSHOT.parent.mkdir(exist_ok=True)
    SNAPSHOT.write_text(json.dumps(current(), indent=1, sort_keys=True) + "\n")
    sys.exit(0)



def test_the_mujoco_release_the_kit_pins_keeps_keys_another_rebuilds(tmp_path, monkeypatch):
    """MuJoCo 4.0.1 drove 6 of `demo` seed 0's 130 episodes differently from 4.0.0: an
    artifact simulated or drawn by one release is not another's. The pinned release is
    left out of the keys (a cache built with it stays valid); any other one is in them."""
    from dgt_lib.stages import collect
    from dgt_lib.world.mujoco_model import Physics

    root = Path(__file__).resolve().parent.parent
    for pinning in ("pyproject.toml", "environment.yml"):
        assert f'mujoco=={Physics().mujoco}' in (root / pinning).read_text(), pinning
    prof = get_profile("smoke")
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    monkeypatch.setattr(collect, "PHYSICS", Physics())
    relpath, pinned = "episodes/one.npz", collect.episode_config(prof, "jeep", 0)
    artifacts.ensure(relpath, pinned, lambda: {"x": np.zeros(1)}, profile="smoke")
    survey_key = artifacts.config_hash(collect.bev_config("hill", prof))
    assert "mujoco" not in json.dumps(cache_keys.jsonable(pinned))
    monkeypatch.setattr(collect, "PHYSICS", Physics(mujoco="4.0.1"))
    assert (artifacts.staleness(relpath, collect.episode_config(prof, "jeep", 0),
                                profile="smoke") == "configuration changed (physics)")
    assert artifacts.config_hash(collect.bev_config("hill", prof)) != survey_key
