"""What the command line writes outside the folders a user names: somo-sweep's cache folder only
(the URDF cache, and Matplotlib's font cache beside it), as docs/outputs.md says."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from test_robustness import sign_study

from somo_sweep.sweep.run.runner import RunOptions, run_sweep
from somo_sweep.sweep.study import load_study

CLI = Path(sys.executable).parent / "somo-sweep"


def _plot(folder: Path, home: Path, **env: str) -> None:
    clean = {k: v for k, v in os.environ.items() if not k.startswith(("XDG_", "MPL", "SOMO_SWEEP"))}
    done = subprocess.run(
        [str(CLI), "plot", str(folder)],
        env={**clean, "HOME": str(home), **env},
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr


def _written(home: Path) -> list[str]:
    return sorted(str(p.relative_to(home)) for p in home.rglob("*") if p.is_dir())


def test_matplotlib_caches_its_fonts_in_somo_sweeps_cache_folder_not_its_own(tmp_path: Path) -> None:
    """Matplotlib wrote ~/.cache/matplotlib, while the docs named the URDF cache the one folder outside."""
    path = sign_study(tmp_path, xs="[-1, 1]")
    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    home = tmp_path / "home"
    home.mkdir()
    _plot(tmp_path / "out", home)
    assert (tmp_path / "out" / "plots" / "summary.png").exists()
    assert _written(home) == [".cache", ".cache/somo-sweep", ".cache/somo-sweep/matplotlib"]
    assert any((home / ".cache" / "somo-sweep" / "matplotlib").iterdir())
    # SOMO_SWEEP_CACHE moves it with the URDF cache; a user's MPLCONFIGDIR is kept.
    _plot(tmp_path / "out", home, SOMO_SWEEP_CACHE=str(tmp_path / "scratch"))
    assert (tmp_path / "scratch" / "matplotlib").is_dir()
    _plot(tmp_path / "out", home, MPLCONFIGDIR=str(tmp_path / "mine"))
    assert (tmp_path / "mine").is_dir() and _written(home)[-1] == ".cache/somo-sweep/matplotlib"
