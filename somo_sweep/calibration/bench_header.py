"""The bench a measurement CSV was taken on, read from its ``# bench:`` header line.

A bench CSV may state its blocked-force stop, in one comment line above the header::

    # bench: {stop_z_mm: -9, stop: fingertip}

``stop_z_mm``: height of the stop's top face relative to the straight finger's centre line, mm
(z up: negative is below the finger). Without it the stop is at the straight finger's
underside, half the link thickness below the centre line (the protocol of
``somo-sweep measure`` and of the bundled tables). A stop above that underside (the finger
would start inside it) or more than the finger's length below the centre line (it could never
reach it) is refused once the finger is known, naming the line; so is a second ``# bench:``
line, an unknown key or a value that is no number.

``stop``: ``plate`` (the default: a plate under the whole finger, which carries every link
lying on it) or ``fingertip`` (a stop that touches only the finger's end, such as a load cell
under the fingertip: the clamp holds the rest of the finger's weight). A finger heavy for its
stiffness lies on a plate at low pressure and puts its whole weight on it; on a fingertip stop
it puts about 3/8 of it there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from somo_sweep.calibration.bench_file import BenchFile, read_bench_file
from somo_sweep.calibration.finger import header_mapping
from somo_sweep.errors import MeasurementError, SimulationError
from somo_sweep.model.description import MAX_LENGTH_M, Manipulator
from somo_sweep.statics.bench_rig import STOPS, BenchSettings, check_stop, finger_underside_m

__all__ = ["BENCH_KEYS", "BenchHeader", "bench_header", "read_bench_header"]

#: Header keys with their meaning.
BENCH_KEYS = {
    "stop_z_mm": "blocked-force stop's top relative to the finger's centre line, mm (z up)",
    "stop": "what the blocked-force stop touches: plate (the whole finger) or fingertip (its end only)",
}
_PREFIX = "# bench:"


@dataclass(frozen=True)
class BenchHeader:
    """The bench geometry of a CSV (all None: the default protocol).

    Attributes:
        stop_z_mm: Stop height relative to the straight finger's centre line, mm; None: its underside.
        stop: ``plate`` or ``fingertip`` (:data:`~somo_sweep.statics.bench_rig.STOPS`).
        line: Line of the ``# bench:`` header in the file (None when there is none).
        source: The file, for messages.
    """

    stop_z_mm: float | None = None
    stop: str = "plate"
    line: int | None = None
    source: str = "<rows>"

    def settings(self, base: BenchSettings, manip: Manipulator) -> BenchSettings:
        """``base`` with this stop, checked against the finger to be simulated.

        Raises:
            MeasurementError: A stop the finger would start inside or could never reach (naming the line).
        """
        if self.stop_z_mm is None:
            return replace(base, stop=self.stop)
        stop_m = self.stop_z_mm * 1e-3
        try:
            check_stop(manip, stop_m)
        except SimulationError as exc:
            raise MeasurementError(self.source, [f"line {self.line}, bench header: {exc}"]) from None
        return replace(base, stop_z_m=stop_m, stop=self.stop)

    def describe(self, manip: Manipulator) -> str:
        """Which blocked-force geometry is used, and where it comes from (for the terminal)."""
        under_mm = finger_underside_m(manip) * 1e3
        kind = (
            ""
            if self.stop == "plate"
            else f"; a fingertip stop (only the finger's end touches it), from line {self.line} of "
            f"{self.source}"
        )
        if self.stop_z_mm is None:
            return (
                f"bench: blocked-force stop at the finger's underside, {-under_mm:.4g} mm from its centre "
                f"line (the default; a CSV line '# bench: {{stop_z_mm: ...}}' moves it){kind}"
            )
        gap = -self.stop_z_mm - under_mm
        return (
            f"bench: blocked-force stop at {self.stop_z_mm:.4g} mm from the finger's centre line "
            f"({gap:.4g} mm below its underside), from line {self.line} of {self.source}{kind}"
        )

    def as_dict(self) -> dict[str, Any]:
        """For JSON reports."""
        return {"stop_z_mm": self.stop_z_mm, "stop": self.stop, "line": self.line}


def read_bench_header(path: str | Path) -> BenchHeader:
    """The ``# bench:`` line of a CSV file, validated (:func:`bench_header` of the file read)."""
    return bench_header(read_bench_file(path))


def bench_header(file: BenchFile) -> BenchHeader:
    """The ``# bench:`` line of a bench file, validated (the default bench when there is none).

    Raises:
        MeasurementError: Given twice, not a mapping, an unknown key, a ``stop_z_mm`` that is no
            finite number of at most ±100 m or a ``stop`` not in :data:`~somo_sweep.statics.bench_rig.STOPS`
            (the message names the line and the key).
    """
    path = file.path
    found = header_mapping(file, _PREFIX, "bench header", "{stop_z_mm: -9}")
    source = str(path)
    if found is None:
        return BenchHeader(source=source)
    number, data = found
    where = f"line {number}, bench header"
    problems = [
        f"{where}: unknown key '{k}'; allowed: {', '.join(BENCH_KEYS)}" for k in data if k not in BENCH_KEYS
    ]
    value = data.get("stop_z_mm")
    limit_mm = MAX_LENGTH_M * 1e3
    if "stop_z_mm" in data and not (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and math.isfinite(value)
        and abs(value) <= limit_mm
    ):
        problems.append(
            f"{where}: stop_z_mm ({BENCH_KEYS['stop_z_mm']}) must be a finite number from "
            f"{-limit_mm:g} to {limit_mm:g}, got {value!r}"
        )
    stop = data.get("stop", "plate")
    if stop not in STOPS:
        problems.append(
            f"{where}: stop ({BENCH_KEYS['stop']}) must be one of {', '.join(STOPS)}, got {stop!r}"
        )
    if problems:
        raise MeasurementError(path, problems)
    return BenchHeader(float(value) if value is not None else None, str(stop), number, source)
