"""The manual stays true to the code: every name its Python examples import exists, every make
target it names is in the Makefile, every link between its pages lands on a file."""

from __future__ import annotations

import ast
import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _python_blocks(page: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", page.read_text(encoding="utf-8"), flags=re.S)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_name_a_python_example_imports_exists(page: Path) -> None:
    missing = []
    for block in _python_blocks(page):
        for node in ast.walk(ast.parse(block)):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("somo_sweep"):
                module = importlib.import_module(node.module)
                missing += [f"{node.module}.{a.name}" for a in node.names if not hasattr(module, a.name)]
    assert missing == []


def _make_targets() -> set[str]:
    text = (ROOT / "Makefile").read_text(encoding="utf-8")
    return set(re.findall(r"^([A-Za-z0-9_.-]+):", text, flags=re.M))


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_make_target_named_exists(page: Path) -> None:
    named = set(re.findall(r"`make ([a-z0-9-]+)", page.read_text(encoding="utf-8")))
    assert sorted(named - _make_targets()) == []


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_lands_on_a_file(page: Path) -> None:
    links = re.findall(r"\]\(([^)#:\s]+)(?:#[^)]*)?\)", page.read_text(encoding="utf-8"))
    broken = [link for link in links if not (page.parent / link).exists()]
    assert broken == []


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_the_manual_holds_no_measurement_history(page: Path) -> None:
    """Dates and issue numbers belong beside the benchmark that produced them."""
    text = page.read_text(encoding="utf-8")
    assert re.findall(r"\b20\d\d-\d\d-\d\d\b|issue #\d+|\bload average", text) == []


def test_the_top_help_names_both_engines() -> None:
    """`somo-sweep --help` said "in PyBullet" after MuJoCo became an engine."""
    from typer.testing import CliRunner

    from somo_sweep.cli.app import app

    text = " ".join(CliRunner().invoke(app, ["--help"]).output.split())
    assert "in PyBullet or MuJoCo" in text


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_page_says_the_grasp_task_needs_the_bundled_fingers_shape(page: Path) -> None:
    """The grasp task takes two or more fingers of any equal-link count (docs/tasks.md)."""
    text = " ".join(page.read_text(encoding="utf-8").split())
    stale = r"(two-finger gripper of 20 equal links|a finger of another shape is refused)"
    assert re.findall(stale, text) == []
