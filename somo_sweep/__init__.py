"""somo-sweep: SoMo-style continuum-robot simulation, calibration and design sweeps in PyBullet."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("somo-sweep")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0"

__all__ = ["__version__"]
