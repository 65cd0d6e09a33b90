"""Hostile measurement CSVs and tables: huge, binary, absurdly long cells.

Each is refused with one bounded message naming the file, the line and what is allowed;
none is read whole into memory past its limit or echoed whole into the message.
"""

from __future__ import annotations

import time
from pathlib import Path

import pandas as pd
import pytest

from somo_sweep.calibration.measurements import MAX_FILE_BYTES, read_measurements
from somo_sweep.errors import SHOWN_CHARS, MeasurementError, SomoError, did_you_mean, shown
from somo_sweep.model import tables
from somo_sweep.model.tables import resolve_table

HEADER = "test,pressure_kpa,tip_load_n,tip_deflection_mm,blocked_force_n,tip_x_mm,tip_z_mm\n"


def _error(path: Path) -> str:
    with pytest.raises(MeasurementError) as info:
        read_measurements(path)
    return str(info.value)


def test_a_file_above_the_size_limit_is_refused_before_reading(tmp_path: Path) -> None:
    path = tmp_path / "m.csv"
    path.write_bytes(HEADER.encode() + b"#" * MAX_FILE_BYTES)
    text = _error(path)
    assert f"file is {MAX_FILE_BYTES + len(HEADER)} bytes; allowed: at most 8 MiB" in text
    assert len(text) < 500


def test_a_binary_file_is_named_binary(tmp_path: Path) -> None:
    path = tmp_path / "m.csv"
    path.write_bytes(HEADER.encode() + b"tip_load,0,\x00\x01,1,,,\n")
    assert f"binary file (NUL byte at offset {len(HEADER) + 11}); allowed: UTF-8 text" in _error(path)


@pytest.mark.parametrize(
    ("row", "message"),
    [
        ("a" * 2_000_000 + ",0,1,1,,,", "line 2, column test: unknown test 'aaaa"),
        ("tip_load,0," + "1" * 2_000_000 + ",1,,,", "line 2, column tip_load_n: 1111"),
        ("tip_load,0,x" + "y" * 1_999_999 + ",1,,,", "line 2, column tip_load_n: 'xyyy"),
    ],
    ids=["test", "overflowing-number", "not-a-number"],
)
def test_a_huge_cell_is_cut_in_the_message_and_costs_no_time(tmp_path: Path, row: str, message: str) -> None:
    path = tmp_path / "m.csv"
    path.write_text(HEADER + row + "\n")
    start = time.perf_counter()
    text = _error(path)
    assert time.perf_counter() - start < 5.0  # difflib on a 2-MB word took minutes
    assert message in text and "… (2000000 characters)" in text
    assert len(text) < 1000


def test_a_huge_column_name_is_cut(tmp_path: Path) -> None:
    path = tmp_path / "m.csv"
    path.write_text(HEADER.rstrip("\n") + ",z" + "x" * 1_000_000 + "\n")
    text = _error(path)
    assert "unknown column 'zxxx" in text and "… (1000001 characters)'; allowed: test, pressure_kpa" in text
    assert len(text) < 1000


def test_shown_keeps_short_values_and_cuts_long_ones() -> None:
    assert shown("tip_lod") == "tip_lod"
    assert shown("x" * SHOWN_CHARS) == "x" * SHOWN_CHARS
    assert shown("x" * (SHOWN_CHARS + 1)) == "x" * SHOWN_CHARS + f"… ({SHOWN_CHARS + 1} characters)"


def test_did_you_mean_still_hints_and_skips_absurd_words() -> None:
    assert did_you_mean("tip_lod", ["tip_load", "blocked_force"]) == " (did you mean 'tip_load'?)"
    assert did_you_mean("tip_load" * 1000, ["tip_load"]) == ""
    assert did_you_mean("anything", []) == ""


def test_a_table_above_the_size_limit_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tables, "MAX_TABLE_BYTES", 1024)
    (tmp_path / "small.csv").write_text("time_s,a\n" + "0,1\n" * 10)
    assert "#sha256=" in resolve_table("small.csv", tmp_path)
    (tmp_path / "big.csv").write_text("time_s,a\n" + "0,1\n" * 1000)
    with pytest.raises(SomoError, match=r"big\.csv: file is 4009 bytes; allowed: at most 1024 bytes"):
        resolve_table("big.csv", tmp_path)


def test_a_folder_or_a_device_is_named_for_what_it_is(tmp_path: Path) -> None:
    assert "not a regular file (a folder); allowed: a text file" in _error(tmp_path)
    assert "not a regular file (a device, pipe or socket)" in _error(Path("/dev/null"))
    assert "file not found" in _error(tmp_path / "missing.csv")


BUNDLED = Path(__file__).parents[2] / "somo_sweep" / "data" / "tables" / "planar_finger_synthetic.csv"


@pytest.mark.parametrize("encoding", ["utf-16", "utf-32"])
def test_utf16_and_utf32_are_named_with_what_to_do(tmp_path: Path, encoding: str) -> None:
    path = tmp_path / "m.csv"
    path.write_bytes(BUNDLED.read_text().encode(encoding))
    assert f"{encoding.upper()} text (byte-order mark" in _error(path)
    assert "save the file as UTF-8" in _error(path)


def test_excel_utf8_with_a_byte_order_mark_and_crlf_reads_like_the_plain_file(tmp_path: Path) -> None:
    from somo_sweep.calibration.finger import read_finger_header

    lines = BUNDLED.read_text().splitlines()
    finger = [ln for ln in lines if ln.startswith("# finger:")]
    body = finger + [ln for ln in lines if not ln.startswith("#")]  # the finger line first, as Excel keeps it
    path = tmp_path / "excel.csv"
    path.write_bytes(b"\xef\xbb\xbf" + "\r\n".join(body).encode() + b"\r\n")
    plain = tmp_path / "plain.csv"
    plain.write_text("\n".join(body) + "\n")
    assert read_finger_header(path) == read_finger_header(plain) is not None
    pd.testing.assert_frame_equal(read_measurements(path), read_measurements(plain))


@pytest.mark.parametrize(
    ("sep", "decimal"),
    [(";", ","), (";", "."), ("\t", ".")],
    ids=["semicolon-comma", "semicolon-point", "tab"],
)
def test_a_spreadsheet_export_with_semicolons_or_tabs_reads_like_the_plain_file(
    tmp_path: Path, sep: str, decimal: str
) -> None:
    # A spreadsheet in a decimal-comma locale saves "CSV" as 1,5;2,0: the same data.
    lines = BUNDLED.read_text().splitlines()
    body = [
        ln if ln.startswith("#") else sep.join(c.replace(".", decimal) for c in ln.split(",")) for ln in lines
    ]
    path = tmp_path / "export.csv"
    path.write_text("\n".join(body) + "\n")
    pd.testing.assert_frame_equal(read_measurements(path), read_measurements(BUNDLED))


def test_a_semicolon_file_names_a_bad_cell_by_line_and_column(tmp_path: Path) -> None:
    path = tmp_path / "m.csv"
    path.write_text(HEADER.replace(",", ";") + "tip_load;0;0,01;1,2,3;;;\n")
    assert "line 2, column tip_deflection_mm: '1,2,3' is not a number" in _error(path)


@pytest.mark.parametrize("gravity", ["nan", "1e300", "-9.81"])
@pytest.mark.parametrize("command", ["calibrate", "diagnose"])
def test_bench_gravity_outside_0_to_100_is_refused_and_nothing_written(
    tmp_path: Path, command: str, gravity: str
) -> None:
    """NaN gravity calibrated and wrote a model."""
    from typer.testing import CliRunner

    from somo_sweep.cli.app import app

    out = tmp_path / "o"
    args = [command, str(BUNDLED), "--gravity-m-s2", gravity]
    args += ["-o", str(out / "m.yaml")] if command == "calibrate" else ["--out", str(out)]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 2, res.output
    assert "gravity on the bench must be from 0 (a horizontal bench) to 100 m/s²" in res.output
    assert not out.exists()


def test_a_line_of_millions_of_fields_is_refused_by_its_line_before_parsing(tmp_path: Path) -> None:
    """2,000,000 empty columns took 197 s and 7.27 GB and printed 333 MB of errors."""
    path = tmp_path / "wide.csv"
    path.write_text(HEADER + "tip_load,0,0.01,1.0,,," + "," * 2_000_000 + "\n")
    assert "line 2 has 2000007 fields; allowed: at most 64" in _error(path)  # no column was made


def test_a_trailing_comma_on_every_line_reads_like_the_plain_file(tmp_path: Path) -> None:
    """A spreadsheet export: "unknown column 'Unnamed: 9'" before."""
    lines = BUNDLED.read_text().splitlines()
    path = tmp_path / "trailing.csv"
    path.write_text("\n".join(ln if ln.startswith("#") else ln + "," for ln in lines) + "\n")
    pd.testing.assert_frame_equal(read_measurements(path), read_measurements(BUNDLED))


def test_calibrate_and_diagnose_refuse_bad_output_places_and_empty_effects_before_any_work(
    tmp_path: Path,
) -> None:
    from typer.testing import CliRunner

    from somo_sweep.cli.app import app

    blocker = tmp_path / "a_file"
    blocker.write_text("mine\n")
    runner = CliRunner()
    for args in (
        ["calibrate", str(BUNDLED), "-o", str(blocker / "x.yaml")],
        ["calibrate", str(BUNDLED), "-o", str(tmp_path / "m.yaml"), "--report", str(blocker)],
        ["diagnose", str(BUNDLED), "--out", str(blocker / "sub")],
    ):
        res = runner.invoke(app, args)
        assert res.exit_code == 2 and "is a file, so" in res.output and "bench simulations" not in res.output
    res = runner.invoke(app, ["diagnose", str(BUNDLED), "--out", str(tmp_path / "d"), "--effects", " , "])
    assert res.exit_code == 2 and "--effects names no effect; allowed:" in res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]
    res = runner.invoke(app, ["calibrate", str(BUNDLED), "-o", str(tmp_path / "m.yaml"), "--allow-outside"])
    assert res.exit_code == 0, res.output


def test_a_dotted_output_path_is_checked_where_it_writes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``-o nosuch/../notes.yaml`` passed every check (no ``nosuch``, so no file to protect) and then
    replaced notes.yaml, or the input CSV; a CSV named ``...csv`` wrote into results/."""
    from typer.testing import CliRunner

    from somo_sweep.cli.app import app

    monkeypatch.chdir(tmp_path)
    bench = tmp_path / "bench.csv"
    bench.write_bytes(BUNDLED.read_bytes())
    (tmp_path / "notes.yaml").write_text("my notes\n")
    (tmp_path / "report.md").write_text("# My lab report\n")
    runner = CliRunner()
    res = runner.invoke(app, ["calibrate", "bench.csv", "-o", "nosuch/../notes.yaml"])
    assert res.exit_code == 2 and "notes.yaml exists and has no 'somo-sweep' header" in res.output
    res = runner.invoke(app, ["calibrate", "bench.csv", "-o", "nosuch/../bench.csv"])
    assert res.exit_code == 2 and "is this command's input" in res.output
    res = runner.invoke(app, ["diagnose", "bench.csv", "--out", "nosuch/.."])
    assert res.exit_code == 2 and "report.md exists and has no 'somo-sweep' header" in res.output
    res = runner.invoke(app, ["calibrate", "bench.csv", "-o", "r/calibration.json", "--report", "r"])
    assert res.exit_code == 2 and "is a file the report writes in --report r" in res.output
    assert (
        tmp_path / "notes.yaml"
    ).read_text() == "my notes\n" and bench.read_bytes() == BUNDLED.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bench.csv", "notes.yaml", "report.md"]
    from somo_sweep.cli.calibrate import default_output

    assert default_output(Path("...csv"), "calibration") == Path("results/calibration/__")


def test_a_deflection_longer_than_the_finger_is_refused_by_its_line(tmp_path: Path) -> None:
    """A 1000-mm typo on a 100-mm finger gave an unfitted model, "nan%" and exit 0."""
    lines = BUNDLED.read_text().splitlines()
    row = next(i for i, ln in enumerate(lines) if ln.startswith("tip_load,0,0.05,"))
    fields = lines[row].split(",")
    fields[3] = "1000"
    lines[row] = ",".join(fields)
    path = tmp_path / "typo.csv"
    path.write_text("\n".join(lines) + "\n")
    from typer.testing import CliRunner

    from somo_sweep.cli.app import app

    res = CliRunner().invoke(app, ["calibrate", str(path), "-o", str(tmp_path / "m.yaml")])
    assert res.exit_code == 2, res.output
    assert (
        f"line {row + 1}, column tip_deflection_mm: 1000 mm, farther than a 100-mm finger's tip" in res.output
    )
    assert not (tmp_path / "m.yaml").exists()


def test_a_fit_that_could_not_start_writes_nothing_and_exits_1(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from dataclasses import replace

    from typer.testing import CliRunner

    from somo_sweep.calibration import solve, workflow
    from somo_sweep.cli.app import app

    real = solve.solve_paper

    def unfitted(problem, n_jobs=1):  # type: ignore[no-untyped-def]
        result = real(problem, n_jobs)
        return replace(result, message="not fitted: calibration rows without equilibrium", fitted=False)

    monkeypatch.setattr(workflow, "solve_fit", unfitted)
    res = CliRunner().invoke(app, ["calibrate", str(BUNDLED), "-o", str(tmp_path / "m.yaml")])
    assert res.exit_code == 1 and "not fitted: calibration rows without equilibrium" in res.output
    assert "nothing was written" in res.output and not (tmp_path / "m.yaml").exists()


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (
            ("thickness_mm: 15", "thickness_mm: 500"),
            "thickness_mm 500 is more than the finger's length_mm 100",
        ),
        (("length_mm: 100,", "length_mm: 1e9,"), "length_mm must be at most 100000, got 1000000000.0"),
    ],
)
def test_a_finger_line_no_finger_has_is_refused_at_its_line(
    tmp_path: Path, edit: tuple[str, str], message: str
) -> None:
    """Both calibrated with exit 0 (RMSE 7.6e4 N), or failed naming neither the CSV nor the key."""
    from somo_sweep.calibration.finger import read_finger_header

    path = tmp_path / "finger.csv"
    path.write_text(BUNDLED.read_text().replace(*edit))
    with pytest.raises(MeasurementError, match="finger header: " + message.replace(".", r"\.")):
        read_finger_header(path)


@pytest.mark.parametrize(
    ("test", "values", "message"),
    [
        ("tip_load", "5000", "--values 5000 is outside"),
        ("free_bending", "50000", "--values 50000 is outside"),
    ],
)
def test_measure_refuses_values_the_csv_reader_would_refuse(test: str, values: str, message: str) -> None:
    """It printed a tip_load row of 5000 N that calibrate then refused."""
    from typer.testing import CliRunner

    from somo_sweep.cli.app import app

    model = Path(__file__).parents[2] / "somo_sweep" / "data" / "models" / "pinch_finger.yaml"
    res = CliRunner().invoke(app, ["measure", str(model), "--test", test, "--values", values])
    assert res.exit_code == 2 and message in res.output and "allowed:" in res.output


def test_a_column_named_twice_in_the_header_is_refused_by_its_name(tmp_path: Path) -> None:
    """pandas renamed it 'tip_load_n.1' and the message named a column the file does not have."""
    path = tmp_path / "twice.csv"
    path.write_text(HEADER.replace("tip_deflection_mm", "tip_load_n") + "tip_load,0,0.01,1.0,,,\n")
    assert "line 1: column 'tip_load_n' appears more than once in the header" in _error(path)


@pytest.mark.parametrize("force", ["-0.5", "0.5"])
def test_a_constant_blocked_force_is_refused_whatever_the_round_off(tmp_path: Path, force: str) -> None:
    """-0.5 N at every pressure passed on a +3.8e-19 N/kPa round-off slope and fitted a gain of 2e-18."""
    from somo_sweep.calibration.solve import build_problem
    from somo_sweep.model.builders import planar_finger

    lines = [
        ",".join([*f[:4], force, *f[5:]]) if (f := ln.split(","))[0] == "blocked_force" else ln
        for ln in BUNDLED.read_text().splitlines()
    ]
    path = tmp_path / "flat.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(MeasurementError, match="the blocked force does not grow with pressure_kpa"):
        build_problem(read_measurements(path), planar_finger(0.1, 20, 0.02))


def test_calibrate_report_never_replaces_a_users_figure(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from somo_sweep.cli.app import app

    report = tmp_path / "report"
    report.mkdir()
    (report / "tip_load.png").write_text("MINE\n")
    res = CliRunner().invoke(
        app, ["calibrate", str(BUNDLED), "-o", str(tmp_path / "m.yaml"), "--report", str(report)]
    )
    assert res.exit_code == 2 and "is not an earlier copy of this output" in res.output
    assert (report / "tip_load.png").read_text() == "MINE\n" and not (tmp_path / "m.yaml").exists()
    (report / "tip_load.png").unlink()
    for _ in range(2):  # its own figures are replaced
        res = CliRunner().invoke(
            app, ["calibrate", str(BUNDLED), "-o", str(tmp_path / "m.yaml"), "--report", str(report)]
        )
        assert res.exit_code == 0, res.output


def test_a_parameter_the_rows_do_not_determine_is_warned_about(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A constant -0.5 N blocked force used to fit a gain at its bound with a 2.6e12 % error, silently."""
    from dataclasses import replace

    from typer.testing import CliRunner

    from somo_sweep.calibration import solve, workflow
    from somo_sweep.cli.app import app

    real = solve.solve_fit

    def loose(problem, n_jobs=1):  # type: ignore[no-untyped-def]
        result = real(problem, n_jobs)
        return replace(
            result, relative_stderr={**result.relative_stderr, "pressure_gain_n_m_per_kpa": 2.5e10}
        )

    monkeypatch.setattr(workflow, "solve_fit", loose)
    res = CliRunner().invoke(app, ["calibrate", str(BUNDLED), "-o", str(tmp_path / "m.yaml")])
    assert res.exit_code == 0
    assert "warning: pressure_gain_n_m_per_kpa is not determined by these rows" in res.output


@pytest.mark.parametrize(
    ("cell", "message"),
    [
        ("nan", "'nan' is not a measured value; leave the cell empty"),
        ("1_000", "'1_000' is not a number"),
        ("\uff11.\uff10", "'\uff11.\uff10' is not a number"),
        ("inf", "inf is not finite"),
    ],
)
def test_cells_python_would_read_but_a_bench_file_does_not_hold(
    tmp_path: Path, cell: str, message: str
) -> None:
    """'nan' was reported as an empty cell; '1_000' and full-width digits were read as numbers."""
    path = tmp_path / "cells.csv"
    path.write_text(HEADER + f"tip_load,0,0.01,{cell},,,\n", encoding="utf-8")
    assert f"line 2, column tip_deflection_mm: {message}" in _error(path)


def test_old_mac_line_endings_keep_the_finger_line(tmp_path: Path) -> None:
    from somo_sweep.calibration.finger import read_finger_header

    path = tmp_path / "cr.csv"
    path.write_bytes(BUNDLED.read_bytes().replace(b"\n", b"\r"))
    assert read_finger_header(path) == read_finger_header(BUNDLED) is not None
    pd.testing.assert_frame_equal(read_measurements(path), read_measurements(BUNDLED))


def test_a_hash_inside_a_line_is_data_not_a_comment(tmp_path: Path) -> None:
    """'#N/A' in a spreadsheet export dropped the rest of the row: an 'axis' of side became
    none and the row was fitted as a grasp row, the stiffness 31 % off, without a word."""
    lines = BUNDLED.read_text().splitlines()
    path = tmp_path / "na.csv"
    path.write_text("\n".join([*lines, "tip_load,0,0.1,0.6,,,,#N/A,side"]) + "\n")
    assert f"line {len(lines) + 1}, column tip_angle_deg: '#N/A' is not a number" in _error(path)
    path.write_text("\n".join([*lines, "tip_load,0,0.1,9#.14,,,,,grasp"]) + "\n")
    assert f"line {len(lines) + 1}, column tip_deflection_mm: '9#.14' is not a number" in _error(path)


def test_blank_lines_and_indented_comments_keep_every_line_number(tmp_path: Path) -> None:
    lines = BUNDLED.read_text().splitlines()
    header = next(i for i, ln in enumerate(lines) if ln.startswith("test,"))
    body = [*lines[: header + 2], "", "   ", "  # an indented note", *lines[header + 2 :]]
    body[header + 6] = body[header + 6].replace("0.03", "zero", 1)  # the third data row
    path = tmp_path / "gaps.csv"
    path.write_text("\n".join(body) + "\n")
    assert f"line {header + 7}, column tip_load_n: 'zero' is not a number" in _error(path)
    body[header + 6] = lines[header + 3]
    path.write_text("\n".join(body) + "\n")
    pd.testing.assert_frame_equal(
        read_measurements(path).drop(columns="line"), read_measurements(BUNDLED).drop(columns="line")
    )


def test_many_comment_lines_cost_no_more_than_reading_them(tmp_path: Path) -> None:
    """Finding a row's line went over every comment line for every row: 4990 rows and 4 million
    comment lines in an 8 MiB file took 278 s to read."""
    lines = BUNDLED.read_text().splitlines()
    header = next(i for i, ln in enumerate(lines) if ln.startswith("test,"))
    rows = lines[header + 1 :] * (4000 // len(lines[header + 1 :]))
    path = tmp_path / "comments.csv"
    path.write_text("\n".join([*lines[: header + 1], *rows, *["#"] * 1_000_000]) + "\n")
    start = time.perf_counter()
    assert len(read_measurements(path)) == len(rows)
    assert time.perf_counter() - start < 30.0


def test_a_trailing_comma_on_the_data_rows_only_reads_like_the_plain_file(tmp_path: Path) -> None:
    """pandas took the first field of such rows for an index and shifted every value one column:
    "'grasp' is not a number" on every row."""
    lines = BUNDLED.read_text().splitlines()
    header = next(i for i, ln in enumerate(lines) if ln.startswith("test,"))
    path = tmp_path / "trailing.csv"
    path.write_text("\n".join(ln + "," if i > header else ln for i, ln in enumerate(lines)) + "\n")
    pd.testing.assert_frame_equal(read_measurements(path), read_measurements(BUNDLED))
    lines[header + 3] += ",0.5"  # a value past the header: refused, not dropped
    path.write_text("\n".join(lines) + "\n")
    assert f"line {header + 4} has 10 fields, the header (line {header + 1}) 9" in _error(path)


def test_terminal_control_characters_in_a_cell_are_shown_escaped(tmp_path: Path) -> None:
    lines = BUNDLED.read_text().splitlines()
    header = next(i for i, ln in enumerate(lines) if ln.startswith("test,"))
    lines[header + 1] = lines[header + 1].replace("tip_load", "tip\x1b[2J\x1b]0;pwned\x07load", 1)
    path = tmp_path / "esc.csv"
    path.write_text("\n".join(lines) + "\n")
    text = _error(path)
    assert "\x1b" not in text and "\x07" not in text and "tip\\x1b[2J\\x1b]0;pwned\\x07load" in text


def test_the_finger_line_is_found_above_the_header_once(tmp_path: Path) -> None:
    """With 50 comment lines above it, '# finger:' was not found ("add a line '# finger: …'");
    with two, the first silently won."""
    from somo_sweep.calibration.finger import read_finger_header

    lines = BUNDLED.read_text().splitlines()
    finger = next(ln for ln in lines if ln.startswith("# finger:"))
    path = tmp_path / "notes.csv"
    path.write_text("\n".join([*(f"# note {i}" for i in range(60)), *lines]) + "\n")
    assert read_finger_header(path) == read_finger_header(BUNDLED)
    path.write_text("\n".join([finger.replace("segments: 20", "segments: 10"), *lines]) + "\n")
    with pytest.raises(MeasurementError, match="the finger header is given twice"):
        read_finger_header(path)


def test_finger_flags_are_held_to_the_header_rules_and_named(tmp_path: Path) -> None:
    """--segments 150 failed on PyBullet's link limit without the file or the flag; --width-mm 500
    (refused in the header) passed."""
    from somo_sweep.calibration.finger import finger_from_header, read_finger_header

    header = read_finger_header(BUNDLED)
    assert header is not None
    with pytest.raises(
        MeasurementError, match=r"with --segments 150: segments must be a whole number from 1 to 126"
    ):
        finger_from_header(header, str(BUNDLED), segments=150)
    with pytest.raises(
        MeasurementError, match=r"with --width-mm 500: width_mm 500.0 is more than the finger's length"
    ):
        finger_from_header(header, str(BUNDLED), width_mm=500.0)
    assert finger_from_header(header, str(BUNDLED), segments=126).manipulator is not None


def test_a_quoted_line_break_keeps_the_later_line_numbers(tmp_path: Path) -> None:
    """A quoted field holding a line break joined two lines: every later row was named one line early."""
    lines = BUNDLED.read_text().splitlines()
    header = next(i for i, ln in enumerate(lines) if ln.startswith("test,"))
    first = lines[header + 1].split(",")
    broken = ",".join([*first[:-1], '"gr\nasp"'])  # the axis cell of the first row, over two lines
    lines[header + 1] = broken
    lines[header + 5] = lines[header + 5].replace("0.05", "zero", 1)  # the fifth data row
    path = tmp_path / "break.csv"
    path.write_text("\n".join(lines) + "\n")
    text = _error(path)
    assert f"line {header + 2}, column axis: 'gr\\nasp' is not allowed (did you mean 'grasp'?)" in text
    assert f"line {header + 7}, column tip_load_n: 'zero' is not a number" in text  # one line later
    lines[header + 5] = BUNDLED.read_text().splitlines()[header + 5]
    lines[header + 1] = ",".join([*first[:-1], '"gra""\nsp,"', *first[-1:]])  # a quote, then more fields
    path.write_text("\n".join(lines) + "\n")
    assert f"line {header + 2} has 10 fields" in _error(path)


def test_a_quote_never_closed_is_named_by_its_line(tmp_path: Path) -> None:
    lines = BUNDLED.read_text().splitlines()
    header = next(i for i, ln in enumerate(lines) if ln.startswith("test,"))
    lines[header + 3] = lines[header + 3].replace(",grasp", ',"grasp')
    path = tmp_path / "open.csv"
    path.write_text("\n".join(lines) + "\n")
    assert f'line {header + 4}: a field opens a quote (") that is never closed' in _error(path)


def test_a_stray_quote_inside_a_field_joins_no_lines(tmp_path: Path) -> None:
    """A quote that does not start a field is a character (5" for inches), not an open quote."""
    lines = BUNDLED.read_text().splitlines()
    header = next(i for i, ln in enumerate(lines) if ln.startswith("test,"))
    lines[header + 1] = lines[header + 1].replace(",grasp", ',gr"asp')
    lines[header + 3] = lines[header + 3].replace("0.03", "zero", 1)
    path = tmp_path / "stray.csv"
    path.write_text("\n".join(lines) + "\n")
    text = _error(path)
    assert f"line {header + 2}, column axis: 'gr\"asp' is not allowed" in text
    assert f"line {header + 4}, column tip_load_n: 'zero' is not a number" in text


@pytest.mark.parametrize(
    ("command", "name"), [("calibrate", "calibration.json"), ("diagnose", "diagnosis.json")]
)
def test_a_users_own_json_report_is_never_replaced(tmp_path: Path, command: str, name: str) -> None:
    """A user's own calibration.json / diagnosis.json in the report folder was replaced: any JSON
    passed for ours. Ours now carry "written_by": "somo-sweep COMMAND"."""
    from typer.testing import CliRunner

    from somo_sweep.cli.app import app

    report = tmp_path / "report"
    report.mkdir()
    mine = '{"my": "lab notes", "method": "by hand"}\n'
    (report / name).write_text(mine)
    where = ["--report", str(report), "-o", str(tmp_path / "m.yaml")] if command == "calibrate" else []
    args = [command, str(BUNDLED), *(where or ["--out", str(report)]), "--model", "ihm_finger"]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 2, res.output
    assert (
        f'{report / name} exists and has no "written_by": "somo-sweep …" key: somo-sweep did not write it, '
        "so it is not replaced; nothing was written"
    ) in res.output
    assert "bench simulations" not in res.output and (report / name).read_text() == mine
    assert sorted(p.name for p in report.iterdir()) == [name] and not (tmp_path / "m.yaml").exists()


def test_calibrate_marks_its_json_report_and_replaces_it_and_an_older_unmarked_one(tmp_path: Path) -> None:
    import json

    from typer.testing import CliRunner

    from somo_sweep.cli.app import app

    report = tmp_path / "report"
    args = [
        "calibrate",
        str(BUNDLED),
        "--method",
        "paper",
        "-o",
        str(tmp_path / "m.yaml"),
        "--report",
        str(report),
    ]
    assert CliRunner().invoke(app, args).exit_code == 0
    written = json.loads((report / "calibration.json").read_text())
    assert next(iter(written.items())) == ("written_by", "somo-sweep calibrate")
    older = {k: v for k, v in written.items() if k != "written_by"}  # as an earlier version wrote it
    (report / "calibration.json").write_text(json.dumps(older))
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    assert json.loads((report / "calibration.json").read_text())["written_by"] == "somo-sweep calibrate"


def test_a_huge_field_on_a_row_with_an_extra_field_names_its_line(tmp_path: Path) -> None:
    """pandas' own message counted records, not file lines ("line 2" for line 3), or none at all."""
    path = tmp_path / "m.csv"
    path.write_text("# a comment\n" + HEADER + 'tip_load,0,0.01,0.5,,,,,grasp,"' + "x" * 2_000_000 + '"\n')
    text = _error(path)
    assert "line 3: a field is longer than 131072 characters" in text and len(text) < 1000


def test_an_unknown_column_names_the_header_line(tmp_path: Path) -> None:
    path = tmp_path / "m.csv"
    path.write_text("# a comment\n" + HEADER.rstrip("\n") + ",z" + "x" * 1_000_000 + "\n")
    assert "line 2: unknown column 'zxxx" in _error(path)
