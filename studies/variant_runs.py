"""What the studies that rerun the pipeline with other settings share: each variant runs in
its own data directory, linked to what it shares with the profile's own run, in a process of
its own (its ``DGT_DATA_DIR``), and stores its scores as JSON so a rerun resumes.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path


def link(target: Path, link_path: Path) -> None:
    """``link_path`` → ``target`` (a file or directory of the profile's run), made once; nothing
    while ``target`` does not exist."""
    if link_path.is_symlink() or not target.exists():
        return
    link_path.parent.mkdir(parents=True, exist_ok=True)
    link_path.symlink_to(target.resolve(), target_is_directory=target.is_dir())


def stored_or_run(path: Path, root: Path, command: list[str], what: str) -> dict:
    """The JSON scores at ``path``; if missing, ``command`` runs first (``python`` + its
    arguments) with ``DGT_DATA_DIR=root`` and must write them."""
    if path.exists():
        return json.loads(path.read_text())
    print(f"[{Path(command[0]).stem}] {what} in {root}", flush=True)
    subprocess.run([sys.executable, *command], env={**os.environ, "DGT_DATA_DIR": str(root)},
                   check=True)
    return json.loads(path.read_text())


def write_scores(path: Path, scores: dict) -> None:
    """Store one variant's scores (written whole, then renamed: a crash leaves none)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(scores, indent=1))
    tmp.replace(path)
