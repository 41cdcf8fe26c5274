"""Two tiny stages used by tests/test_cli.py to exercise `dgt reproduce`."""

from dgt_lib.core import artifacts
from dgt_lib.stages.paths import cache_dir, data_dir
from dgt_lib.stages.registry import StageOutput


def first(profile):
    artifacts.ensure("example.json", {"p": profile.name, "seed": profile.seed},
                     lambda: {"n": 1, "seed": profile.seed}, profile=cache_dir(profile))
    return StageOutput([data_dir(profile) / "example.json"], "wrote 1 file")


def second(profile):
    value = artifacts.load(data_dir(profile) / "example.json")
    return StageOutput([], f"read n={value['n']} of seed {value['seed']}")
