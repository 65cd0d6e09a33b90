"""PyBullet's limits as the descriptions state them, and PyBullet's import banner kept out of the output."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import MODELS, load_yaml

from somo_sweep.model.load import MAX_BODY_LINKS, body_links, load_model, model_from_dict
from somo_sweep.sim.planner import plan_assembly
from somo_sweep.sim.worlds import open_world

CLI = Path(sys.executable).parent / "somo-sweep"
BANNER = "pybullet build time"


def _variants() -> list[dict]:
    free = load_yaml("ihm_finger.yaml")
    free["manipulator"]["base"] = {"mode": "free"}
    start = load_yaml("ihm_finger.yaml")
    start["manipulator"]["actuators"][0]["joint_placement"] = "start"
    hand = load_yaml("ihm_hand.yaml")
    hand["assembly"]["base"].pop("link", None)
    return [free, start, hand]


@pytest.mark.parametrize("name", sorted(p.name for p in MODELS.glob("*.yaml")))
def test_link_count_of_every_bundled_model_matches_its_plan(name: str) -> None:
    assembly = load_model(MODELS / name).as_assembly()
    planned = {p.name: len(p.links) for p in plan_assembly(assembly) if p.joints}
    assert {k: v for k, v in body_links(assembly).items() if k in planned} == planned


@pytest.mark.parametrize("data", _variants(), ids=["free_base", "start_placement", "hand_without_base_link"])
def test_link_count_of_variants_matches_their_plan(data: dict) -> None:
    assembly = model_from_dict(data, "m.yaml", MODELS).as_assembly()
    planned = {p.name: len(p.links) for p in plan_assembly(assembly) if p.joints}
    assert body_links(assembly) == planned


def test_a_body_at_the_link_limit_loads_and_reports_its_state() -> None:
    data = load_yaml("ihm_finger.yaml")
    act = data["manipulator"]["actuators"][0]
    act["n_segments"], act["length_m"] = MAX_BODY_LINKS - 2, 0.01 * (MAX_BODY_LINKS - 2)
    model = model_from_dict(data)
    assert body_links(model.as_assembly()) == {"ihm_finger": MAX_BODY_LINKS}
    with open_world() as world:
        handle = world.add_model(model)
        world.step(2)
        tip = world.tip_position(handle.bodies[0])
    assert np.all(np.isfinite(tip))


def test_pybullet_fails_one_link_beyond_the_limit() -> None:
    # The measurement behind MAX_BODY_LINKS: a chain of MAX_BODY_LINKS + 1 links loads, but
    # PyBullet can no longer report its joint or link states.
    import tempfile

    import pybullet as p

    inertial = (
        '<inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>'
    )
    parts = [f'<robot name="r"><link name="l0">{inertial}</link>']
    for i in range(1, MAX_BODY_LINKS + 1):
        parts.append(f'<link name="l{i}">{inertial}</link>')
        parts.append(
            f'<joint name="j{i}" type="continuous"><parent link="l{i - 1}"/><child link="l{i}"/>'
            '<origin xyz="0 0 0.01"/><axis xyz="1 0 0"/></joint>'
        )
    with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as fh:
        fh.write("\n".join(parts) + "\n</robot>\n")  # one element a line: long lines fail to parse
    client = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(fh.name, physicsClientId=client)
        assert p.getNumJoints(body, physicsClientId=client) == MAX_BODY_LINKS
        with pytest.raises(p.error, match="getLinkState failed"):
            p.getLinkState(body, 0, physicsClientId=client)
    finally:
        p.disconnect(client)
        Path(fh.name).unlink()


def test_the_pybullet_banner_is_silent_in_a_command() -> None:
    res = subprocess.run(
        [str(CLI), "measure", str(MODELS / "ihm_finger.yaml"), "--test", "free_bending", "--values", "0"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("# simulated with somo-sweep measure")
    assert BANNER not in res.stdout + res.stderr


def test_the_pybullet_banner_is_silent_in_worker_processes(tmp_path: Path) -> None:
    study = tmp_path / "study.yaml"
    study.write_text(
        f"task: bench\nmodel: {MODELS / 'ihm_finger.yaml'}\nparams: {{test: free_bending}}\n"
        "sweep: {task.pressure_kpa: [0, 50]}\n"
    )
    res = subprocess.run(
        [str(CLI), "run", str(study), "--jobs", "2", "--no-plots", "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr
    assert "2 trial(s) run (ok 2)" in res.stdout
    assert BANNER not in res.stdout + res.stderr
