"""Where a profile's artifacts live: the one place that maps a :class:`Profile` to its
directory of the artifact cache (``dgt_lib.core.artifacts``).

Each run seed has its own directory, ``data/<profile>/seed-<seed>/``, so several seeds
are cached side by side and each resumes on its own; what pools the seeds (the results
report) lives in ``data/<profile>/``.
"""

from __future__ import annotations

from pathlib import Path

from dgt_lib.core import artifacts
from dgt_lib.core.config import Profile, as_profile
from dgt_lib.core.outputs import bounded_name
from dgt_lib.core.overrides import format_setting


def cache_dir(profile: Profile | str | None) -> str:
    """The cache key of a profile's artifacts for its run seed: ``<profile>/seed-<seed>``."""
    prof = as_profile(profile)
    return f"{prof.name}/seed-{prof.seed}"


def data_dir(profile: Profile | str | None) -> Path:
    """The artifact directory of the profile's run seed, e.g. ``data/demo/seed-0``."""
    return artifacts.profile_dir(cache_dir(profile))


def results_dir(profile: Profile | str | None) -> Path:
    """Where a run seed's report goes: ``data/<profile>/seed-<s>/results``, or for a
    profile changed by overrides ``…/results/variants/<the overrides>`` — a variant's
    report (``--set experiments.controller=robust``) never replaces the seed's own run
    record, which ``python -m dgt_lib.records publish`` copies."""
    prof = as_profile(profile)
    out = data_dir(prof) / "results"
    if not prof.overrides:
        return out
    text = ",".join(f"{k}={format_setting(v)}" for k, v in prof.overrides)
    return out / "variants" / bounded_name(text)


def profile_root(profile: Profile | str | None) -> Path:
    """The profile's directory, ``data/<profile>``: every seed below it, pooled results
    in ``results/``."""
    return artifacts.profile_dir(as_profile(profile).name)
