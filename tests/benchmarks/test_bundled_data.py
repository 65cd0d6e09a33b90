"""The bundled synthetic tables are what their generators make, and remaking one never replaces a
file somo-sweep did not write."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks import bundled_data
from somo_sweep.model.tables import bundled_path


def test_a_file_somo_sweep_did_not_write_is_never_replaced(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`paper data ... /etc/passwd` replaced it."""
    precious = tmp_path / "notes.txt"
    precious.write_text("my own notes\n")
    with pytest.raises(SystemExit) as stop:
        bundled_data.main(["synthetic", str(precious)])
    assert stop.value.code == 2
    assert f"{precious} exists and has no 'somo-sweep' header: somo-sweep did not write it" in (
        capsys.readouterr().err
    )
    assert precious.read_text() == "my own notes\n"


@pytest.mark.parametrize("which", sorted(bundled_data.DATA_NAMES))
def test_each_bundled_table_says_how_it_is_made_again(which: str) -> None:
    first = bundled_path("tables", bundled_data.DATA_NAMES[which]).read_text().splitlines()[0]
    assert f"(somo-sweep: python -m benchmarks.bundled_data {which})" in first


@pytest.mark.slow
@pytest.mark.parametrize("which", sorted(bundled_data.DATA_NAMES))
def test_each_bundled_table_is_made_again_byte_for_byte(which: str, tmp_path: Path) -> None:
    bundled_data.main([which, f"{tmp_path}/"])
    made = (tmp_path / bundled_data.DATA_NAMES[which]).read_bytes()
    assert made == bundled_path("tables", bundled_data.DATA_NAMES[which]).read_bytes()
