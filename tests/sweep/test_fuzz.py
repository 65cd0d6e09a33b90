"""Fuzzing the commands that read user files: mutated studies, models and measurement CSVs.

Seeds are the bundled files. Mutations change keys, values and types in the parsed data,
or cut, splice, re-encode and corrupt the raw text. Through the command line in-process,
every case must end with exit code 0 or 2 and a message, never a traceback, quickly.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import MODELS
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.model.tables import bundled_path

STUDIES = sorted(bundled_path(".").glob("*.yaml"))
MODEL_FILES = sorted(MODELS.glob("*.yaml"))
CSVS = sorted(p for p in bundled_path("tables").glob("*.csv") if "test," in p.read_text())
#: Per example, s: a case that hangs is a failure too.
DEADLINE_S = 5.0
FUZZ = settings(
    max_examples=40,
    deadline=None,  # timed by hand below (the first example pays for imports)
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    derandomize=True,
)

SCALARS = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(10**12), max_value=10**12),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from(["", "x", "a&b<c>", "../../etc/passwd", "/etc/passwd", "{start: 0}", "é", "\u202e"]),
    st.text(max_size=20),
)
VALUES = st.recursive(
    SCALARS,
    lambda kids: st.lists(kids, max_size=4) | st.dictionaries(st.text(max_size=8), kids, max_size=4),
    max_leaves=8,
)


def _paths(data: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    found = [prefix]
    if isinstance(data, dict):
        for k, v in data.items():
            found += _paths(v, (*prefix, k))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            found += _paths(v, (*prefix, i))
    return found


def _mutate(data: Any, draw: st.DrawFn) -> Any:
    """Change, delete, add or rename at one random place of parsed data."""
    paths = _paths(data)
    where = draw(st.sampled_from(paths))
    if not where:
        return draw(VALUES)
    parent = data
    for part in where[:-1]:
        parent = parent[part]
    key = where[-1]
    action = draw(st.sampled_from(["set", "delete", "add", "rename", "big"]))
    if action == "set":
        parent[key] = draw(VALUES)
    elif action == "delete":
        del parent[key]
    elif action == "big" and isinstance(parent, dict):
        parent[key] = {"start": 0, "stop": draw(st.integers(1, 10**12)), "step": 1}
    elif isinstance(parent, dict):
        name = draw(st.text(min_size=1, max_size=12))
        value = parent.pop(key) if action == "rename" else draw(VALUES)
        parent[name] = value
    else:
        parent.insert(int(key), draw(VALUES))
    return data


@st.composite
def _structured(draw: st.DrawFn, seeds: list[Path]) -> bytes:
    data = yaml.safe_load(draw(st.sampled_from(seeds)).read_text())
    for _ in range(draw(st.integers(1, 3))):
        data = _mutate(data, draw)
    return yaml.safe_dump(data, allow_unicode=True).encode("utf-8")


@st.composite
def _raw(draw: st.DrawFn, seeds: list[Path], utf8_only: bool = False) -> bytes:
    text = draw(st.sampled_from(seeds)).read_text()
    lines = text.splitlines(keepends=True)
    action = draw(st.sampled_from(["truncate", "splice", "drop_line", "repeat_line", "encode", "bytes"]))
    if action == "truncate":
        return text[: draw(st.integers(0, len(text)))].encode()
    if action == "splice":
        at = draw(st.integers(0, len(text)))
        return (text[:at] + draw(st.text(max_size=30)) + text[at:]).encode("utf-8", "surrogatepass")
    if action in ("drop_line", "repeat_line") and lines:
        i = draw(st.integers(0, len(lines) - 1))
        lines[i : i + 1] = [] if action == "drop_line" else [lines[i], lines[i]]
        return "".join(lines).encode()
    if action == "encode" and not utf8_only:
        return (
            text.encode(draw(st.sampled_from(["utf-16", "utf-32", "latin-1", "cp1252"])), "replace") + b"\xe9"
        )
    if action == "bytes" and not utf8_only:
        at = draw(st.integers(0, len(text)))
        raw = text.encode()
        return raw[:at] + draw(st.binary(min_size=1, max_size=8)) + raw[at:]
    return text.encode()


def _invoke(args: list[str]) -> None:
    start = time.perf_counter()
    res = CliRunner().invoke(app, args)
    elapsed = time.perf_counter() - start
    assert res.exit_code in (0, 2), (res.exit_code, res.output, res.exception)
    assert res.exception is None or isinstance(res.exception, SystemExit), repr(res.exception)
    assert "Traceback" not in res.output
    if res.exit_code == 2:  # warnings (a repeated row) may come first
        said = [ln for ln in res.output.splitlines() if not ln.startswith("warning: ")]
        assert (said and said[0].startswith("error: ")) or "Usage:" in res.output, res.output
    assert elapsed < DEADLINE_S, f"{elapsed:.1f} s"


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder holding the bundled models and tables, where mutated files are written."""
    root = tmp_path_factory.mktemp("fuzz")
    shutil.copytree(MODELS, root / "models")
    shutil.copytree(bundled_path("tables"), root / "tables")
    return root


def _write(folder: Path, data: bytes, name: str) -> Path:
    path = folder / name
    path.write_bytes(data)
    return path


@FUZZ
@given(data=st.one_of(_structured(STUDIES), _raw(STUDIES)))
def test_mutated_studies_never_crash_check_or_dry_run(folder: Path, data: bytes) -> None:
    path = _write(folder, data, "study.yaml")
    _invoke(["run", str(path), "--dry-run", "--no-estimate", "--out", str(folder / "out")])


@FUZZ
@given(data=st.one_of(_structured(MODEL_FILES), _raw(MODEL_FILES)))
def test_mutated_models_never_crash_check(folder: Path, data: bytes) -> None:
    _invoke(["check", str(_write(folder / "models", data, "fuzzed.yaml"))])


def _calibrate(folder: Path, csv: Path) -> list[str]:
    # A --model that does not exist: calibrate reads and validates the CSV, then stops before
    # any simulation (the reader is what is fuzzed).
    return [
        "calibrate",
        str(csv),
        "-o",
        str(folder / "calibrated.yaml"),
        "--model",
        str(folder / "none.yaml"),
    ]


@FUZZ
@given(data=_raw(CSVS, utf8_only=True))
def test_mutated_measurement_csvs_never_crash_the_reader(folder: Path, data: bytes) -> None:
    _invoke(_calibrate(folder, _write(folder, data, "bench.csv")))


def test_a_latin1_byte_in_a_measurement_csv_is_a_clear_error(folder: Path) -> None:
    text = CSVS[0].read_text().replace("test,", "# réglage\ntest,", 1)
    res = CliRunner().invoke(app, _calibrate(folder, _write(folder, text.encode("latin-1"), "latin1.csv")))
    assert res.exit_code == 2 and "not UTF-8" in res.output and "offset" in res.output
