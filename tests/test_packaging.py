"""Packaging: every third-party import is declared, optional backends are extras, platforms are named."""

from __future__ import annotations

import ast
import re
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TOML = tomllib.loads((ROOT / "pyproject.toml").read_text())
PYPROJECT = TOML["project"]
#: Import name → distribution name, where they differ.
DISTRIBUTIONS = {
    "PIL": "pillow",
    "yaml": "pyyaml",
    "distributed": "dask",
    "sklearn": "scikit-learn",
    "mujoco_warp": "mujoco-warp",
    "warp": "warp-lang",
}


def _names(requirements: list[str]) -> set[str]:
    return {re.split(r"[\[<>=!~ ;]", r, maxsplit=1)[0].lower() for r in requirements}


def _imported() -> set[str]:
    found = set()
    for path in (ROOT / "somo_sweep").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                found |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                found.add(node.module.split(".")[0])
    return {n for n in found if n not in sys.stdlib_module_names and n != "somo_sweep"}


def test_every_imported_distribution_is_declared() -> None:
    extras = PYPROJECT["optional-dependencies"]
    declared = _names(PYPROJECT["dependencies"]) | set().union(
        *(_names(extras[e]) for e in ("dask", "mujoco", "warp"))
    )
    missing = {DISTRIBUTIONS.get(n, n).lower() for n in _imported()} - declared
    assert missing == set()


def test_pillow_is_a_core_dependency() -> None:
    assert "pillow" in _names(PYPROJECT["dependencies"])


def test_dask_is_an_extra_and_a_dev_dependency_not_a_core_one() -> None:
    extras = PYPROJECT["optional-dependencies"]
    assert "dask" not in _names(PYPROJECT["dependencies"])
    assert any(r.startswith("dask[distributed]") for r in extras["dask"])
    assert "dask" in _names(extras["dev"])


def test_the_cluster_extra_adds_dask_jobqueue_to_dask_and_the_core_has_neither() -> None:
    extras = PYPROJECT["optional-dependencies"]
    assert _names(extras["cluster"]) == {"dask", "dask-jobqueue"}
    assert not {"dask", "dask-jobqueue", "distributed"} & _names(PYPROJECT["dependencies"])


def test_mujoco_is_an_extra_and_a_dev_dependency_not_a_core_one() -> None:
    """The default install runs without MuJoCo; CI (make test installs .[dev]) runs its tests."""
    extras = PYPROJECT["optional-dependencies"]
    assert "mujoco" not in _names(PYPROJECT["dependencies"])
    assert "mujoco" in _names(extras["mujoco"]) and "mujoco" in _names(extras["dev"])


def test_supported_platforms_are_classified() -> None:
    classifiers = PYPROJECT["classifiers"]
    assert "Operating System :: POSIX :: Linux" in classifiers and "Operating System :: MacOS" in classifiers


def test_the_wheel_holds_the_package_and_not_the_lab() -> None:
    """benchmarks/ (and tests/) stay in the repository: setuptools finds somo_sweep's packages only."""
    from setuptools import find_packages

    include = TOML["tool"]["setuptools"]["packages"]["find"]["include"]
    found = find_packages(where=str(ROOT), include=include)
    assert "somo_sweep" in found and "somo_sweep.paper" in found
    assert (ROOT / "benchmarks" / "__init__.py").is_file()
    assert not [name for name in found if not name.startswith("somo_sweep")]
