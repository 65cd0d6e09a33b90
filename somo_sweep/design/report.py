"""What a design search returns, as data: its summary, the Pareto front, each finalist's label map,
and a plain grid study of the best design. Nothing here writes a file (the command line does).

A finalist is one of the best complete designs (``design.search.finalists``). Its label map is the
sweep's own (:func:`~somo_sweep.sweep.views.label_maps.label_map_figure`) over the objects: each cell
coloured by its majority label, hatched where its replicas disagree. The best design's study runs
the design's values as one-value sweep axes with the objects: the trials the search ran (same ids
and seeds), every cell with its replicas (``robustness: {where: all}``), so that rerunning it gives
the share the ranking gives.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd
import yaml

from somo_sweep.design.ranking import Z_95, trade_column
from somo_sweep.design.study import DesignStudy
from somo_sweep.design.variables import as_asked
from somo_sweep.sweep.jobs.job import param_column
from somo_sweep.sweep.run.robustness import fold
from somo_sweep.sweep.views.label_maps import folded_cells, label_map_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["best_study_text", "finalists", "label_map", "pareto_figure", "summary"]


def finalists(ranking: pd.DataFrame, study: DesignStudy) -> pd.DataFrame:
    """The best complete designs (at most ``study.finalists``), best first."""
    return ranking[ranking["complete"].astype(bool)].head(study.finalists)


def _described(row: Any, study: DesignStudy) -> str:
    parts = [f"{k.rsplit('.', 1)[-1]} {_short(row[k])}" for k in study.keys]
    return ", ".join(parts)


def _short(value: Any) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def summary(ranking: pd.DataFrame, study: DesignStudy, record: dict[str, Any]) -> dict[str, Any]:
    """The search in numbers: the best design, the designs judged, the simulations spent."""
    best = finalists(ranking, study).head(1)
    out: dict[str, Any] = {
        "study": study.base.name,
        "objective": f"robust {study.objective.label} = {study.objective.value}",
        "objects": study.n_objects,
        "replicas": study.replicas,
        "budget": study.budget,
        "simulations": int(ranking["simulations"].sum()) if len(ranking) else 0,
        "designs": len(ranking),
        "complete_designs": int(ranking["complete"].sum()) if len(ranking) else 0,
        "search": record,
        "interval": f"Wilson score, {Z_95:.2f} sigma (95 %), over the objects",
    }
    if len(best):
        row = best.iloc[0]
        out["best"] = {
            "design": int(row["design"]),
            "values": {k: _json(row[k]) for k in study.keys},
            "robust_objects": int(row["robust_objects"]),
            "robust_share": float(row["robust_share"]),
            "share_95": [float(row["share_low_95"]), float(row["share_high_95"])],
            "simulations": int(row["simulations"]),
        }
    return out


def _json(value: Any) -> Any:
    return value.item() if hasattr(value, "item") else value


def label_map(table: pd.DataFrame, row: Any, study: DesignStudy) -> Figure:
    """A finalist's label map over the objects (non-robust cells hatched)."""
    n = study.n_objects
    label = f"label_{study.objective.label}"
    mine = table[pd.to_numeric(table["trial"]) // n == int(row["design"])]
    folded = fold(mine, labels=[label], planned=study.replicas)
    cells = folded_cells(folded, label)
    axes = [param_column(k) for k in study.objects]
    short = {param_column(k): k.rsplit(".", 1)[-1] for k in study.objects}
    values = "\n".join(f"{k.rsplit('.', 1)[-1]} {_short(row[k])}" for k in study.keys)
    robust = f"{int(row['robust_objects'])}/{n} robust {study.objective.value}"
    title = f"design {int(row['design'])}: {robust}\n{values}\n"
    return label_map_figure(cells, label, axes, short, title)


def pareto_figure(ranking: pd.DataFrame, study: DesignStudy) -> Figure:
    """The complete designs' robust share against the trade-off, the Pareto front joined."""
    import matplotlib.pyplot as plt

    trade = study.trade_off
    assert trade is not None
    name = trade_column(study)
    done = ranking[ranking["complete"].astype(bool)]
    fig, ax = plt.subplots(figsize=(5.5, 4.2), layout="constrained")
    values = pd.to_numeric(done[name], errors="coerce")
    ax.scatter(values, done["robust_share"], s=18, color="0.6", label="complete designs")
    front = done[done["pareto"].astype(bool)].assign(x=values).sort_values("x")
    ax.plot(front["x"], front["robust_share"], "o-", color="C3", label="Pareto front")
    for _, row in front.iterrows():
        ax.annotate(str(int(row["design"])), (row["x"], row["robust_share"]), fontsize="x-small")
    ax.set_xlabel(f"{name} ({trade.direction})")
    ax.set_ylabel(f"robust share: {study.objective.label} = {study.objective.value}")
    ax.set_ylim(-0.03, 1.03)
    ax.legend(fontsize="small")
    ax.set_title(f"{study.base.name}: {len(done)} complete designs", fontsize="small")
    return fig


def best_study_text(row: Any, study: DesignStudy, folder: Path) -> str:
    """A plain grid study of one design (``row`` of the ranking), to be written into ``folder``."""
    base = study.base
    model = os.path.relpath(Path(base.model_path).resolve(), folder.resolve())
    data: dict[str, Any] = {
        "name": f"{base.name}_best"[:100],
        "task": base.task.name,
        "model": model,
        "params": base.params,
    }
    if base.fixed:
        data["set"] = base.fixed
    data["sweep"] = {
        **{k: [as_asked(study.variable(k), _json(row[k]))] for k in study.keys},
        **{a.key: list(a.values) for a in base.axes},
    }
    data["seed"] = base.seed
    data["robustness"] = {"replicas": study.replicas, "where": "all", "labels": [study.objective.label]}
    if base.simulation is not None:
        data["simulation"] = base.simulation.model_dump(mode="json", exclude_defaults=True) or {
            "engine": base.simulation.engine
        }
    header = (
        f"# somo-sweep design: the best design of {base.name} ({int(row['robust_objects'])} of "
        f"{study.n_objects} objects robustly {study.objective.label} = {study.objective.value}).\n"
        "# The design's values are one-value sweep axes, so that each trial is the one the search ran\n"
        "# (same ids and seeds). Rerun it with: somo-sweep run THIS_FILE\n"
    )
    return header + yaml.safe_dump(data, sort_keys=False, allow_unicode=True)
