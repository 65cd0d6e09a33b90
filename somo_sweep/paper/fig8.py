"""Paper Fig. 8: snake poses over time with isotropic and anisotropic friction.

``somo-sweep paper fig8 --out results/figures [--quick]`` runs both variants of
task ``snake`` and draws the body poses (grey), the start pose (black, dotted) and
the path of the body's centre, one panel per friction mode, as PNG and SVG.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
from matplotlib.axes import Axes

from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.paper.artifacts import Artifacts
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.tasks.snake.params import SnakeParams
from somo_sweep.tasks.snake.task import SnakeRun, simulate_snake

__all__ = ["draw_snake_panel", "run_both"]

MODEL = bundled_path("models", "snake.yaml")


def draw_snake_panel(ax: Axes, run: SnakeRun, title: str, n_poses: int = 6) -> None:
    """Draw one run's poses (mm) on ``ax``: start dotted, later poses grey, centre path coloured."""
    xy = run.links_xy_m * 1e3
    picks = sorted({round(i * (len(xy) - 1) / (n_poses - 1)) for i in range(n_poses)})
    for i in picks[1:]:
        shade = 0.75 - 0.5 * i / (len(xy) - 1)
        ax.plot(xy[i, :, 0], xy[i, :, 1], color=str(shade), lw=2)
    ax.plot(xy[0, :, 0], xy[0, :, 1], "k:", lw=2, label="start")
    com = run.com_xy_m * 1e3
    ax.plot(com[:, 0], com[:, 1], color="tab:red", lw=1, label="centre path")
    ax.set_title(f"{title}: advanced {run.advance_m() * 1e3:.0f} mm in {run.times_s[-1]:.0f} s")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="upper right", fontsize=8)


def run_both(duration_s: float, time_step_s: float = 1e-3) -> dict[str, SnakeRun]:
    """Run the snake with isotropic and with anisotropic friction."""
    model = load_model(MODEL)
    settings = WorldSettings(time_step_s=time_step_s)
    return {
        mode: simulate_snake(model, SnakeParams(friction=mode, duration_s=duration_s), settings)
        for mode in ("isotropic", "anisotropic")
    }


def build(quick: bool = False) -> Artifacts:
    """Both snakes (3 s each when ``quick``, else 10 s): the figure and the advance per friction."""
    runs = run_both(3.0 if quick else 10.0)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for ax, (mode, run) in zip(axes, runs.items(), strict=True):
        draw_snake_panel(ax, run, mode)
    fig.tight_layout()
    name = "fig8-quick" if quick else "fig8"
    summary = {
        mode: {
            "advance_mm": run.advance_m() * 1e3,
            "sideways_mm": run.sideways_m() * 1e3,
            "advance_body_widths": run.advance_m() / run.width_m,
            "duration_s": float(run.times_s[-1]),
        }
        for mode, run in runs.items()
    }
    lines = [
        f"{mode:12s} advanced {s['advance_mm']:7.1f} mm ({s['advance_body_widths']:.1f} body widths), "
        f"sideways {s['sideways_mm']:.1f} mm in {s['duration_s']:.0f} s"
        for mode, s in summary.items()
    ]
    return Artifacts(figures={name: fig}, json={f"{name}.json": summary}, lines=lines)
