"""Paper Fig. 7: a continuum arm wraps a ball, lifts it and drops it through a hoop.

``somo-sweep paper fig7 --out results/figures [--quick]`` runs task ``whole_arm``
once with a camera and writes ``fig7.png`` (frames a–h plus the ball's height and
distance from the hoop axis against time), the frames as ``fig7_frames/fig7_<a-h>.png``,
``fig7.json`` (outcome numbers) and an animated ``fig7.gif``. The full variant also
reruns the physics at half the time step and records both outcomes. ``--quick``
renders smaller frames, no GIF and no half-step rerun; the physics is the same.
"""

from __future__ import annotations

import math
import string
from time import perf_counter

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes

from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.paper.artifacts import Artifacts
from somo_sweep.sim.render import Camera
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.tasks.whole_arm.params import WholeArmParams
from somo_sweep.tasks.whole_arm.task import WholeArmRun, simulate_whole_arm

__all__ = ["FRAME_TIMES_S", "build", "draw_ball_trace", "outcome"]

MODEL = bundled_path("models", "whole_arm.yaml")
#: Times of panels a–h, s: start, wrapping, wrapped, lifting, over the hoop, opening, through, landed.
FRAME_TIMES_S = (0.0, 1.4, 2.5, 3.8, 6.0, 6.45, 6.65, 8.5)
GIF_EVERY_S = 0.1
TIME_STEP_S = 1e-3


def _camera(width_px: int, height_px: int) -> Camera:
    return Camera(
        target_m=(-0.15, 0.0, 0.55),
        distance_m=1.45,
        yaw_deg=0.0,
        pitch_deg=-8.0,
        fov_deg=45.0,
        width_px=width_px,
        height_px=height_px,
    )


def outcome(run: WholeArmRun) -> dict[str, float | bool | None]:
    """The numbers of one run (JSON-ready: no crossing gives ``None``)."""
    hit = run.crossing()
    return {
        "ball_passed_hoop": run.passed(),
        "ball_max_lift_m": run.max_lift_m(),
        "hoop_crossing_time_s": hit[0] if hit else None,
        "hoop_crossing_offset_m": hit[1] if hit else None,
        "hoop_allowed_offset_m": run.allowed_offset_m,
        "ball_touched_rim": bool(run.rim_contact.any()),
    }


def draw_ball_trace(ax: Axes, run: WholeArmRun) -> None:
    """Draw the ball's height (m) and horizontal distance from the hoop axis (m) against time on ``ax``."""
    pos = run.ball_position_m
    ax.plot(run.times_s, pos[:, 2], color="tab:orange", label="ball height")
    offset = np.linalg.norm(pos[:, :2] - run.hoop_centre_m[:2], axis=1)
    ax.plot(run.times_s, offset, color="tab:blue", label="distance from hoop axis")
    ax.axhline(run.hoop_centre_m[2], color="tab:red", ls="--", lw=1, label="hoop plane")
    ax.axhline(run.allowed_offset_m, color="tab:blue", ls=":", lw=1, label="fits through the hoop")
    hit = run.crossing()
    if hit:
        ax.plot([hit[0]], [run.hoop_centre_m[2]], "kx")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("m")
    ax.legend(fontsize=7, loc="upper left")


def build(quick: bool = False) -> Artifacts:
    """Run the task with a camera: the figure, its frames, the numbers, and (unless ``quick``) a GIF.

    ``quick`` renders smaller frames, no GIF and no half-step rerun; the physics is the same.
    """
    model, params = load_model(MODEL), WholeArmParams()
    size = (240, 200) if quick else (480, 400)
    gif_times = [] if quick else [i * GIF_EVERY_S for i in range(round(FRAME_TIMES_S[-1] / GIF_EVERY_S) + 1)]
    times = [*FRAME_TIMES_S, *gif_times]
    start = perf_counter()
    run, images = simulate_whole_arm(
        model,
        params,
        WorldSettings(time_step_s=TIME_STEP_S),
        camera=_camera(*size),
        frame_times_s=tuple(times),
    )
    wall_s = perf_counter() - start
    # Frames come back in time order; map them back to the requested times.
    steps = sorted({round(t / TIME_STEP_S) for t in times})
    by_step = dict(zip(steps, images, strict=True))
    panels = [by_step[round(t / TIME_STEP_S)] for t in FRAME_TIMES_S]

    name = "fig7-quick" if quick else "fig7"
    out = Artifacts(formats=("png",), dpi=100)
    fig, axes = plt.subplots(3, 3, figsize=(12, 10.5))
    for ax, image, t, letter in zip(axes.flat, panels, FRAME_TIMES_S, string.ascii_lowercase, strict=False):
        ax.imshow(image)
        ax.set_title(f"{letter}) t = {t:.2f} s", fontsize=10)
        ax.axis("off")
        out.images[f"{name}_frames/{name}_{letter}.png"] = image
    draw_ball_trace(axes.flat[-1], run)
    summary: dict[str, object] = {"time_step_s": TIME_STEP_S, **outcome(run), "wall_time_s": wall_s}
    verdict = "through the hoop" if run.passed() else "missed the hoop"
    fig.suptitle(
        f"Whole-arm manipulation (paper Fig. 7): ball {verdict}, lifted {run.max_lift_m() * 1e3:.0f} mm"
    )
    fig.tight_layout()
    out.figures[name] = fig
    if not quick:
        out.animations[f"{name}.gif"] = [
            by_step[s] for s in sorted({round(t / TIME_STEP_S) for t in gif_times})
        ]
        half, _ = simulate_whole_arm(model, params, WorldSettings(time_step_s=TIME_STEP_S / 2))
        summary["half_time_step"] = {"time_step_s": TIME_STEP_S / 2, **outcome(half)}
    out.json[f"{name}.json"] = summary
    hit = run.crossing()
    offset_mm = hit[1] * 1e3 if hit else math.nan
    out.lines.append(
        f"ball {verdict}: lifted {run.max_lift_m() * 1e3:.0f} mm, crossed the hoop plane "
        f"{offset_mm:.1f} mm from its axis (allowed {run.allowed_offset_m * 1e3:.0f} mm); {wall_s:.1f} s wall"
    )
    return out
