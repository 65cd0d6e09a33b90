"""Sub-command modules: each adds its commands to :data:`somo_sweep.cli.app` on import."""

import importlib
import pkgutil

for _info in pkgutil.iter_modules(__path__):
    importlib.import_module(f"{__name__}.{_info.name}")
