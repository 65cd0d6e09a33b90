"""The package's shape: layers import downward only, studies load without PyBullet, one CLI."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "somo_sweep"
#: Each stage may import the stages ranked below it (and itself), never above.
RANK = {
    "errors": 0,
    "model": 1,
    "sim": 2,
    "tasks": 3,
    "sweep": 4,
    "calibration": 4,
    "diagnosis": 5,
    "paper": 6,
    "cli": 7,
    "data": 1,
}


def _stage(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def _imports(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("somo_sweep."):
            found.add(node.module)
        elif isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("somo_sweep.")}
    return found


def test_the_top_level_holds_only_the_package_entry_and_the_errors() -> None:
    assert sorted(p.name for p in PACKAGE.glob("*.py")) == ["__init__.py", "__main__.py", "errors.py"]


def test_no_module_outside_the_cli_has_a_main() -> None:
    offenders = [
        str(path.relative_to(PACKAGE))
        for path in PACKAGE.rglob("*.py")
        if "cli" not in path.parts and "\ndef main(" in path.read_text(encoding="utf-8")
    ]
    assert offenders == []


@pytest.mark.parametrize("path", sorted(PACKAGE.rglob("*.py")), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_every_import_points_down_the_stages(path: Path) -> None:
    here = ".".join(("somo_sweep", *path.relative_to(PACKAGE).with_suffix("").parts))
    stage = _stage(here)
    if stage not in RANK:
        return  # __init__ / __main__ of the package itself
    upward = [m for m in _imports(path) if _stage(m) != stage and RANK[_stage(m)] >= RANK[stage]]
    assert upward == [], f"{here} imports a stage at or above its own: {upward}"


def test_loading_and_expanding_a_study_does_not_import_pybullet() -> None:
    code = (
        "import sys\n"
        "from somo_sweep.model.tables import bundled_path\n"
        "from somo_sweep.sweep.study import load_study\n"
        "from somo_sweep.sweep.jobs import build_jobs\n"
        "for name in ('pinch_grasp_quick.yaml', 'palm_design_quick.yaml', 'finger_pressure_sweep.yaml'):\n"
        "    table = build_jobs(load_study(bundled_path(name)))\n"
        "    assert table.jobs\n"
        "print(sorted(m for m in sys.modules if m.startswith('pybullet')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_test_modules_have_unique_names() -> None:
    """``tests`` has no packages: two test files with one basename stop pytest's collection."""
    names = [p.name for p in (PACKAGE.parent / "tests").rglob("test_*.py")]
    assert sorted({n for n in names if names.count(n) > 1}) == []


#: Each engine's own package, the only place that may import it.
ENGINE_PACKAGES = {"pybullet": "sim/pybullet", "mujoco": "sim/mujoco"}


def _third_party_imports(path: Path) -> set[str]:
    """Top-level names of every module a file imports (``import x.y`` and ``from x import y`` give x)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module.split(".")[0])
        elif isinstance(node, ast.Import):
            found |= {a.name.split(".")[0] for a in node.names}
    return found


@pytest.mark.parametrize("engine", sorted(ENGINE_PACKAGES))
def test_each_engine_is_imported_only_in_its_own_package(engine: str) -> None:
    home = PACKAGE / ENGINE_PACKAGES[engine]
    offenders = [
        str(path.relative_to(PACKAGE))
        for path in PACKAGE.rglob("*.py")
        if engine in _third_party_imports(path) and home not in path.parents
    ]
    assert offenders == []


def test_no_task_imports_an_engine_or_an_engine_package() -> None:
    """Tasks talk only to ``World``: a task written once runs on both engines."""
    offenders = {}
    for path in (PACKAGE / "tasks").rglob("*.py"):
        engines = _third_party_imports(path) & set(ENGINE_PACKAGES)
        engine_packages = ("somo_sweep.sim.pybullet", "somo_sweep.sim.mujoco")
        packages = {m for m in _imports(path) if m.startswith(engine_packages)}
        if engines or packages:
            offenders[str(path.relative_to(PACKAGE))] = sorted(engines | packages)
    assert offenders == {}


def test_the_checks_above_see_an_engine_import() -> None:
    """The scanner finds ``import pybullet as p`` and ``from mujoco import x`` (the checks can fail)."""
    assert {"pybullet", "mujoco"} <= _third_party_imports(PACKAGE / "sim" / "pybullet" / "world.py") | (
        _third_party_imports(PACKAGE / "sim" / "mujoco" / "world.py")
    )


def test_loading_a_mujoco_study_imports_neither_engine(tmp_path: Path) -> None:
    study = tmp_path / "study.yaml"
    study.write_text(
        "task: pinch_grasp\nmodel: models/pinch_gripper.yaml\nsimulation: {engine: mujoco}\n"
        "sweep:\n  task.object_width_m: [0.01, 0.04]\n",
        encoding="utf-8",
    )
    (tmp_path / "models").symlink_to(PACKAGE / "data" / "models")
    code = (
        "import sys\n"
        "from somo_sweep.sweep.study import load_study\n"
        "from somo_sweep.sweep.jobs import build_jobs\n"
        f"assert build_jobs(load_study({str(study)!r})).jobs\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('pybullet', 'mujoco')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
