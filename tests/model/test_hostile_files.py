"""Hostile model files: bombs, huge and binary files, repeated keys, NaN, escaping includes, odd names.

Every one fails fast with one message naming the file, the key path (and line), the bad
value and what is allowed; none gets as far as PyBullet.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
import yaml
from conftest import MODELS, load_yaml
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import DescriptionError
from somo_sweep.model.files import MAX_FILE_BYTES, load_mapping
from somo_sweep.model.load import MAX_BODY_LINKS, load_model, model_from_dict

#: Nine levels of nine-way aliases: 9⁹ ≈ 387 million values once expanded.
BOMB = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{c}: &{c} [" + ", ".join([f"*{p}"] * 9) + "]\n" for p, c in zip("abcdefgh", "bcdefghi", strict=True)
)


def _error(path: Path) -> str:
    with pytest.raises(DescriptionError) as info:
        load_model(path)
    return str(info.value)


def _write(tmp_path: Path, text: str, name: str = "m.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_an_alias_bomb_is_refused_at_once(tmp_path: Path) -> None:
    path = _write(tmp_path, BOMB + "manipulator: *i\n")
    start = time.perf_counter()
    text = _error(path)
    assert time.perf_counter() - start < 1.0
    assert "expands to more than 100000 values (YAML aliases included); allowed: at most 100000" in text
    assert text.startswith(f"{path}: 1 problem(s)")


def test_a_self_referencing_alias_is_refused(tmp_path: Path) -> None:
    text = _error(_write(tmp_path, "manipulator: &m {actuators: [*m]}\n"))
    assert "a YAML alias refers to itself (a recursive structure)" in text


def test_a_file_above_the_size_limit_is_refused_before_parsing(tmp_path: Path) -> None:
    path = tmp_path / "big.yaml"
    path.write_bytes(b"manipulator: {}\n" + b"#" * MAX_FILE_BYTES)
    assert f"file is {MAX_FILE_BYTES + 16} bytes; allowed: at most 4 MiB" in _error(path)


@pytest.mark.parametrize(
    "body",
    [
        "[" * 100 + "]" * 100,  # past our limit, within libyaml's
        "[" * 5000 + "]" * 5000,  # past libyaml's 1000 levels too (its own error since PyYAML 6.0.4)
        "\n" + "".join(" " * (2 * i + 2) + "-\n" for i in range(1500)),  # block style, 1500 levels
    ],
    ids=["flow-100", "flow-5000", "block-1500"],
)
def test_deep_nesting_is_refused_not_a_recursion_error(tmp_path: Path, body: str) -> None:
    text = _error(_write(tmp_path, "manipulator: " + body + "\n"))
    assert "nested deeper than 64 levels; allowed: at most 64" in text


def test_nesting_at_the_limit_is_read(tmp_path: Path) -> None:
    path = _write(tmp_path, "manipulator: {}\nnote: " + "[" * 63 + "]" * 63 + "\n")
    data, _ = load_mapping(path)
    assert isinstance(data["note"], list)


def test_a_latin1_byte_names_its_offset(tmp_path: Path) -> None:
    path = tmp_path / "latin1.yaml"
    path.write_bytes("manipulator:\n  name: café\n".encode("latin-1"))
    assert f"{path}: 1 problem(s)\n  - <top level>: not UTF-8 text: byte 0xe9 at offset 24" in _error(path)


def test_a_binary_file_is_named_binary(tmp_path: Path) -> None:
    path = tmp_path / "model.yaml"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR")
    assert "binary file (NUL byte at offset 8); allowed: UTF-8 text" in _error(path)


def test_a_key_given_twice_names_the_key_and_both_lines(tmp_path: Path) -> None:
    text = (MODELS / "ihm_finger.yaml").read_text()
    path = _write(
        tmp_path, text.replace("      length_m: 0.100\n", "      length_m: 0.100\n      length_m: 0.120\n")
    )
    assert (
        "line 11: manipulator.actuators[0].length_m: key 'length_m' is given twice "
        "(lines 10 and 11); allowed: each key once per mapping"
    ) in _error(path)


def test_a_key_given_twice_in_json_is_refused_with_both_lines(tmp_path: Path) -> None:
    path = _write(
        tmp_path, '{"manipulator": {\n  "name": "a",\n  "name": "b"},\n "manipulator": {}}', "m.json"
    )
    text = _error(path)
    assert "line 3: manipulator.name: key 'name' is given twice (lines 2 and 3); allowed: each" in text
    assert "line 4: manipulator: key 'manipulator' is given twice (lines 1 and 4)" in text


def test_json_model_errors_name_their_lines_as_yaml_ones_do(tmp_path: Path) -> None:
    """A JSON model's problems had key paths but no lines."""
    data = load_yaml("ihm_finger.yaml")
    data["manipulator"]["actuators"][0]["lenght_m"] = 1
    data["manipulator"]["actuators"][0]["link"]["mass_kg"] = -1
    text = json.dumps(data, indent=2)

    def line_of(fragment: str) -> int:
        return next(n for n, ln in enumerate(text.splitlines(), start=1) if fragment in ln)

    problems = _error(_write(tmp_path, text, "m.json"))
    assert f"line {line_of('lenght_m')}: manipulator.actuators[0].lenght_m: unknown key" in problems
    mass = line_of('"mass_kg": -1')
    assert f"line {mass}: manipulator.actuators[0].link.mass_kg: Input should be" in problems
    data["manipulator"]["tip_links"][0]["radius_m"] = float("nan")
    text = json.dumps(data, indent=2)
    problems = _error(_write(tmp_path, text, "m.json"))
    assert f"line {line_of('NaN')}: manipulator.tip_links[0].radius_m: must be a finite number" in problems
    one_line = _error(_write(tmp_path, json.dumps(data), "flat.json"))  # all on line 1
    assert "line 1: manipulator.tip_links[0].radius_m" in one_line


def test_json_line_numbers_survive_escapes_and_nesting(tmp_path: Path) -> None:
    from somo_sweep.model.files import load_mapping

    text = '{"a": {"b\\"": [1, {"c": "x,:{}[]\\\\"}, [3,\n 4]]},\n\n  "e": [\n\n  {"f": 1}]}'
    data, lines = load_mapping(_write(tmp_path, text, "t.json"))
    assert data["a"]['b"'][1]["c"] == "x,:{}[]\\"
    assert lines['a.b"[2][1]'] == 2 and lines["e"] == 4 and lines["e[0]"] == 6 and lines["e[0].f"] == 6


@pytest.mark.parametrize("suffix", [".yaml", ".json"])
def test_include_errors_name_the_line_of_their_file_key(tmp_path: Path, suffix: str) -> None:
    """An include that could not be read named its key path but no line."""
    gripper = yaml.safe_load((MODELS / "pinch_gripper.yaml").read_text())
    for mount in gripper["assembly"]["manipulators"]:
        mount["file"] = "missing.yaml"
    text = yaml.safe_dump(gripper, sort_keys=False) if suffix == ".yaml" else json.dumps(gripper, indent=2)
    where = [n for n, ln in enumerate(text.splitlines(), start=1) if "missing.yaml" in ln]
    problems = _error(_write(tmp_path, text, f"g{suffix}"))
    for i, line in enumerate(where):
        assert f"line {line}: assembly.manipulators[{i}].file: cannot include" in problems


@pytest.mark.parametrize("value", [".nan", ".inf", "-.inf"])
def test_nan_and_infinity_are_refused_with_their_key_path(tmp_path: Path, value: str) -> None:
    text = (MODELS / "ihm_finger.yaml").read_text().replace("length_m: 0.100", f"length_m: {value}", 1)
    shown = {".nan": "nan", ".inf": "inf", "-.inf": "-inf"}[value]
    assert f"manipulator.actuators[0].length_m: must be a finite number, got {shown}" in _error(
        _write(tmp_path, text)
    )


def test_nan_in_a_python_dict_is_refused_by_the_schema() -> None:
    data = load_yaml("ihm_finger.yaml")
    data["manipulator"]["actuators"][0]["joints"][0]["stiffness_n_m_per_rad"] = float("inf")
    with pytest.raises(DescriptionError, match=r"stiffness_n_m_per_rad: Input should be a finite number"):
        model_from_dict(data)


def test_a_parse_error_never_quotes_the_file(tmp_path: Path) -> None:
    path = _write(tmp_path, "manipulator:\n  name: [secret-token-123\n")
    text = _error(path)
    assert "cannot parse: while parsing a flow sequence" in text and "secret-token-123" not in text


def _gripper(tmp_path: Path, ref: str) -> Path:
    text = (MODELS / "pinch_gripper.yaml").read_text().replace("file: pinch_finger.yaml", f"file: {ref}")
    sub = tmp_path / "models"
    sub.mkdir(exist_ok=True)
    return _write(sub, text, "gripper.yaml")


@pytest.mark.parametrize("ref", ["../../../../../../etc/passwd", "/etc/passwd"], ids=["dotdot", "absolute"])
def test_an_include_may_not_leave_the_model_folder(tmp_path: Path, ref: str) -> None:
    text = _error(_gripper(tmp_path, ref))
    assert f"assembly.manipulators[0].file: cannot include '{ref}'" in text
    assert "allowed: a path inside the model file's folder (or pass --allow-outside)" in text
    assert "root:" not in text


def test_allow_outside_lets_an_include_go_up(tmp_path: Path) -> None:
    (tmp_path / "shared").mkdir()
    (tmp_path / "shared" / "finger.yaml").write_text((MODELS / "pinch_finger.yaml").read_text())
    path = _gripper(tmp_path, "../shared/finger.yaml")
    assert "leaves the folder" in _error(path)
    assert load_model(path, allow_outside=True).assembly is not None


def test_an_included_file_that_cannot_be_parsed_is_reported_without_its_content(tmp_path: Path) -> None:
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "notes.yaml").write_text("password: [hunter2\n")
    text = _error(_gripper(tmp_path, "notes.yaml"))
    assert "assembly.manipulators[0].file: cannot include" in text and "cannot parse" in text
    assert "hunter2" not in text


@pytest.mark.parametrize("name", ["a&b", "x<y>", 'q"uote', "it's", "sp ace"])
def test_names_outside_the_safe_pattern_are_refused(name: str) -> None:
    data = load_yaml("ihm_finger.yaml")
    data["manipulator"]["name"] = name
    with pytest.raises(DescriptionError) as info:
        model_from_dict(data, "m.yaml")
    assert (
        "manipulator.name: a name may hold only letters, digits, '_', '.' and '-' "
        f"(pattern [A-Za-z0-9_.-]+), got {name!r}"
    ) in str(info.value)


def test_more_segments_than_an_actuator_may_have_is_refused() -> None:
    data = load_yaml("ihm_finger.yaml")
    data["manipulator"]["actuators"][0]["n_segments"] = 10000
    with pytest.raises(DescriptionError) as info:
        model_from_dict(data, "m.yaml")
    assert "manipulator.actuators[0].n_segments: Input should be less than or equal to 200, got 10000" in str(
        info.value
    )


@pytest.mark.parametrize(
    ("where", "what", "limit"),
    [("manipulators", "manipulators", 100), ("bodies", "rigid bodies", 256)],
)
def test_an_assembly_with_thousands_of_parts_is_refused_at_once(where: str, what: str, limit: int) -> None:
    # 2500 fingers of 122 links each took 3 min and 0.9 GB to check before the limit.
    finger = load_yaml("ihm_finger.yaml")["manipulator"]
    box = {"shape": "box", "size_m": [0.01, 0.01, 0.01], "mass_kg": 0.01}
    items = {
        "manipulators": [{"name": f"f{i}", "manipulator": finger} for i in range(2500)],
        "bodies": [{"name": f"b{i}", "link": box} for i in range(2500)],
    }
    assembly = {"manipulators": [{"name": "f", "manipulator": finger}], where: items[where]}
    start = time.perf_counter()
    with pytest.raises(DescriptionError) as info:
        model_from_dict({"assembly": assembly}, "m.yaml")
    assert time.perf_counter() - start < 5.0
    assert f"assembly.{where}: 2500 {what}; allowed: at most {limit}" in str(info.value)


def test_a_manipulator_with_more_actuators_than_a_body_has_links_is_refused() -> None:
    data = load_yaml("ihm_finger.yaml")
    act = data["manipulator"]["actuators"][0]
    data["manipulator"]["actuators"] = [{**act, "name": f"a{i}"} for i in range(200)]
    with pytest.raises(DescriptionError, match=r"manipulator.actuators: 200 actuators; allowed: at most 127"):
        model_from_dict(data, "m.yaml")
    data["manipulator"]["actuators"] = [act]
    data["manipulator"]["tip_links"] = [{"shape": "sphere", "radius_m": 0.01, "mass_kg": 0.01}] * 128
    with pytest.raises(DescriptionError, match=r"manipulator.tip_links: 128 tip links; allowed: at most 127"):
        model_from_dict(data, "m.yaml")


def test_a_tiny_segment_length_is_refused_before_building_anything() -> None:
    data = load_yaml("ihm_finger.yaml")
    act = data["manipulator"]["actuators"][0]
    del act["n_segments"]
    act["segment_length_m"] = 1e-5
    with pytest.raises(DescriptionError, match=r"= 10000 segments; allowed: at most 200"):
        model_from_dict(data, "m.yaml")
    act["segment_length_m"] = 1e-9  # below any link dimension
    with pytest.raises(
        DescriptionError, match=r"segment_length_m: Input should be greater than or equal to 0.000001"
    ):
        model_from_dict(data, "m.yaml")


def test_a_body_above_pybullets_link_limit_is_refused_naming_the_limit() -> None:
    data = load_yaml("ihm_finger.yaml")
    data["manipulator"]["actuators"][0]["n_segments"] = 150
    with pytest.raises(DescriptionError) as info:
        model_from_dict(data, "m.yaml")
    assert (
        f"manipulator: body 'ihm_finger' has 152 links; allowed: at most {MAX_BODY_LINKS} links per body "
        "(PyBullet's multibody limit: a base and 127 jointed links)"
    ) in str(info.value)


def test_check_refuses_a_huge_body_cleanly(tmp_path: Path) -> None:
    text = (MODELS / "ihm_finger.yaml").read_text().replace("n_segments: 10", "n_segments: 1000")
    res = CliRunner().invoke(app, ["check", str(_write(tmp_path, text))])
    assert res.exit_code == 2 and "less than or equal to 200, got 1000" in res.output
    assert "Traceback" not in res.output


def test_loading_stays_fast_at_the_value_limit(tmp_path: Path) -> None:
    path = _write(tmp_path, "manipulator:\n  tip_links: [" + ", ".join(["1"] * 150_000) + "]\n")
    start = time.perf_counter()
    with pytest.raises(DescriptionError, match="holds more than 100000 values"):
        load_mapping(path)
    assert time.perf_counter() - start < 2.0


def test_measure_refuses_a_huge_body_instead_of_crashing(tmp_path: Path) -> None:
    text = (MODELS / "ihm_finger.yaml").read_text().replace("n_segments: 10", "n_segments: 10000")
    args = ["measure", str(_write(tmp_path, text)), "--test", "free_bending", "--values", "10"]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert "n_segments: Input should be less than or equal to 200, got 10000" in res.output


def test_a_folder_or_a_device_is_named_for_what_it_is(tmp_path: Path) -> None:
    assert "<top level>: not a regular file (a folder); allowed: a text file" in _error(tmp_path)
    assert "not a regular file (a device, pipe or socket)" in _error(Path("/dev/null"))
    assert "<top level>: file not found" in _error(tmp_path / "missing.yaml")


@pytest.mark.parametrize("suffix", [".json", ".yaml"])
def test_a_utf8_byte_order_mark_is_read_and_keeps_the_line_numbers(tmp_path: Path, suffix: str) -> None:
    text = (
        '{"manipulator": {"name": "f"}, "unknown": 1}'
        if suffix == ".json"
        else "manipulator: {}\nunknown: 1\n"
    )
    path = tmp_path / f"m{suffix}"
    path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    message = _error(path)
    assert "unknown key 'unknown'" in message and "BOM" not in message
    if suffix == ".yaml":
        assert "line 2: unknown" in message


def test_utf16_is_named_with_what_to_do(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_bytes("manipulator: {}\n".encode("utf-16"))
    assert "UTF-16 text (byte-order mark ff fe); allowed: UTF-8, save the file as UTF-8" in _error(path)


def test_exponents_without_a_decimal_point_are_numbers(tmp_path: Path) -> None:
    # PyYAML (YAML 1.1) reads 1e-3 as the text "1e-3"; every other reader has it a number.
    path = _write(tmp_path, 'a: 1e-3\nb: [2E5, -3e+2, .5e1, 1.5e-3]\nc: "1e-3"\nd: 1e\ne: 10\n')
    data, lines = load_mapping(path)
    assert data == {"a": 0.001, "b": [200000.0, -300.0, 5.0, 0.0015], "c": "1e-3", "d": "1e", "e": 10}
    assert isinstance(data["a"], float) and lines["b"] == 2
    assert yaml.safe_load("1e-3") == "1e-3"  # PyYAML's own loader is left as it is


def test_a_model_written_with_exponents_is_the_same_model(tmp_path: Path) -> None:
    text = (MODELS / "pinch_finger.yaml").read_text()
    assert "mass_kg: 0.0025" in text and "pressure_gain_n_m_per_kpa: 1.5e-3" in text
    plain = _write(tmp_path, text, "plain.yaml")
    exp = _write(
        tmp_path,
        text.replace("mass_kg: 0.0025", "mass_kg: 25e-4").replace("1.5e-3", "15e-4"),
        "exp.yaml",
    )
    assert load_model(exp) == load_model(plain)


@pytest.mark.parametrize("length", [65, 1017, 1500, 100_000])
def test_a_name_too_long_is_refused_at_load_not_by_pybullet(length: int) -> None:
    """1017-1250 characters made PyBullet mis-load the chain (a traceback), 1500 crashed it."""
    data = load_yaml(MODELS / "pinch_finger.yaml")
    data["manipulator"]["name"] = "x" * length
    with pytest.raises(DescriptionError, match=f"a name may be at most 64 characters long, got {length}"):
        model_from_dict(data, "long.yaml")
    data["manipulator"]["name"] = "x" * 64
    assert model_from_dict(data, "long.yaml").manipulator is not None


@pytest.mark.parametrize(("key", "path"), [("n_segments", ("actuators", 0)), ("mass_kg", ("base", "link"))])
def test_a_boolean_where_a_number_belongs_is_refused(key: str, path: tuple[object, ...]) -> None:
    """``n_segments: true`` built a one-segment actuator."""
    data = load_yaml(MODELS / "pinch_finger.yaml")
    node = data["manipulator"]
    for step in path:
        node = node[step]  # type: ignore[index]
    node[key] = True  # type: ignore[index]
    with pytest.raises(DescriptionError, match=f"{key}: expected a number, not a boolean"):
        model_from_dict(data, "bool.yaml")


def test_a_bad_value_in_an_included_file_is_named_by_that_file_and_its_line(tmp_path: Path) -> None:
    """It was named by the including file's 'file:' line and the merged key path."""
    (tmp_path / "m").mkdir()
    text = (MODELS / "pinch_finger.yaml").read_text()
    number = next(i for i, ln in enumerate(text.splitlines(), start=1) if "length_m:" in ln)
    first = text.splitlines()[number - 1]
    (tmp_path / "m" / "neg.yaml").write_text(text.replace(first, first.split(":")[0] + ": -1", 1))
    (tmp_path / "a.yaml").write_text(
        "assembly:\n  name: asm\n  base: {mode: fixed, link: {shape: box, size_m: [0.05, 0.05, 0.01], "
        "mass_kg: 0.5}}\n  manipulators:\n    - {name: f1, file: m/neg.yaml}\n"
    )
    with pytest.raises(DescriptionError) as info:
        load_model(tmp_path / "a.yaml")
    assert f"m/neg.yaml: line {number}: manipulator.actuators[0].length_m" in str(info.value)


def test_a_file_with_many_problems_lists_twenty_and_counts_them_all(tmp_path: Path) -> None:
    data = load_yaml("ihm_finger.yaml")
    data["manipulator"].update({f"unknown_{i}": 1 for i in range(25)})
    with pytest.raises(DescriptionError) as info:
        model_from_dict(data, "m.yaml")
    text = str(info.value)
    assert len(info.value.problems) == 25 and text.startswith("m.yaml: 25 problem(s)\n")
    assert text.count("\n  - ") == 20 and text.endswith("\n  … and 5 more problem(s)")


@pytest.mark.parametrize("command", [["check"], ["run", "--dry-run"], ["calibrate"], ["diagnose"]])
def test_a_symbolic_link_loop_is_named_a_loop_not_a_missing_file(tmp_path: Path, command: list[str]) -> None:
    """A study that is a link loop was reported as "file not found"."""
    (tmp_path / "a.yaml").symlink_to(tmp_path / "b.yaml")
    (tmp_path / "b.yaml").symlink_to(tmp_path / "a.yaml")
    res = CliRunner().invoke(app, [command[0], str(tmp_path / "a.yaml"), *command[1:]])
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert "a symbolic link on the way leads back to itself, a link loop (Too many levels" in res.output
    assert "remove or repair that link" in res.output and "not found" not in res.output


def test_a_study_whose_model_is_a_link_to_nothing_says_so(tmp_path: Path) -> None:
    (tmp_path / "gone.yaml").symlink_to(tmp_path / "deleted.yaml")
    study = tmp_path / "s.yaml"
    study.write_text("task: selftest_sleep\nmodel: gone.yaml\n")
    res = CliRunner().invoke(app, ["run", str(study), "--dry-run"])
    assert res.exit_code == 2
    link, target = tmp_path / "gone.yaml", tmp_path / "deleted.yaml"
    assert f"model file {link}: a symbolic link to {target}, which does not exist" in res.output
