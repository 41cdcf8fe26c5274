"""Where and with what a run was made: commit, processor, cores, library versions, date.

Physics' floating point follows the processor family, so a run's numbers are only
comparable with another run's when the records say on which processor each was made.
"""

from __future__ import annotations

import os
import platform
import re
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
"""The kit's checkout (where ``git`` finds the commit)."""

PACKAGES = ("numpy", "torch", "mujoco", "scipy")
"""Libraries whose version changes results, recorded with every run."""

FLAGS = ("avx2", "avx512f", "amx_tile")
"""CPU flags that change the speed (and, across families, the last bits) of a run."""


def commit() -> str:
    """``git rev-parse HEAD`` of the checkout, with ``+changes`` when ``dgt_lib/`` differs
    from it; ``unknown`` outside a git checkout (an installed wheel)."""
    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=ROOT, check=True, capture_output=True,
                              text=True, timeout=10).stdout.strip()
    try:
        changed = git("status", "--porcelain", "--", "dgt_lib")
        return git("rev-parse", "HEAD") + ("+changes" if changed else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def _cpuinfo() -> dict[str, str]:
    """The first processor's fields of ``/proc/cpuinfo`` ({} where there is none)."""
    try:
        text = Path("/proc/cpuinfo").read_text(encoding="utf-8", errors="replace")
    except OSError:
        return {}
    first = text.split("\n\n", 1)[0]
    return {k.strip(): v.strip() for k, _, v in (ln.partition(":") for ln in first.splitlines())}


def processor() -> dict[str, object]:
    """The processor: its model name, vendor family and model numbers, the flags of
    :data:`FLAGS` it has, and the number of CPUs the process sees."""
    info = _cpuinfo()
    flags = set(info.get("flags", "").split())
    return {"model": info.get("model name") or platform.processor() or platform.machine(),
            "family": info.get("cpu family"), "model_id": info.get("model"),
            "flags": [f for f in FLAGS if f in flags], "cpus": os.cpu_count()}


def processor_label(proc: dict) -> str:
    """A short human name: ``AMD EPYC (family 25 model 1, AVX2), 2 CPUs``."""
    inner = [f"family {proc['family']} model {proc['model_id']}"] if proc.get("family") else []
    inner += [f.upper().replace("_TILE", "").replace("512F", "-512") for f in proc.get("flags", [])]
    name = re.sub(r"\s*\((R|TM)\)", "", str(proc["model"]))
    parens = f" ({', '.join(inner)})" if inner else ""
    return f"{name}{parens}, {proc['cpus']} CPUs"


def processor_slug(proc: dict) -> str:
    """A file-name-safe short name: ``amd-epyc-f25m1``."""
    base = re.sub(r"[^a-z0-9]+", "-", str(proc["model"]).lower()).strip("-")[:24]
    fam = f"-f{proc['family']}m{proc['model_id']}" if proc.get("family") else ""
    return base + fam


def versions() -> dict[str, str]:
    """Python's and :data:`PACKAGES`' versions (``missing`` for one not installed)."""
    out = {"python": sys.version.split()[0]}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "missing"
    return out


def provenance() -> dict[str, object]:
    """Everything above, with the date (UTC): the head of every run record."""
    return {"commit": commit(), "processor": processor(), "versions": versions(),
            "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
