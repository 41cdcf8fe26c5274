"""Two tiny stages used by tests/test_cli.py to exercise `dgt reproduce`."""

from dgt_lib.core import artifacts
from dgt_lib.stages.registry import StageOutput


def first(profile):
    artifacts.ensure("example.json", {"p": profile.name}, lambda: {"n": 1}, profile=profile.name)
    return StageOutput([artifacts.profile_dir(profile.name) / "example.json"], "wrote 1 file")


def second(profile):
    value = artifacts.load(artifacts.profile_dir(profile.name) / "example.json")
    return StageOutput([], f"read n={value['n']}")
