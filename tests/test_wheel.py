"""A wheel (non-editable) install carries its data and not the lab: the bundled example and the paper
figures run from an empty folder, with nothing of the source tree on the path, and benchmarks/ is
not in it."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
@pytest.mark.timeout(1200)  # a wheel built, 24 trials and five figures: 7.5 min on a loaded machine
def test_a_wheel_install_runs_the_bundled_example_and_figures_from_an_empty_folder(tmp_path: Path) -> None:
    wheels, target, empty = tmp_path / "wheels", tmp_path / "site", tmp_path / "empty"
    empty.mkdir()
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    subprocess.run(
        [*pip, "wheel", "--no-deps", "-w", str(wheels), str(ROOT)], check=True, capture_output=True
    )
    (wheel,) = wheels.glob("somo_sweep-*.whl")
    with zipfile.ZipFile(wheel) as archive:
        tops = {name.split("/")[0] for name in archive.namelist()}
    assert not {"benchmarks", "tests", "examples"} & tops  # the lab and the examples are not installed
    assert "somo_sweep" in tops
    subprocess.run([*pip, "install", "--no-deps", "--target", str(target), str(wheel)], check=True)
    env = {**os.environ, "PYTHONPATH": str(target)}

    def cli(*args: str) -> str:
        out = subprocess.run(
            [sys.executable, "-m", "somo_sweep", *args], cwd=empty, env=env, capture_output=True, text=True
        )
        assert out.returncode == 0, out.stdout + out.stderr
        return out.stdout

    where = subprocess.run(
        [sys.executable, "-c", "import somo_sweep; print(somo_sweep.__file__)"],
        cwd=empty,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert where.startswith(str(target))  # the wheel's copy, not the source tree
    assert "24 trial(s) run (ok 24)" in cli("run", "studies/pinch_grasp_demo.yaml", "--jobs", "2")
    # The README's other studies/... lines: there is no studies/ folder here.
    assert "ihm_finger: base fixed" in cli("check", "studies/models/ihm_finger.yaml")
    cli("calibrate", "studies/tables/planar_finger_synthetic.csv", "-o", "results/planar_finger.yaml", "-q")
    assert (empty / "results" / "planar_finger.yaml").is_file()
    assert "smallest all-width pinch DSR" in cli("paper", "fig6", "results/pinch_grasp_demo", "--out", "figs")
    cli("new", "grasp-study", "mine")  # the starter's templates are package data
    assert sorted(p.name for p in (empty / "mine").iterdir()) == [
        "bench.csv",
        "design.yaml",
        "finger.yaml",
        "gripper.yaml",
        "study.yaml",
    ]
    cli("paper", "fig8", "--quick", "--out", "figs")
    cli("paper", "fig3", "--out", "figs")
    cli("paper", "fig7", "--quick", "--out", "figs")
    cli("paper", "fig5", "--quick", "--out", "figs")
    for name in (
        "fig6_contacts.png",
        "fig8-quick.png",
        "fig3_blocked_force.png",
        "fig7-quick.png",
        "fig5-quick.png",
    ):
        assert (empty / "figs" / name).read_bytes().startswith(b"\x89PNG")
