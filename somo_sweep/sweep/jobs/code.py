"""What code a trial runs: the task's module, every somo_sweep module it imports, and their hash.

A job id names the code its trial runs (:func:`code_version`), so that results of other code are
never taken for this code's: editing a module a trial runs changes the ids of its trials, and
editing anything else (the command line, the plots, the sweep engine, another task) keeps them.
"""

from __future__ import annotations

import ast
import hashlib
from functools import cache
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

__all__ = ["code_version", "pybullet_version", "trial_modules"]


def _package_version() -> str:
    try:
        return version("somo-sweep")
    except PackageNotFoundError:  # a source tree that is not installed
        return "0.0.0"


@cache
def pybullet_version() -> str:
    """The installed PyBullet's version (from its metadata: PyBullet itself is not imported)."""
    try:
        return version("pybullet")
    except PackageNotFoundError:
        return "none"


def _module_file(name: str) -> Path | None:
    root = Path(__file__).resolve().parents[3]
    base = root / Path(*name.split("."))
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


#: Plumbing whose own source is hashed but whose imports are not followed: the registry
#: imports the model and world modules for type annotations only.
_NOT_FOLLOWED = {"somo_sweep.tasks.registry", "somo_sweep.tasks"}


def _imports(path: Path) -> set[str]:
    """``somo_sweep`` modules a source file imports (static; ``if TYPE_CHECKING:`` blocks skipped)."""
    found: set[str] = set()
    todo: list[ast.AST] = [ast.parse(path.read_text(encoding="utf-8"))]
    while todo:
        node = todo.pop()
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            todo.extend(node.orelse)
            continue
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("somo_sweep"):
            found.add(node.module)
            found.update(f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("somo_sweep"))
        todo.extend(ast.iter_child_nodes(node))
    return found


def _engine_packages() -> tuple[str, ...]:
    """The engines' packages (``somo_sweep.sim.<engine>``: the folders of sim/ that are packages)."""
    sim = Path(__file__).resolve().parents[2] / "sim"
    return tuple(f"somo_sweep.sim.{p.name}" for p in sorted(sim.iterdir()) if (p / "__init__.py").is_file())


def _engine_modules(engine: str) -> list[str]:
    """Every module of an engine's package (``somo_sweep.sim.<engine>``)."""
    folder = Path(__file__).resolve().parents[2] / "sim" / engine
    return [f"somo_sweep.sim.{engine}.{p.stem}" for p in sorted(folder.glob("*.py")) if p.stem != "__init__"]


def trial_modules(task_module: str, engine: str = "pybullet") -> list[str]:
    """The task's module and every somo_sweep module it imports, transitively (sorted).

    The engines' packages are not followed: the sim layer imports each engine by name, inside the
    function that opens it (:mod:`somo_sweep.sim.worlds`), so a scan of its imports finds both.
    A trial runs the modules of the engine its settings name: a trial that reaches the sim layer
    (opens a world, or a chain's kinematics) gets every module of that engine's package, and none
    of the other's (editing one engine keeps the other's job ids).
    """
    engines = _engine_packages()
    todo, seen, uses_engine = [task_module], set(), False
    while todo:
        name = todo.pop()
        path = _module_file(name)
        if name in seen or path is None:
            continue
        if name.startswith(engines):
            uses_engine = True
            continue
        seen.add(name)
        if name not in _NOT_FOLLOWED:
            todo.extend(sorted(_imports(path) - seen))
        uses_engine = uses_engine or name == "somo_sweep.sim.world"
    if uses_engine:
        seen.update(_engine_modules(engine))
    return sorted(seen)


@cache
def code_version(task_module: str, engine: str = "pybullet") -> str:
    """Package version plus a hash of the sources of :func:`trial_modules`.

    Only code a trial can run is hashed: editing the CLI, the plots, the sweep engine or
    another task keeps job ids, and hence finished results, valid; editing the task or
    the core modules it uses (world, springs, ...) changes them.
    """
    digest = hashlib.sha256()
    for name in trial_modules(task_module, engine):
        path = _module_file(name)
        assert path is not None
        digest.update(name.encode() + path.read_bytes())
    return f"{_package_version()}+{digest.hexdigest()[:12]}"
