"""Presenting a diagnosis: Markdown report, terminal verdict, and a plot helper drawing on a given ``ax``."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes

from somo_sweep.calibration.metrics import ANGLE, ANGLE_LABEL, measured_array, row_labels
from somo_sweep.diagnosis.effects import EFFECTS
from somo_sweep.diagnosis.result import DiagnosisResult

__all__ = ["plot_diagnosis", "report_markdown", "test_labels", "verdict_lines"]


def test_labels(result: DiagnosisResult) -> list[str]:
    """Test labels of the rows, first-seen order, plus ``free_bending.tip_angle`` when measured."""
    labels = list(dict.fromkeys(row_labels(result.problem.rows)))
    if "free_bending" in labels and not np.isnan(result.problem.measured[:, ANGLE]).all():
        labels.insert(labels.index("free_bending") + 1, ANGLE_LABEL)
    return labels


def _value(value: float, stderr: float | None) -> str:
    """``value`` (4 significant digits), ``± stderr`` when known."""
    if stderr is None:
        return f"{value:.4g}"
    return f"{value:.4g} ± {stderr:.2g}"


def verdict_lines(result: DiagnosisResult) -> list[str]:
    """The short verdict printed by the CLI."""
    lines = [f"missing effect: {result.missing_effect} ({result.verdict})"]
    if result.best_candidate != "none":
        for name in result.best_candidate.split("+"):
            lines.append(f"  {EFFECTS[name].summary}")
        fit = result.candidate(result.best_candidate)
        held = (
            "  fitted" if result.missing_effect != "unexplained" else "  best attempt (in the written model)"
        )
        errors = result.stderr(fit)
        values = result.parameters(fit).items()
        lines.append(f"{held}: " + ", ".join(f"{k} = {_value(v, errors.get(k))}" for k, v in values))
        lines += [f"  {line}" for line in result.describe_effects(fit)]
    lines.append(
        f"combined noise-normalised score: before {result.combined_before:.2f}, "
        f"after {result.combined_after:.2f}"
    )
    return lines


def report_markdown(result: DiagnosisResult, source: str) -> str:
    """``report.md``: verdict, disagreements, candidates, RMSE before/after per test."""
    before = {m.label: m for m in result.metrics(result.problem.before)}
    after = {m.label: m for m in result.metrics(result.after)}
    none_bic = result.candidate("none").bic
    out = [
        "<!-- written by somo-sweep diagnose -->",
        f"# Diagnosis of {source}",
        "",
        "\n".join(f"**{ln.strip()}**  " for ln in verdict_lines(result)),
        "",
    ]
    out += ["## Where the model as given disagrees", ""]
    out += [f"- {d.describe()}" for d in result.problem.disagreements] or ["- nothing beyond the noise"]
    out += [
        "",
        "Noise per channel (from the residuals of the diagnosed model; σ at the RMS reading): "
        + ", ".join(f"{k} {v.sigma:.3g} ({v.model}, {v.method})" for k, v in result.noise.items()),
    ]
    out += ["", "## Candidates (BIC = Σ_c n_c·ln(RSS_c/n_c) + k·ln n, best first)", ""]
    out += ["| candidate | χ² | BIC | ΔBIC vs none | refined | parameters |", "|---|---|---|---|---|---|"]
    for c in result.candidates:
        errors = result.stderr(c)
        pars = ", ".join(f"{k} = {_value(v, errors.get(k))}" for k, v in result.parameters(c).items())
        out.append(
            f"| {c.name} | {c.chi2:.1f} | {c.bic:.1f} | {c.bic - none_bic:+.1f} | "
            f"{'simulated' if c.refined else 'linear prediction'} | {pars} |"
        )
    out += [
        "",
        "## Gap before and after",
        "",
        "| test | RMSE before | RMSE after | unit |",
        "|---|---|---|---|",
    ]
    for label, m in before.items():
        out.append(f"| {label} | {m.rmse:.4g} | {after[label].rmse:.4g} | {m.unit} |")
    out.append(
        f"| combined (noise-normalised) | {result.combined_before:.3f} | {result.combined_after:.3f} | 1 |"
    )
    out += ["", f"{result.simulations} bench simulations in {result.wall_time_s:.0f} s.", ""]
    return "\n".join(out)


def plot_diagnosis(ax: Axes, result: DiagnosisResult, label: str) -> None:
    """Measured (markers), before (dashed) and after (solid) for one test label, on ``ax``.

    Free bending is drawn as tip z against pressure (the x–z path hides errors along it),
    ``free_bending.tip_angle`` as tip angle against pressure.
    """
    rows = result.problem.rows
    angle = label == ANGLE_LABEL
    sel = np.array(row_labels(rows)) == ("free_bending" if angle else label)
    if angle:
        sel &= ~np.isnan(result.problem.measured[:, ANGLE])
    sub = rows[sel]
    measured = measured_array(rows)[sel]
    directions = sub["direction"].to_numpy() if "direction" in sub.columns else np.full(len(sub), "")
    free = label.startswith("free_bending")
    column = ANGLE if angle else 1 if free else 0
    for direction in dict.fromkeys(directions):
        d = directions == direction
        tag = f" ({direction})" if direction else ""
        key = sub["pressure_kpa" if free or not label.startswith("tip_load") else "tip_load_n"].to_numpy(
            float
        )
        order = np.argsort(key[d], kind="stable")
        curves = {
            "measured": measured[d],
            "before": result.problem.before[sel][d],
            "after": result.after[sel][d],
        }
        for name, style in (("measured", "o"), ("before", "--"), ("after", "-")):
            y = curves[name][order]
            ax.plot(key[d][order], y[:, column], style, label=name + tag)
    if angle:
        ax.set_xlabel("pressure (kPa)")
        ax.set_ylabel("tip angle (deg)")
    elif free:
        ax.set_xlabel("pressure (kPa)")
        ax.set_ylabel("tip z (mm)")
    elif label.startswith("tip_load"):
        ax.set_xlabel("tip load (N)")
        ax.set_ylabel("tip deflection (mm)")
    else:
        ax.set_xlabel("pressure (kPa)")
        ax.set_ylabel("blocked force (N)")
    ax.set_title(label)
    ax.legend(fontsize="small")
