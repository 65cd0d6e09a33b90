"""The finger a measurement CSV describes, read from its machine-readable header line.

A bench CSV may state its finger in one comment line above the header, a YAML mapping::

    # finger: {length_mm: 100, segments: 20, mass_g: 20, width_mm: 20, thickness_mm: 15}

so ``somo-sweep calibrate measurements.csv`` needs nothing else. ``length_mm``, ``segments``
and ``mass_g`` are required; ``width_mm`` (20), ``thickness_mm`` (15) and ``joint_placement``
(``midpoint``) are optional. Command-line flags override the header, ``--model`` replaces it.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from somo_sweep.calibration.bench_file import BenchFile, read_bench_file
from somo_sweep.errors import MeasurementError
from somo_sweep.model.builders import DEFAULT_THICKNESS_M, DEFAULT_WIDTH_M, planar_finger
from somo_sweep.model.description import MAX_LENGTH_M, MAX_MASS_KG
from somo_sweep.model.files import parse_yaml_value
from somo_sweep.model.load import Model

__all__ = ["FINGER_KEYS", "finger_from_header", "finger_header", "header_mapping", "read_finger_header"]

#: Header keys with their meaning; the first three are required.
FINGER_KEYS = {
    "length_mm": "bending length, mm",
    "segments": "number of links (and joints), 1-200",
    "mass_g": "mass of the bending part, g; 0: weightless",
    "width_mm": "link width along the joint axis, mm",
    "thickness_mm": "link thickness in the bending direction, mm",
    "joint_placement": "midpoint or start",
}
REQUIRED = ("length_mm", "segments", "mass_g")
#: Most segments of the planar finger: with its base and tip link, PyBullet's 128 links of a body.
MAX_FINGER_SEGMENTS = 126
_PREFIX = "# finger:"
#: Longest header line read, in bytes of UTF-8 (a longer one is refused).
_MAX_LINE_BYTES = 4096


def read_finger_header(path: str | Path) -> dict[str, Any] | None:
    """The ``# finger:`` mapping of a CSV file, validated (:func:`finger_header` of the file read)."""
    return finger_header(read_bench_file(path))


def finger_header(file: BenchFile) -> dict[str, Any] | None:
    """The ``# finger:`` mapping of a bench file, validated; None when it has no such line.

    Raises:
        MeasurementError: A header line that is not a mapping, an unknown key, a missing
            required key or a value out of range (the message names the line and the key).
    """
    found = header_mapping(file, _PREFIX, "finger header", "{length_mm: 100, segments: 20, mass_g: 20}")
    if found is None:
        return None
    number, data = found
    return _validate(file.path, f"line {number}, finger header", data)


def header_mapping(
    file: BenchFile, prefix: str, what: str, example: str
) -> tuple[int, dict[Any, Any]] | None:
    """The YAML mapping of a ``# <key>:`` comment line above a CSV's header, with its line number.

    Header lines belong among the comment lines above the column header. None when there is no
    such line.

    Raises:
        MeasurementError: The line given twice, too long, not a mapping, or placed after the
            column header, where it would not be read (naming the line).
    """
    path = file.path
    found: list[tuple[int, str]] = []
    header = 0  # the column header's line
    for number, raw in enumerate(file.lines, start=1):
        line = raw.strip()
        if header and not line.startswith("#"):
            continue  # a data row (only the comments after the header are looked at)
        if line and not line.startswith("#") and not header:
            header = number
        elif line.lower().startswith(prefix):
            found.append((number, line))
    late = [n for n, _ in found if header and n > header]
    if late:
        raise MeasurementError(
            path,
            [
                f"line {late[0]}: the {what} is after the column header (line {header}), where it is "
                f"not read; allowed: one '{prefix}' line above the header"
            ],
        )
    if len(found) > 1:
        lines = " and ".join(str(n) for n, _ in found[:2])
        raise MeasurementError(
            path, [f"lines {lines}: the {what} is given twice; allowed: one '{prefix}' line"]
        )
    for number, line in found:
        where = f"line {number}, {what}"
        hint = f"write a mapping, e.g. {example}"
        if len(line.encode("utf-8")) > _MAX_LINE_BYTES:
            raise MeasurementError(
                path, [f"{where}: longer than {_MAX_LINE_BYTES} bytes; allowed: one short line; {hint}"]
            )
        try:
            data = parse_yaml_value(line[len(prefix) :])
        except ValueError as exc:
            raise MeasurementError(path, [f"{where}: {exc}; {hint}"]) from None
        if not isinstance(data, dict):
            raise MeasurementError(path, [f"{where}: {hint}"])
        return number, data
    return None


def _validate(path: Path, where: str, data: dict[Any, Any]) -> dict[str, Any]:
    problems = [
        f"{where}: unknown key '{k}'; allowed: {', '.join(FINGER_KEYS)}" for k in data if k not in FINGER_KEYS
    ]
    problems += [f"{where}: {k} ({FINGER_KEYS[k]}) is required" for k in REQUIRED if k not in data]
    for key in ("length_mm", "mass_g", "width_mm", "thickness_mm"):
        value = data.get(key)
        least = 0 if key == "mass_g" else None  # 0 g: a weightless finger (its weight left out)
        if value is not None and not (
            isinstance(value, int | float)
            and not isinstance(value, bool)
            and math.isfinite(value)
            and (value > 0 or value == least)
        ):
            bound = ">= 0" if least == 0 else "> 0"
            problems.append(f"{where}: {key} must be a finite number {bound}, got {value!r}")
    if not problems:
        length = data.get("length_mm")
        if length is not None and length > MAX_LENGTH_M * 1e3:
            problems.append(f"{where}: length_mm must be at most {MAX_LENGTH_M * 1e3:g}, got {length!r}")
        for key in ("width_mm", "thickness_mm"):
            value = data.get(key)
            if value is not None and length is not None and value > length:
                problems.append(
                    f"{where}: {key} {value!r} is more than the finger's length_mm {length!r}; "
                    "allowed: at most the length (a cross-section, in mm)"
                )
        mass = data.get("mass_g")
        if mass is not None and mass > MAX_MASS_KG * 1e3:
            problems.append(f"{where}: mass_g must be at most {MAX_MASS_KG * 1e3:g}, got {mass!r}")
    segments = data.get("segments")
    if segments is not None and not (
        isinstance(segments, int) and not isinstance(segments, bool) and 1 <= segments <= MAX_FINGER_SEGMENTS
    ):
        problems.append(
            f"{where}: segments must be a whole number from 1 to {MAX_FINGER_SEGMENTS} (a base, the "
            f"segments and a tip in PyBullet's 128 links of a body), got {segments!r}"
        )
    if data.get("joint_placement", "midpoint") not in ("midpoint", "start"):
        problems.append(
            f"{where}: joint_placement must be midpoint or start, got {data['joint_placement']!r}"
        )
    if problems:
        raise MeasurementError(path, problems)
    return dict(data)


def finger_from_header(header: dict[str, Any], source: str | Path = "<flags>", **overrides: Any) -> Model:
    """The planar finger of a header (mm and g as written), with flag values overriding it.

    Flag values are held to the header's rules (``--segments 150`` was refused later by the
    body's link limit, without the file or the flag; ``--width-mm 500`` passed).

    Raises:
        MeasurementError: A flag value the header would refuse, named as the flag.
    """
    given = {k: v for k, v in overrides.items() if v is not None}
    values = {**header, **given}
    if given:
        flags = ", ".join(f"--{k.replace('_', '-')} {v:g}" for k, v in given.items())
        _validate(Path(source), f"with {flags}", values)
    return planar_finger(
        float(values["length_mm"]) * 1e-3,
        int(values["segments"]),
        float(values["mass_g"]) * 1e-3,
        float(values.get("width_mm", DEFAULT_WIDTH_M * 1e3)) * 1e-3,
        float(values.get("thickness_mm", DEFAULT_THICKNESS_M * 1e3)) * 1e-3,
        joint_placement=str(values.get("joint_placement", "midpoint")),
    )
