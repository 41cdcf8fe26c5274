"""Where a profile's artifacts live: the one place that maps a :class:`Profile` to its
directory of the artifact cache (``dgt_lib.core.artifacts``)."""

from __future__ import annotations

from pathlib import Path

from dgt_lib.core import artifacts
from dgt_lib.core.config import Profile, as_profile


def cache_dir(profile: Profile | str | None) -> str:
    """The cache key of a profile's artifacts: its directory under ``data/``."""
    return as_profile(profile).name


def data_dir(profile: Profile | str | None) -> Path:
    """The profile's artifact directory, e.g. ``data/demo``."""
    return artifacts.profile_dir(cache_dir(profile))
