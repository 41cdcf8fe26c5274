"""Markdown tables rendered from published run records (``docs/runs/<run>/seed-*.json``).

A :class:`Run` is one published run: one profile, one processor, its seeds' records.
Every table names what it pools (:func:`caption`): profile, seeds, processor, commit and
the folder of its records. Nothing here measures anything; everything here formats what
the records hold, so the same records always render the same text.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from dgt_lib.evaluation import accuracy, seeds
from dgt_lib.evaluation.experiments import EXPERIMENT_TITLES, EXPERIMENTS
from dgt_lib.evaluation.paper import PAPER
from dgt_lib.evaluation.statistics import n_seeds
from dgt_lib.mapping.methods import METHOD_LABELS, METHODS
from dgt_lib.records.claims import CLAIMS, Verdict, pooled, route_claim
from dgt_lib.records.provenance import processor_label

EXPERIMENT_ROWS: tuple[tuple[str, str, str], ...] = (
    ("experiment1", "carla_cola", "1 · hill, carla_cola"),
    ("experiment2", "mercedes_van", "2 · ridge, mercedes_van"),
    ("experiment2_jeep", "jeep", "2 · ridge, jeep (ours: the same queries)"),
    ("experiment3", "jeep", "3 · random, jeep"),
    ("experiment3", "vw_van", "3 · random, vw_van"),
)
"""The README results table's rows: (experiment, vehicle, label)."""

ROUTE_CLAIMS = ("hill_ascent_A", "hill_descent_B", "ridge_smooth", "ridge_jeep_sharp")
"""The claims about which way DGT-Map's plans go (the README's hero figure draws them)."""


def seeds_holding(records: Sequence[dict], names: Sequence[str] = ROUTE_CLAIMS) -> list[int]:
    """The seeds whose run record (:mod:`dgt_lib.records.record`) says every claim of
    ``names`` held in it, in order."""
    return [r["seed"] for r in records if all(r["claims"][name][2] for name in names)]


def results_digest(record: dict) -> str:
    """A digest of what a seed's run record says it found (experiments and claims): equal
    for two runs of a seed that reached the same results, wherever they ran."""
    found = json.dumps([record["experiments"], record["claims"]], sort_keys=True)
    return hashlib.sha256(found.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Run:
    """One published run: its folder's name and its seeds' records, by seed."""

    name: str
    records: tuple[dict, ...]

    @classmethod
    def load(cls, folder: Path) -> Run:
        """The run in ``folder`` (every ``seed-*.json``); ValueError for an empty one."""
        paths = sorted(folder.glob("seed-*.json"), key=lambda p: int(p.stem.split("-")[1]))
        if not paths:
            raise ValueError(f"{folder}: no seed-*.json run records")
        return cls(folder.name, tuple(json.loads(p.read_text()) for p in paths))

    @property
    def profile(self) -> str:
        return self.records[0]["profile"]

    @property
    def seeds(self) -> list[int]:
        return [r["seed"] for r in self.records]

    @property
    def processor(self) -> str:
        return processor_label(self.records[0]["processor"])

    @property
    def commits(self) -> list[str]:
        return sorted({r["commit"][:7] + ("+changes" if "+" in r["commit"] else "")
                       for r in self.records})


def seed_text(ids: Sequence[int]) -> str:
    """``8 seeds (0–7)``, ``3 seeds (0, 2, 5)``, ``1 seed (0)``."""
    ids = sorted(ids)
    if len(ids) > 2 and ids == list(range(ids[0], ids[-1] + 1)):
        span = f"{ids[0]}–{ids[-1]}"
    else:
        span = ", ".join(map(str, ids))
    return f"{n_seeds(len(ids))} ({span})"


def caption(run: Run, link_prefix: str = "docs/") -> str:
    """What a table of ``run`` pools: profile, seeds, processor, commit(s), records."""
    return (f"`{run.profile}`, {seed_text(run.seeds)}, {run.processor}, commit "
            f"{', '.join(f'`{c}`' for c in run.commits)}; records: "
            f"[`docs/runs/{run.name}/`]({link_prefix}runs/{run.name}/)")


def _kn(kn: tuple[int, int] | None) -> str:
    return "—" if kn is None else f"{kn[0]}/{kn[1]}"


def results_table(runs: Sequence[Run]) -> str:
    """k/n per method: the paper's Tables I and II beside each run's pooled arrivals;
    the best of a row in bold."""
    head = ["experiment", "source", *(METHOD_LABELS[m] for m in METHODS)]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for experiment, vehicle, label in EXPERIMENT_ROWS:
        paper = PAPER.get(experiment, {}).get(vehicle)
        rows = []
        if paper is not None:
            rows.append(("the paper", {m: (k, paper.n) for m, k in paper.k.items()}))
        elif experiment == "experiment2_jeep":
            rows.append(("the paper", {}))
        for run in runs:
            rows.append((f"ours, `{run.profile}`, {n_seeds(len(run.seeds))}",
                         {m: pooled(run.records, experiment, vehicle, m) for m in METHODS}))
        for i, (source, counts) in enumerate(rows):
            rates = [k / n for k, n in (c for c in counts.values() if c)]
            best = max(rates, default=None)
            cells = []
            for m in METHODS:
                kn = counts.get(m)
                text = _kn(kn)
                cells.append(f"**{kn[0]}**/{kn[1]}" if kn and kn[0] / kn[1] == best else text)
            lines.append(f"| {label if i == 0 else ''} | {source} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def claims_table(runs: Sequence[Run], by_processor: bool = False) -> str:
    """Each claim of :data:`~dgt_lib.records.claims.CLAIMS`: the paper's numbers, what each
    run measured, and the verdict by the claim's rule; ``by_processor``: each run's column
    names its processor (runs of one profile on several)."""
    head = ["claim", "the paper"]
    for run in runs:
        where = f", {run.processor.split(' (')[0]}" if by_processor else ""
        head += [f"`{run.profile}`, {n_seeds(len(run.seeds))}{where}", "verdict"]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for claim in CLAIMS:
        cells = [claim.text + (" (ours)" if claim.ours else ""), claim.paper]
        for run in runs:
            v = claim.check(run.records)
            word = v.word if not claim.ours else v.word.replace(
                "**not reproduced**", "**does not hold**").replace("**reproduced**", "**holds**")
            cells += [v.measured, word]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def verdicts(run: Run) -> list[tuple[str, Verdict, bool]]:
    """(short name, verdict, ours) of every claim in ``run``."""
    return [(c.short, c.check(run.records), c.ours) for c in CLAIMS]


def verdicts_by_key(run: Run) -> dict[str, Verdict]:
    """The route claims' verdicts in ``run`` by their key in
    :data:`dgt_lib.evaluation.seeds.CLAIMS`."""
    return {key: route_claim(key)(run.records) for key in seeds.CLAIMS}


def bottom_line(runs: Sequence[Run]) -> str:
    """At most two sentences over the cited runs: how many of the paper's claims checked
    here each reproduces and which (in every run, in one only), then which in none."""
    checked = [{s: v.reproduced for s, v, ours in verdicts(r)
                if not ours and v.reproduced is not None} for r in runs]
    names = list(dict.fromkeys(s for c in checked for s in c))

    def which(keep) -> str:
        these = [s for s in names if keep([c.get(s, False) for c in checked])]
        return ", ".join(these[:-1]) + " and " + these[-1] if len(these) > 1 else "".join(these)

    where = [f"`{r.profile}` ({seed_text(r.seeds)}, {r.processor}) reproduces "
             f"{sum(c.values())} of {len(c)}" for r, c in zip(runs, checked, strict=True)]
    groups = [("", all)] if len(runs) == 1 else [
        (f"in {'both runs' if len(runs) == 2 else 'every run'}: ", all),
        *[(f"only on `{r.profile}`: ", lambda yes, i=i: yes[i] and not all(yes))
          for i, r in enumerate(runs)]]
    found = [label + which(keep) for label, keep in groups if which(keep)]
    text = "Of the paper's claims checked here, " + " and ".join(where)
    text += (" — " + "; ".join(found) if found else "") + "."
    none = which(lambda yes: not any(yes))
    if none:
        text += (" Not reproduced: " if len(runs) == 1 else
                 f" Reproduced in {'neither' if len(runs) == 2 else 'none'}: ") + none + "."
    return text + "\n"


def provenance_table(run: Run) -> str:
    """Seed by seed: commit, date, processor, library versions."""
    lines = ["| seed | commit | date (UTC) | processor | Python / numpy / torch / mujoco |",
             "|---|---|---|---|---|"]
    for r in run.records:
        v = r["versions"]
        lines.append(f"| {r['seed']} | `{r['commit'][:7]}` | {r['date_utc'][:10]} | "
                     f"{processor_label(r['processor'])} | {v['python']} / {v['numpy']} / "
                     f"{v['torch']} / {v['mujoco']} |")
    return "\n".join(lines) + "\n"


def stage_time_table(run: Run) -> str:
    """Each stage's wall time per seed [s], summed over the invocations that ran it (a
    cached stage counts under a second), with the highest 1-minute load seen at a start."""
    stages = list(dict.fromkeys(t["stage"] for r in run.records for t in r.get("stage_times", [])))
    if not stages:
        return "No stage times in these records.\n"
    lines = ["| seed | " + " | ".join(stages) + " | total | load at start |",
             "|---|" + "---|" * (len(stages) + 2)]
    for r in run.records:
        times = r.get("stage_times", [])
        per = [sum(t["seconds"] for t in times if t["stage"] == s) for s in stages]
        loads = [t["load_1min_before"] for t in times if t.get("load_1min_before") is not None]
        lines.append(f"| {r['seed']} | " + " | ".join(f"{x:.0f}" for x in per)
                     + f" | {sum(per):.0f} | ≤ {max(loads, default=float('nan')):.1f} |")
    return "\n".join(lines) + "\n"


def seeds_sections(run: Run, *, published: bool = True) -> str:
    """Every seed of ``run``: the claims seed by seed, every experiment over the seeds, the
    models' test errors, the costmaps' accuracy; for a ``published`` run (docs/results.md)
    also what it pools, and where, when and how long each seed ran. ``dgt reproduce``'s
    own report over seeds is the same text for the run in the data directory."""
    recs = list(run.records)
    parts = [f"Pooled: {caption(run, '')}.", ""] if published else []
    parts += ["### Claims, seed by seed", "", seeds.claims_table(recs)]
    for name in EXPERIMENTS:
        parts += [f"### {EXPERIMENT_TITLES[name]}", "",
                  seeds.experiment_over_seeds(recs, name, PAPER.get(name))]
    parts += ["### Learned locomotion (test split)", "", seeds.learning_table(recs)]
    scored = [r for r in recs if r.get("accuracy")]
    if scored:
        parts += ["### Costmaps against the driven ground truth (open loop)", "",
                  "Multi-task against single-task per vehicle, seed by seed (closer = MAE "
                  "lower by ≥ 0.005 with p < 0.05 in a paired test on the same samples):", "",
                  accuracy.multitask_over_seeds({r["seed"]: r["multitask"] for r in scored}),
                  "Every method, per seed (MAE / Spearman ρ):", "",
                  accuracy.accuracy_over_seeds({r["seed"]: r["accuracy"] for r in scored})]
    if published:
        parts += ["### Where and when each seed ran", "", provenance_table(run),
                  "### Stage wall times [s]", "", stage_time_table(run)]
    return "\n".join(parts)


def cross_machine_table(runs: Sequence[Run]) -> str:
    """The same profile and seed run on more than one processor, side by side (physics'
    last bits follow the processor family): DGT-Map's arrivals per experiment, then the
    seed's own claims (:data:`~dgt_lib.evaluation.seeds.CLAIMS`: count, and ✓ where it
    held), each row with the commit and the MuJoCo version it ran."""
    arrivals, claims = [], []
    for profile in dict.fromkeys(r.profile for r in runs):
        mine = [r for r in runs if r.profile == profile]
        shared = sorted(set.intersection(*(set(r.seeds) for r in mine))) if len(mine) > 1 else []
        for seed, run in ((seed, run) for seed in shared for run in mine):
            rec = next(x for x in run.records if x["seed"] == seed)
            row = (f"| `{profile}` | {seed} | {run.processor}, `{rec['commit'][:7]}`, MuJoCo "
                   f"{rec['versions'].get('mujoco', '?')} | ")
            arrivals.append(row + " | ".join(_kn(pooled([rec], e, v, "dgt"))
                                             for e, v, _ in EXPERIMENT_ROWS) + " |")
            held = [rec["claims"].get(key) for key in seeds.CLAIMS]
            claims.append(row + " | ".join("—" if c is None else f"{c[0]}/{c[1]} "
                                           f"{'✓' if c[2] else '✗'}" for c in held) + " |")
    if not arrivals:
        return ("No seed of a profile has records from more than one processor yet; when one "
                "has, this table sets them side by side.\n")
    head, rule = "| profile | seed | processor, commit, MuJoCo | ", "|" + "---|" * 3
    return "\n".join([head + " | ".join(x for _, _, x in EXPERIMENT_ROWS) + " |",
                      rule + "---|" * len(EXPERIMENT_ROWS), *arrivals, "",
                      head + " | ".join(t for t, _ in seeds.CLAIMS.values()) + " |",
                      rule + "---|" * len(seeds.CLAIMS), *claims]) + "\n"
