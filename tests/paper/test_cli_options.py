"""Options of the paper commands that used to fail late (after minutes of work) or with a traceback."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from somo_sweep.cli.app import app


@pytest.mark.parametrize("cycles", ["0", "10", "100000"])
def test_fig5_fit_cycles_outside_the_recording_are_refused_before_any_work(
    tmp_path: Path, cycles: str
) -> None:
    """100000 was an IndexError after the finger calibration."""
    res = CliRunner().invoke(app, ["paper", "fig5", "--fit-cycles", cycles, "--out", str(tmp_path / "f")])
    assert res.exit_code == 2 and "--fit-cycles must be from 1 to 9" in res.output
    assert "held out" in res.output and not (tmp_path / "f").exists()
