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
    "statics": 3,
    "tasks": 4,
    "sweep": 5,
    "calibration": 5,
    "diagnosis": 6,
    "design": 6,
    "paper": 7,
    "cli": 8,
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


#: The rooms of ``sweep/``, each by the data it handles, lowest first: a room may import the rooms
#: ranked below it (and itself), never above.
SWEEP_ROOMS = {"store": 0, "study": 1, "jobs": 2, "run": 3, "views": 4}


def test_sweep_holds_only_its_rooms() -> None:
    sweep = PACKAGE / "sweep"
    assert sorted(p.name for p in sweep.glob("*.py")) == ["__init__.py"]
    assert sorted(p.name for p in sweep.iterdir() if p.is_dir() and p.name != "__pycache__") == sorted(
        SWEEP_ROOMS
    )


@pytest.mark.parametrize(
    "path", sorted((PACKAGE / "sweep").rglob("*.py")), ids=lambda p: str(p.relative_to(PACKAGE))
)
def test_every_import_inside_sweep_points_down_its_rooms(path: Path) -> None:
    parts = path.relative_to(PACKAGE / "sweep").parts
    if len(parts) < 2:
        return
    room = parts[0]
    upward = [
        m
        for m in _imports(path)
        if m.startswith("somo_sweep.sweep.")
        and m.split(".")[2] != room
        and SWEEP_ROOMS[m.split(".")[2]] >= SWEEP_ROOMS[room]
    ]
    assert upward == [], f"sweep/{'/'.join(parts)} imports a room at or above its own: {upward}"


def test_loading_and_expanding_a_study_does_not_import_pybullet() -> None:
    code = (
        "import sys\n"
        "from somo_sweep.model.tables import bundled_path\n"
        "from somo_sweep.sweep.study import load_study\n"
        "from somo_sweep.sweep.jobs.table import build_jobs\n"
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
ENGINE_PACKAGES = {
    "pybullet": "sim/pybullet",
    "mujoco": "sim/mujoco",
    "mujoco_warp": "sim/mujoco",
    "warp": "sim/mujoco",
}


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


def test_only_the_warp_modules_import_warp_so_mujoco_runs_without_the_extra() -> None:
    """MuJoCo Warp is an extra of its own: the MuJoCo engine never imports it, only the
    ``mujoco_warp`` engine's modules (loaded when a study names that engine) do."""
    importers = sorted(
        str(path.relative_to(PACKAGE))
        for path in PACKAGE.rglob("*.py")
        if _third_party_imports(path) & {"warp", "mujoco_warp"}
    )
    assert importers == ["sim/mujoco/warp_batch.py", "sim/mujoco/warp_model.py"]
    for path in (PACKAGE / "sim" / "mujoco").glob("*.py"):
        if not path.name.startswith("warp_"):
            assert not any(m.startswith("somo_sweep.sim.mujoco.warp") for m in _imports(path)), path.name


#: Stages that reach an engine only through the engine-neutral interfaces of ``sim``.
ENGINE_FREE_STAGES = ("statics", "tasks")


def _engine_imports(path: Path) -> list[str]:
    """The engines and engine packages a file imports (anywhere in it, function bodies too)."""
    engines = _third_party_imports(path) & set(ENGINE_PACKAGES)
    engine_packages = ("somo_sweep.sim.pybullet", "somo_sweep.sim.mujoco")
    return sorted(engines | {m for m in _imports(path) if m.startswith(engine_packages)})


@pytest.mark.parametrize("stage", ENGINE_FREE_STAGES)
def test_no_task_nor_the_statics_import_an_engine_or_an_engine_package(stage: str) -> None:
    """Tasks talk only to ``World``, the bench statics only to ``World`` and ``ChainKinematics``:
    each is written once and runs on both engines."""
    offenders = {}
    for path in (PACKAGE / stage).rglob("*.py"):
        if found := _engine_imports(path):
            offenders[str(path.relative_to(PACKAGE))] = found
    assert offenders == {}


#: The bench statics' modules: a stage of their own above the engines, not part of ``sim``.
STATICS_MODULES = {
    "bench_rig", "bench", "relaxation", "bench_bodies", "chain_kinematics", "chain_energy", "active_set_qp",
    "static_newton", "continuation", "no_equilibrium", "plate_force_range", "static_chain", "solve",
}  # fmt: skip


def test_the_bench_statics_are_a_stage_of_their_own_above_the_engines_kinematics() -> None:
    statics = {p.stem for p in (PACKAGE / "statics").glob("*.py")} - {"__init__"}
    assert statics == STATICS_MODULES
    assert not {p.stem for p in (PACKAGE / "sim").glob("*.py")} & (STATICS_MODULES | {"statics"})
    # Each engine's chain kinematics stays in sim, below the statics, and needs nothing of them.
    for home in set(ENGINE_PACKAGES.values()):
        kinematics = PACKAGE / home / "kinematics.py"
        assert not {m for m in _imports(kinematics) if m.startswith("somo_sweep.statics")}


def test_the_engine_free_check_sees_an_engine_package(tmp_path: Path) -> None:
    """The check above can fail: an engine package imported inside a function is found."""
    module = tmp_path / "m.py"
    module.write_text("def f():\n    from somo_sweep.sim.mujoco.kinematics import MujocoChainKinematics\n")
    assert _engine_imports(module) == ["somo_sweep.sim.mujoco.kinematics"]


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
        "from somo_sweep.sweep.jobs.table import build_jobs\n"
        f"assert build_jobs(load_study({str(study)!r})).jobs\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('pybullet', 'mujoco')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _module_graph() -> dict[str, set[str]]:
    """Every somo_sweep module and the somo_sweep modules it imports anywhere in its body
    (function-local imports too): ``from a.b import c`` names a.b.c when c is a module, else a.b."""
    modules = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join([*anchor, *([base] if base else [])])
                targets |= {f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names}
        graph[name] = set()
        for target in targets:
            while target not in modules and "." in target:
                target = target.rpartition(".")[0]
            if target in modules and target != name:
                graph[name].add(target)
    return graph


def test_no_import_circle_between_any_two_modules() -> None:
    """Not only between stages: two modules of one package that import each other (even inside a
    function) are a circle too, and each is a knot a reader has to untie."""
    import graphlib

    try:
        graphlib.TopologicalSorter(_module_graph()).prepare()
    except graphlib.CycleError as circle:
        pytest.fail(f"import circle: {' -> '.join(circle.args[1])}")


def test_the_circle_check_sees_a_circle_inside_a_package(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The check above can fail: two sibling modules importing each other in functions are found."""
    package = tmp_path / "somo_sweep" / "stage"
    package.mkdir(parents=True)
    (package.parent / "__init__.py").write_text("")
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("def f():\n    from somo_sweep.stage.b import g\n")
    (package / "b.py").write_text("def g():\n    from . import a\n")
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", tmp_path / "somo_sweep")
    with pytest.raises(pytest.fail.Exception, match=r"import circle: somo_sweep\.stage"):
        test_no_import_circle_between_any_two_modules()


#: Limits of a unit's size: a module's lines, and a function's from its ``def`` line to its last
#: (docstring and comments included, decorators not). Past one, split along a seam: a module per
#: concern, a function's distinct steps as named helpers; never squeeze lines or drop docstrings.
MAX_MODULE_LINES, MAX_FUNCTION_LINES = 400, 60


def test_no_module_or_function_outgrows_its_limit() -> None:
    too_long = []
    for path in sorted(PACKAGE.rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        where = path.relative_to(PACKAGE)
        if text.count("\n") > MAX_MODULE_LINES:
            too_long.append(f"{where}: {text.count(chr(10))} lines, more than {MAX_MODULE_LINES} a module")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = (node.end_lineno or node.lineno) - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    limit = f"more than {MAX_FUNCTION_LINES} a function"
                    too_long.append(f"{where}:{node.lineno} {node.name}: {lines} lines, {limit}")
    assert too_long == [], (
        "split these along a seam (a module per concern, a function's distinct steps as named helpers): "
        + "; ".join(too_long)
    )


def test_the_size_check_finds_a_module_and_a_function_one_line_over(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The check above can fail: a function of 61 lines and a module of 401 are both found, a
    function of 60 lines in a module of 400 is not."""
    package = tmp_path / "somo_sweep"
    package.mkdir()
    body = "".join(f"    x{i} = {i}\n" for i in range(59))  # the house's habits: 60 and 400 lines
    blank = "\n" * 340
    (package / "fits.py").write_text(f"def fits():\n{body}{blank}")
    (package / "over.py").write_text(f"def long():\n{body}    y = 0\n{blank}")
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", package)
    with pytest.raises(AssertionError) as info:
        test_no_module_or_function_outgrows_its_limit()
    found = str(info.value).split("\n")[0]
    assert "over.py: 401 lines, more than 400 a module" in found
    assert "over.py:1 long: 61 lines, more than 60 a function" in found
    assert "fits.py" not in found


#: The only places that write, move or delete files: the command line (every file a user asks
#: for), the results store (part files, manifest, lock) and the URDF cache. A module elsewhere
#: computes and returns; its caller decides where things go.
WRITERS = ("cli/", "sweep/store/", "sim/urdf_cache.py")
#: A test task writes marker files a test waits for (`tasks/selftest.py`, hidden from users).
WRITER_EXCEPTIONS = {"tasks/selftest.py": {"touch"}}
_WRITE_METHODS = {
    "write_text", "write_bytes", "savefig", "write_table", "mkdir", "unlink", "rmtree", "touch",
    "imsave", "rmdir", "symlink_to", "hardlink_to", "to_parquet", "to_csv", "to_json",
}  # fmt: skip
_OS_CALLS = {"replace", "rename", "remove", "unlink", "makedirs", "mkdir", "rmdir", "link", "symlink"}


def _file_writes(path: Path) -> list[tuple[int, str]]:
    """Calls in a module that write, move or delete a file (``to_csv()`` with no path returns text)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if not isinstance(node, ast.Call):
            continue
        func, hit = node.func, None
        if isinstance(func, ast.Attribute):
            to_text = func.attr.startswith("to_") and not node.args
            to_text = to_text and not {k.arg for k in node.keywords} & {"path", "path_or_buf", "where"}
            if isinstance(func.value, ast.Name) and func.value.id == "shutil":
                hit = f"shutil.{func.attr}"
            elif func.attr in _WRITE_METHODS and not to_text:
                hit = func.attr
            elif isinstance(func.value, ast.Name) and func.value.id == "os" and func.attr in _OS_CALLS:
                hit = f"os.{func.attr}"
            elif isinstance(func.value, ast.Name) and func.value.id == "os" and func.attr == "open":
                hit = "os.open" if "O_CREAT" in ast.unparse(node) else None
        elif isinstance(func, ast.Name) and func.id == "open":
            mode = node.args[1] if len(node.args) > 1 else None
            mode = next((k.value for k in node.keywords if k.arg == "mode"), mode)
            if isinstance(mode, ast.Constant) and set(str(mode.value)) & set("wax+"):
                hit = "open"
        if hit:
            found.append((node.lineno, hit))
    return found


def test_only_the_cli_the_store_and_the_urdf_cache_write_files() -> None:
    offenders = []
    for path in sorted(PACKAGE.rglob("*.py")):
        where = str(path.relative_to(PACKAGE))
        if where.startswith(WRITERS):
            continue
        allowed = WRITER_EXCEPTIONS.get(where, set())
        offenders += [f"{where}:{line} {call}" for line, call in _file_writes(path) if call not in allowed]
    assert offenders == []


def test_the_writer_check_sees_a_write(tmp_path: Path) -> None:
    """The check above can fail: each kind of write is found."""
    module = tmp_path / "m.py"
    module.write_text(
        "import os, shutil\n"
        "def f(p, df):\n"
        "    p.write_text('x'); df.to_parquet(p); open(p, 'a'); os.replace(p, p)\n"
        "    shutil.rmtree(p); os.open(p, os.O_CREAT)\n"
        "    text = df.to_csv(); open(p)\n"
    )
    assert sorted(call for _, call in _file_writes(module)) == sorted(
        ["write_text", "to_parquet", "open", "os.replace", "shutil.rmtree", "os.open"]
    )
