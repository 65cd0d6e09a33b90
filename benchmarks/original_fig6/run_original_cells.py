"""Run the original SoMo pinch-grasp trial (paper Fig. 6) on chosen grid cells, with its own code.

This script contains none of the original's code. It runs in the original's own virtual
environment (see README.md beside it), imports the original from the checkout the user names
(``--somo``), applies four compatibility patches *in its own process* (nothing in the checkout is
changed), and for each cell

1. writes a run configuration: the original's ``sweeps/grid_dsr.yaml`` as read from the checkout,
   with the cell's distal segment ratio, object file and hand offset filled in, headless;
2. calls the original's ``run_single`` on it (its own loop, 0.5 ms, 8000 steps);
3. labels the trial with the original's own ``labels/label_functions.py`` (``height_check``,
   ``bounding_box``, ``mean_link``) read from the logs the trial wrote, positions in metres as the
   original's ``DataLabeler`` gives them, and the decision of the notebook's all-in-one DSR figure
   (``plot_dsr.ipynb``): grasped if both checks pass, then pinch if ``mean_link / 20 > 1 - DSR``,
   else power (a grasped trial without a final-step contact has ``mean_link`` NaN and is power).

Cells are given as (DSR, object width in mm, centering position c in mm); the original's hand
offset is ``h = (100 - c) / 50`` scaled units (c = 100 - 50 h mm). Results are appended to a CSV,
one row per cell; cells already in it are skipped, so an interrupted run resumes.

Patches (compatibility only, no physics):
  * ``numpy.float``: removed from numpy >= 1.24; set to ``float``.
  * ``yaml.load``: PyYAML 6 requires a ``Loader``; ``FullLoader`` is supplied when none is given.
  * The actuator-length assert ``n_segments * link_height == actuator_length`` in
    ``somo/sm_actuator_definition.py`` fails on float round-off for 10 of the 15 DSR values; the
    constructor is wrapped so that a length within 1e-9 (relative) of ``n_segments * link_height`` is
    passed as that product. Anything further off still fails as before.
  * pandas < 3 must be installed (the label functions OR a list with a Series); checked at start.

Restitution: ``run_single`` sets 1.0 on the object and the configuration's value on the finger
links. ``--restitution R`` (default 0) replaces every restitution passed to ``changeDynamics`` by R
(object and finger links); ``--restitution original`` leaves them as committed.

``--trace`` records, every 10 ms, the hand's target, the finger bases' positions, the object's
pose, the finger joint angles and the finger-object contact forces, by wrapping
``pybullet.stepSimulation`` in this process (the original's loop is not changed).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import random
import shutil
import signal
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

DSR_VALUES = [round(0.05 * k, 2) for k in range(15)]
WIDTHS_MM = [10, 20, 40, 60, 80, 100, 120]
CENTERINGS_MM = [70 + 5 * k for k in range(22)]
HEADLINE = [(d, w, c) for d in (0.0, 0.1, 0.2) for w in (10, 120) for c in (70, 75, 80, 85, 90)]
REGION = Path("examples/design_studies/region_of_acquisition")
FIELDS = [
    "dsr",
    "width_mm",
    "c_mm",
    "hand_x_units",
    "restitution",
    "orig_label",
    "orig_mean_link",
    "orig_height_check",
    "orig_bounding_box",
    "orig_x_m",
    "orig_y_m",
    "orig_z_m",
    "orig_final_contacts",
    "orig_final_step",
    "wall_s",
    "time_step_s",
]


def patch_environment(somo_root: Path) -> None:
    """The four compatibility patches (module docstring), applied to this process only."""
    import numpy as np
    import pandas as pd
    import yaml

    if int(pd.__version__.split(".")[0]) >= 3:
        sys.exit(f"pandas {pd.__version__} found; the original's label functions need pandas < 3")
    np.float = float  # type: ignore[attr-defined]
    yaml_load = yaml.load

    def load(stream, Loader=None, **kw):
        return yaml_load(stream, Loader=Loader or yaml.FullLoader, **kw)

    yaml.load = load
    sys.path.insert(0, str(somo_root))
    from somo import sm_actuator_definition as sad
    from somo.sm_link_definition import SMLinkDefinition

    init = sad.SMActuatorDefinition.__init__

    def tolerant_init(self, actuator_length, n_segments, link_definition, *args, **kwargs):
        link = SMLinkDefinition(**link_definition) if isinstance(link_definition, dict) else link_definition
        exact = n_segments * link.height
        if math.isclose(exact, actuator_length, rel_tol=1e-9, abs_tol=1e-12):
            actuator_length = exact
        init(self, actuator_length, n_segments, link_definition, *args, **kwargs)

    sad.SMActuatorDefinition.__init__ = tolerant_init


def patch_restitution(value: float | None) -> None:
    """Replace every restitution given to ``changeDynamics`` by ``value`` (None: leave them)."""
    if value is None:
        return
    import pybullet as p

    change = p.changeDynamics

    def change_dynamics(*args, **kwargs):
        if "restitution" in kwargs:
            kwargs["restitution"] = value
        return change(*args, **kwargs)

    p.changeDynamics = change_dynamics


def patch_body_damping(value: float | None) -> None:
    """Give every body ``loadURDF`` loads the linear and angular damping ``value`` (None: leave
    PyBullet's default, 0.04, as the original does). An experiment: how much the original's labels
    move with a setting that only adds a small drag."""
    if value is None:
        return
    import pybullet as p

    load = p.loadURDF

    def load_urdf(*args, **kwargs):
        body = load(*args, **kwargs)
        client = {"physicsClientId": kwargs["physicsClientId"]} if "physicsClientId" in kwargs else {}
        p.changeDynamics(body, -1, linearDamping=value, angularDamping=value, **client)
        return body

    p.loadURDF = load_urdf


class Tracer:
    """Samples the state every ``every`` steps by wrapping ``pybullet.stepSimulation``.

    ``inspect_steps``: step counts (0: before the first step) at which every body's links are
    dumped in full (mass, inertia, friction, collision shapes, poses, constraints) into ``dumps``.
    """

    def __init__(self, every: int, scale: float, inspect_steps: tuple[int, ...] = ()):
        import pybullet as p

        self.p, self.every, self.scale, self.n = p, every, scale, 0
        self.rows: list[dict[str, Any]] = []
        self.inspect_steps = set(inspect_steps)
        self.dumps: list[dict[str, Any]] = []
        self.step = p.stepSimulation
        p.stepSimulation = self.__call__

    def __call__(self, *args, **kwargs):
        if self.n in self.inspect_steps:
            self.dumps.append(self.dump())
        out = self.step(*args, **kwargs)
        self.n += 1
        if self.n % self.every == 0:
            self.sample()
        return out

    def dump(self) -> dict[str, object]:
        """Every body's links and every constraint, in the scaled world's units as Bullet reports them."""
        p = self.p
        bodies = []
        for b in range(p.getNumBodies()):
            links = []
            for li in range(-1, p.getNumJoints(b)):
                d = p.getDynamicsInfo(b, li)
                if li < 0:
                    pos, orn = p.getBasePositionAndOrientation(b)
                    frame = pos
                    joint = None
                else:
                    st = p.getLinkState(b, li, computeForwardKinematics=1)
                    pos, orn, frame = st[0], st[1], st[4]
                    ji = p.getJointInfo(b, li)
                    joint = {
                        "name": ji[1].decode(),
                        "type": ji[2],
                        "axis": ji[13],
                        "parent_pos": ji[14],
                        "q": p.getJointState(b, li)[0],
                        "damping": ji[6],
                        "friction": ji[7],
                    }
                links.append(
                    {
                        "index": li,
                        "com": pos,
                        "orn": orn,
                        "frame": frame,
                        "mass": d[0],
                        "lateral": d[1],
                        "inertia": d[2],
                        "inertial_pos": d[3],
                        "restitution": d[5],
                        "rolling": d[6],
                        "spinning": d[7],
                        "margin": d[11] if len(d) > 11 else None,
                        "joint": joint,
                        "shapes": [list(s[2:7]) for s in p.getCollisionShapeData(b, li)],
                    }
                )
            bodies.append({"id": b, "name": p.getBodyInfo(b)[1].decode(), "links": links})
        cons = [list(p.getConstraintInfo(p.getConstraintUniqueId(i))) for i in range(p.getNumConstraints())]
        return {
            "step": self.n,
            "bodies": bodies,
            "constraints": cons,
            "engine": {k: v for k, v in p.getPhysicsEngineParameters().items()},
        }

    def sample(self) -> None:
        p, s = self.p, self.scale
        # run_single loads the plane (0), the two fingers (1, 2), then the object (3).
        row: dict[str, object] = {"t_s": self.n * self.dt}
        pos, orn = p.getBasePositionAndOrientation(3)
        rpy = p.getEulerFromQuaternion(orn)
        row.update({f"obj_{a}_m": v / s for a, v in zip("xyz", pos, strict=True)})
        row.update({f"obj_{a}_rad": v for a, v in zip(("roll", "pitch", "yaw"), rpy, strict=True)})
        for f in (1, 2):
            bpos, _ = p.getBasePositionAndOrientation(f)
            row.update({f"f{f}_base_{a}_m": v / s for a, v in zip("xyz", bpos, strict=True)})
            n = p.getNumJoints(f)
            q = [st[0] for st in p.getJointStates(f, list(range(n)))]
            for j in range(n):
                row[f"f{f}_q{j:02d}_rad"] = q[j]
            cps = p.getContactPoints(f, 3)
            row[f"f{f}_obj_contacts"] = len(cps)
            row[f"f{f}_obj_points"] = [(c[3], *(v / s for v in c[5]), *c[7], c[8] / s, c[9] / s) for c in cps]
            row[f"f{f}_obj_force_n"] = sum(c[9] for c in cps) / s
            row[f"f{f}_obj_mean_link"] = (sum(c[3] for c in cps) / len(cps) + 1) if cps else float("nan")
        row["obj_ground_contacts"] = len(p.getContactPoints(3, 0))
        self.rows.append(row)

    dt = 0.0005


def cell_config(
    region: Path, dsr: float, width_mm: int, c_mm: float, work: Path, time_step_s: float | None = None
) -> tuple[Path, float]:
    """The original's sweep file with one cell's values filled in, headless, saved in ``work``.

    ``time_step_s`` replaces the sweep file's ``simulation.time_step`` (0.5 ms); ``run_single``
    takes its step count from it (4 s of simulated time either way)."""
    import yaml

    with open(region / "sweeps" / "grid_dsr.yaml") as f:
        cfg = yaml.safe_load(f)
    cfg.pop("sweep")
    h = (100.0 - c_mm) / 50.0
    cfg["manipulator"]["fingers"]["distal_seg_ratio"] = dsr
    cfg["manipulator"]["fingers"]["file"] = str(region / cfg["manipulator"]["fingers"]["file"])
    cfg["manipulator"]["hand"]["position"][0] = h
    for part in ("fingers", "hand"):
        cfg["manipulator"]["motion"][part]["file"] = str(region / cfg["manipulator"]["motion"][part]["file"])
    cfg["object"]["file"] = str(region / f"objects/object_set/cube_60mm/CubeLifeSize_v2_60_{width_mm}.urdf")
    cfg["simulation"]["gui"] = False
    cfg["simulation"]["video"] = False
    if time_step_s is not None:
        cfg["simulation"]["time_step"] = time_step_s
    cfg["save"] = {"group_name": "cells", "run_name": f"dsr{dsr:.2f}_w{width_mm}_c{c_mm:g}"}
    path = work / "cell.yaml"
    with open(path, "w") as f:
        yaml.safe_dump(cfg, f)
    return path, h


def label_cell(region: Path, run_folder: Path, dsr: float, scale: float) -> dict[str, object]:
    """The original's labels of one finished trial (module docstring, point 3)."""
    sys.path.insert(0, str(region / "labels"))
    import label_functions as lf
    from somo.sweep import iter_utils

    pose = iter_utils.read_parse_data(str(run_folder / "object_pose.dat")).make_dataframe(
        ["timeStamp", "objectId", "posX", "posY", "posZ", "oriX", "oriY", "oriZ", "oriW"]
    )
    for a in ("posX", "posY", "posZ"):
        pose[a] = pose[a] / scale
    contact = iter_utils.read_parse_data(str(run_folder / "contact.dat")).make_dataframe(
        ["timeStamp", "stepCount", "bodyUniqueIdA", "bodyUniqueIdB", "linkIndexA", "linkIndexB"]
    )
    height = lf.height_check(pose)
    box = lf.bounding_box(pose)
    mean_link = lf.mean_link(contact)
    mean = float("nan") if mean_link is None else float(mean_link)
    last = contact["stepCount"].iloc[-1]
    final = contact[contact.stepCount == last]
    fingers = final.bodyUniqueIdA.isin([1, 2]) & (final.bodyUniqueIdB == 3)
    fingers |= final.bodyUniqueIdB.isin([1, 2]) & (final.bodyUniqueIdA == 3)
    # The notebook's decision: NaN / 20 > x is False, so no final contact gives power.
    pinch = "pinch" if mean / 20 > (1.0 - dsr) else "power"
    label = pinch if height == 1 and box == 1 else "no_grasp"
    end = pose.iloc[-1]
    return {
        "orig_label": label,
        "orig_mean_link": mean,
        "orig_height_check": height,
        "orig_bounding_box": box,
        "orig_x_m": float(end["posX"]),
        "orig_y_m": float(end["posY"]),
        "orig_z_m": float(end["posZ"]),
        "orig_final_contacts": int(fingers.sum()),
        "orig_final_step": int(last),
    }


def choose_cells(args: argparse.Namespace) -> list[tuple[float, int, float]]:
    cells: list[tuple[float, int, float]] = []
    if args.headline:
        cells += HEADLINE
    if args.sample:
        grid = [(d, w, c) for d in DSR_VALUES for w in WIDTHS_MM for c in CENTERINGS_MM]
        cells += random.Random(args.seed).sample(grid, args.sample)
    for spec in args.cell or []:
        d, w, c = spec.split(",")
        cells.append((round(float(d), 2), int(w), float(c)))
    return list(dict.fromkeys(cells))  # each cell once, in the order given


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.original_fig6.run_original_cells", description=__doc__.split("\n\n")[0]
    )
    ap.add_argument("--somo", type=Path, required=True, help="checkout of GrauleM/somo (commit 755978b)")
    ap.add_argument("--out", type=Path, required=True, help="CSV to append one row per cell to")
    ap.add_argument("--headline", action="store_true", help="the 30 headline cells")
    ap.add_argument("--sample", type=int, default=0, help="N cells drawn at random from the 2310-cell grid")
    ap.add_argument("--seed", type=int, default=30, help="seed of --sample")
    ap.add_argument("--cell", action="append", help="one cell 'DSR,width_mm,c_mm' (repeatable)")
    ap.add_argument("--restitution", default="0", help="restitution of object and fingers, or 'original'")
    ap.add_argument("--trace", type=Path, help="write a 10-ms trace (JSON lines) of each cell here")
    ap.add_argument("--trace-every", type=int, default=20, help="steps between --trace samples (20: 10 ms)")
    ap.add_argument(
        "--inspect", type=Path, help="write full dumps of every body (JSON) at --inspect-steps here"
    )
    ap.add_argument("--inspect-steps", default="0,1999,3999,5999,7999", help="step counts of --inspect")
    ap.add_argument(
        "--time-step",
        type=float,
        help="the original's time step in s (default: its sweep file's 0.0005); the trial stays 4 s long",
    )
    ap.add_argument(
        "--body-damping",
        type=float,
        help="every body's linear and angular damping (default: PyBullet's 0.04, as the original)",
    )
    ap.add_argument("--list", action="store_true", help="print the cells and stop")
    args = ap.parse_args(argv)
    cells = choose_cells(args)
    if args.list:
        for c in cells:
            print(*c, sep=",")
        return
    somo = args.somo.resolve()
    region = somo / REGION
    if not (region / "run_single.py").is_file():
        sys.exit(f"{region / 'run_single.py'} not found: --somo must be a checkout of GrauleM/somo")
    restitution = None if args.restitution == "original" else float(args.restitution)
    out = args.out.resolve()
    args.trace = args.trace.resolve() if args.trace else None
    args.inspect = args.inspect.resolve() if args.inspect else None
    done: set[tuple[float, int, float]] = set()
    if out.exists():
        with open(out) as f:
            for r in csv.DictReader(f):
                done.add((round(float(r["dsr"]), 2), int(r["width_mm"]), float(r["c_mm"])))
    todo = [c for c in cells if c not in done]
    print(f"{len(cells)} cells, {len(done & set(cells))} already in {out}, {len(todo)} to run", flush=True)
    patch_environment(somo)
    patch_restitution(restitution)
    patch_body_damping(args.body_damping)
    work = Path(tempfile.mkdtemp(prefix="somo_orig_"))
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # a killed run still removes `work`
    try:
        run_cells(args, todo, region, work, restitution, out)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def run_cells(
    args: argparse.Namespace,
    todo: list[tuple[float, int, float]],
    region: Path,
    work: Path,
    restitution: float | None,
    out: Path,
) -> None:
    """Run ``todo`` in the scratch folder ``work`` (the original writes its logs and URDFs there)."""
    import yaml

    os.chdir(work)
    # run_single loads "objects/plane/plane.urdf" relative to the working folder.
    (work / "objects").symlink_to(region / "objects")
    with open("save_paths.yaml", "w") as f:
        yaml.safe_dump({"save_path": str(work / "data"), "data": _DATA_FILES}, f)
    sys.path.insert(0, str(region))
    import run_single as original
    from somo.sweep import iter_utils

    steps = tuple(int(x) for x in args.inspect_steps.split(",")) if args.inspect else ()
    tracer = (
        Tracer(every=args.trace_every, scale=20.0, inspect_steps=steps)
        if (args.trace or args.inspect)
        else None
    )
    if tracer:
        tracer.dt = args.time_step or 0.0005
    for dsr, width, c in todo:
        cfg, h = cell_config(region, dsr, width, c, work, args.time_step)
        iter_utils.add_tmp("_tmp")
        if tracer:
            tracer.n, tracer.rows, tracer.dumps = 0, [], []
        t0 = time.time()
        original.run_single({"filename": str(cfg), "index": 0})
        wall = time.time() - t0
        iter_utils.delete_tmp("_tmp")
        run_folder = work / "data" / "cells" / f"dsr{dsr:.2f}_w{width}_c{c:g}"
        row: dict[str, Any] = {"dsr": dsr, "width_mm": width, "c_mm": c, "hand_x_units": h}
        row["wall_s"] = round(wall, 2)
        row["time_step_s"] = args.time_step or 0.0005
        row["restitution"] = "original" if restitution is None else restitution
        row.update(label_cell(region, run_folder, dsr, 20.0))
        for path in run_folder.iterdir():
            path.unlink()
        run_folder.rmdir()
        new = not out.exists()
        with open(out, "a", newline="") as f:
            w = csv.DictWriter(f, FIELDS)
            if new:
                w.writeheader()
            w.writerow(row)
        if tracer and args.trace:
            with open(args.trace, "a") as f:
                f.write(json.dumps({"cell": [dsr, width, c], "rows": tracer.rows}) + "\n")
        if tracer and args.inspect:
            with open(args.inspect, "a") as f:
                f.write(json.dumps({"cell": [dsr, width, c], "dumps": tracer.dumps}, default=repr) + "\n")
        print(
            f"DSR {dsr:.2f} w {width} c {c:g}: {row['orig_label']} mean_link {row['orig_mean_link']} "
            f"z {row['orig_z_m']:.4f} ({wall:.1f} s)",
            flush=True,
        )


_DATA_FILES = {
    "objectpose": "object_pose.dat",
    "contact": "contact.dat",
    "actuation": "actuation.pkl",
    "calculated": "calculated.yaml",
    "video": "result.mp4",
}

if __name__ == "__main__":
    main()
