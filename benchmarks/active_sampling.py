"""The active sampler replayed against the robust Fig. 6 reference: runs, CPU and agreement.

The reference (:mod:`benchmarks.fig6_reference`: every cell of the MuJoCo Fig. 6 grid with all 4
replicas, ``results/reference/fig6_robust/runs.csv``) answers every run the sampler asks for, so
a sampler's settings are compared in seconds per seed instead of minutes of simulation:

* **runs**: trials and replicas it asks for; **cpu_s**: the sum of their stored wall times (the
  CPU a run of them takes, two workers halve the wall time);
* **agreement**: under each rule, the share of cells whose map label equals the reference's
  robust label (its label where all 5 runs agree, else *not robust*). A simulated cell's map label
  is its label where its replicas all agree, *not robust* where one disagrees, its own trial's
  where it had none (its neighbours all agree with it), *unchecked* where its replicas stopped at
  a disagreement of a label of the other rule; a cell never simulated has the model's likeliest
  label, as the run stores it (none where the likeliest class is not robust, none for a rule the
  sampler does not follow);
* **estimate**: the sampler's own estimated agreement when it stopped, against the true one;
* **headline**: the smallest DSR with a robust pinch of every width, counted on the map as the
  readers count it (:func:`somo_sweep.sweep.views.answers.answer`), against the reference's.

``python -m benchmarks.active_sampling`` replays each configuration of :data:`CONFIGS` over
``--seeds`` seeds and writes ``results/reference/active_sampling.json``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from benchmarks._cli import echo, int_in, user_errors
from benchmarks.fig6_reference import NOT_ROBUST, REFERENCE, REPLICAS, RULES, cells
from somo_sweep.cli.output import write_outputs
from somo_sweep.paper.fig6_table import AXES, headline_question
from somo_sweep.sweep.run.active import NOT_ROBUST as SAMPLER_NOT_ROBUST
from somo_sweep.sweep.run.active import Sampler, SamplerSettings
from somo_sweep.sweep.run.replica_rule import Verdict
from somo_sweep.sweep.run.robustness import fold
from somo_sweep.sweep.views.answers import answer

__all__ = ["CONFIGS", "Oracle", "Replay", "main", "replay"]

#: A label the map has no value for (a rule the sampler did not follow, never simulated).
UNKNOWN = "unknown"
#: Replicas stopped by the other rule's disagreement: this rule's robustness is not known.
UNCHECKED = "unchecked"


@dataclass(frozen=True)
class Config:
    """One sampler configuration: its settings and the rules it follows."""

    name: str
    settings: SamplerSettings
    follow: tuple[str, ...] = ("contacts",)


BOTH = ("contacts", "paper")
#: ``studies/pinch_grasp_dsr_mujoco.yaml``'s settings (``make fig6-fast``): both rules, batches of 80.
FIG6_FAST = SamplerSettings(replicas=REPLICAS, batch=80, target_agreement=0.97)
CONFIGS = (
    Config("fig6_fast", FIG6_FAST, BOTH),
    Config("neighbours", replace(FIG6_FAST, model="neighbours"), BOTH),
    Config("batch_20", replace(FIG6_FAST, batch=20), BOTH),
    Config("no_exploration", replace(FIG6_FAST, exploration=0.0), BOTH),
    Config("target_0.95", replace(FIG6_FAST, target_agreement=0.95), BOTH),
    Config("target_0.98", replace(FIG6_FAST, target_agreement=0.98), BOTH),
    Config("replicate_all", replace(FIG6_FAST, replicate="all"), BOTH),
    Config("contacts_only", FIG6_FAST),
)


class Oracle:
    """The reference's runs, by (cell, replica): each rule's label and the wall time.

    Args:
        runs: The stored runs (:func:`benchmarks.fig6_reference.export_runs`), cells in grid order.
    """

    def __init__(self, runs: pd.DataFrame):
        self.runs = runs
        # The study's grid, then its repeats (one), as the run's sampler sees it.
        self.shape = (*(runs.loc[runs["replica"] == 0, a].nunique() for a in AXES_IN_GRID_ORDER), 1)
        self.n = int(np.prod(self.shape))
        self.labels: dict[tuple[int, int], dict[str, str]] = {}
        self.time_s: dict[tuple[int, int], float] = {}
        for row in runs.itertuples(index=False):
            key = (int(row.trial), int(row.replica))
            self.labels[key] = {rule: str(getattr(row, column)) for rule, column in RULES.items()}
            self.time_s[key] = float(row.wall_time_s)

    def outcome(self, follow: Sequence[str]) -> Any:
        """The sampler's ``outcome(cell, replica)``: each followed rule's label."""
        return lambda cell, number: tuple(self.labels[(cell, number)][r] for r in follow)


#: The study's axes in its grid order (DSR, width, centering position: trial = C order).
AXES_IN_GRID_ORDER = ("distal_segment_ratio", "object_width_m", "centering_position_m")


@dataclass(frozen=True)
class Replay:
    """What one seed of one configuration did (module docstring)."""

    config: str
    seed: int
    runs: int
    batches: int
    cpu_s: float
    cells_simulated: int
    cells_replicated: int
    estimate: float
    agreement: dict[str, float]
    agreement_on_robust_cells: dict[str, float]
    agreement_of_majority_labels: dict[str, float]
    headline: dict[str, float | None]
    seconds: float


def _claims(sampler: Sampler, oracle: Oracle, follow: Sequence[str], rule: str) -> list[str]:
    """Every cell's map label under ``rule`` (module docstring)."""
    k = sampler.settings.replicas
    out = []
    classes = sampler.claims()
    for cell in range(sampler.n):
        if cell not in sampler.own:  # as stored: no label where the likeliest class is not robust
            value = classes[cell][follow.index(rule)] if rule in follow else UNKNOWN
            out.append(UNKNOWN if value == SAMPLER_NOT_ROBUST else value)
            continue
        own = oracle.labels[(cell, 0)][rule]
        if cell not in sampler.chosen:
            out.append(own)
            continue
        ran = [n for n, r in enumerate(sampler.replicas.get(cell, []), start=1) if r is not None]
        values = {oracle.labels[(cell, n)][rule] for n in ran}
        if values - {own}:
            out.append(NOT_ROBUST)
        elif len(ran) == k:
            out.append(own)
        else:
            verdicts = sampler.verdicts(cell)
            out.append(UNCHECKED if any(v is Verdict.BROKEN for v in verdicts) else "open")
    return out


def _majority(sampler: Sampler, oracle: Oracle, follow: Sequence[str], rule: str) -> list[str]:
    """Every cell's majority label under ``rule`` over the runs the sampler asked for (its own
    trial's on a tie), the model's likeliest label where it simulated nothing."""
    out = []
    classes = sampler.claims()
    for cell in range(sampler.n):
        if cell not in sampler.own:
            value = classes[cell][follow.index(rule)] if rule in follow else UNKNOWN
            out.append(UNKNOWN if value == SAMPLER_NOT_ROBUST else value)
            continue
        ran = [0, *(n for n, r in enumerate(sampler.replicas.get(cell, []), start=1) if r is not None)]
        values = [oracle.labels[(cell, n)][rule] for n in ran]
        top = max(values.count(v) for v in values)
        out.append(
            values[0] if values.count(values[0]) == top else next(v for v in values if values.count(v) == top)
        )
    return out


def _headline(
    sampler: Sampler, oracle: Oracle, follow: Sequence[str], rule: str, reference: pd.DataFrame
) -> float | None:
    """The headline as ``paper fig6`` reads it off the run's folder: the runs the sampler asked
    for and its inferred cells, folded (a cell whose replicas stopped at disagreements awaits
    none), counted on robust cells and on interior cells without replicas."""
    classes = sampler.claims()
    rows = []
    for cell in range(sampler.n):
        if cell in sampler.own:
            ran = [0, *(n for n, r in enumerate(sampler.replicas.get(cell, []), start=1) if r is not None)]
            rows += [(cell, n, oracle.labels[(cell, n)][rule], False) for n in ran]
        else:
            value = classes[cell][follow.index(rule)] if rule in follow else UNKNOWN
            rows.append((cell, 0, UNKNOWN if value == SAMPLER_NOT_ROBUST else value, True))
    runs = pd.DataFrame(rows, columns=["trial", "replica", "label", "inferred"])
    runs["status"] = "ok"
    stopped = [c for c in sampler.chosen if all(v is Verdict.BROKEN for v in sampler.verdicts(c))]
    folded = fold(runs, ["label"], planned=sampler.settings.replicas, chosen=sampler.chosen, stopped=stopped)
    table = reference[["trial", *AXES]].merge(folded.drop(columns=["label"]), on="trial")
    table["label"] = table["label_majority"]
    table = table[["trial", *AXES, "label", "inferred", "replicas", "replicas_awaited", "robust"]]
    value = answer(table, headline_question(table)).table.iloc[0]["answer"]
    return None if pd.isna(value) else round(float(value), 6)


def replay(oracle: Oracle, config: Config, seed: int, reference: dict[str, pd.DataFrame]) -> Replay:
    """One seed of one configuration against the reference."""
    start = time.perf_counter()
    sampler = Sampler(oracle.shape, replace(config.settings, seed=seed))
    asked: list[tuple[int, int]] = []
    batches = 0
    for batch in sampler.batches(oracle.outcome(config.follow)):
        asked += batch
        batches += 1
    agreement, robust_share, headline, majority = {}, {}, {}, {}
    for rule in RULES:
        truth = reference[rule]["robust_label"].to_numpy()
        claims = _claims(sampler, oracle, config.follow, rule)
        same = np.asarray(claims) == truth
        agreement[rule] = round(float(same.mean()), 4)
        robust = truth != NOT_ROBUST
        robust_share[rule] = round(float(same[robust].mean()), 4)
        headline[rule] = _headline(sampler, oracle, config.follow, rule, reference[rule])
        labels = np.asarray(_majority(sampler, oracle, config.follow, rule))
        majority[rule] = round(float((labels == reference[rule]["label"].to_numpy()).mean()), 4)
    return Replay(
        config.name,
        seed,
        len(asked),
        batches,
        round(sum(oracle.time_s[a] for a in asked), 1),
        len(sampler.own),
        len(sampler.chosen),
        round(sampler.estimate, 4),
        agreement,
        robust_share,
        majority,
        headline,
        round(time.perf_counter() - start, 1),
    )


def summary(rows: list[Replay], reference_headline: dict[str, Any]) -> dict[str, Any]:
    """Medians (and worst) over seeds of one configuration."""
    out: dict[str, Any] = {
        "runs_median": statistics.median(r.runs for r in rows),
        "runs_max": max(r.runs for r in rows),
        "batches_median": statistics.median(r.batches for r in rows),
        "cpu_s_median": statistics.median(r.cpu_s for r in rows),
        "estimate_median": statistics.median(r.estimate for r in rows),
        "replay_s_median": statistics.median(r.seconds for r in rows),
    }
    for rule in RULES:
        out[f"agreement_{rule}_median"] = statistics.median(r.agreement[rule] for r in rows)
        out[f"agreement_{rule}_min"] = min(r.agreement[rule] for r in rows)
        out[f"majority_agreement_{rule}_median"] = statistics.median(
            r.agreement_of_majority_labels[rule] for r in rows
        )
        want = reference_headline[rule]["smallest_all_width_pinch_dsr"]
        out[f"headline_{rule}_same"] = sum(r.headline[rule] == want for r in rows)
    return out


def main(argv: list[str] | None = None) -> None:
    """``python -m benchmarks.active_sampling``: every configuration over the seeds."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int_in(1, 100), default=10)
    parser.add_argument("--configs", nargs="*", default=[c.name for c in CONFIGS])
    parser.add_argument("--out", type=Path, default=Path("results/reference"))
    args = parser.parse_args(argv)
    with user_errors():
        runs = pd.read_csv(REFERENCE / "runs.csv")
        found = json.loads((REFERENCE / "headline.json").read_text())
        oracle = Oracle(runs)
        reference = {rule: cells(runs, rule) for rule in RULES}
        report: dict[str, Any] = {
            "reference_headline": {r: found[r]["smallest_all_width_pinch_dsr"] for r in RULES}
        }
        for config in (c for c in CONFIGS if c.name in args.configs):
            rows = [replay(oracle, config, seed, reference) for seed in range(args.seeds)]
            report[config.name] = {
                "settings": asdict(config.settings),
                "follow": list(config.follow),
                **summary(rows, found),
                "seeds": [asdict(r) for r in rows],
            }
            echo([f"{config.name}: {json.dumps(summary(rows, found))}"])
        written = write_outputs([(args.out / "active_sampling.json", json.dumps(report, indent=1) + "\n")])
        echo(f"wrote {p}" for p in written)


if __name__ == "__main__":
    main()
