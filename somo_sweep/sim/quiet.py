"""PyBullet's first import made quiet, and C-level output silenced where asked.

PyBullet's C extension prints ``pybullet build time: …`` when it is first imported (to
standard error in the 3.2.7 wheels, to standard output in some builds), which would land
in every command's output once per worker process. A finder on ``sys.meta_path``
(:func:`quiet_pybullet_import`, put there when :mod:`somo_sweep.sim` is imported) loads
``pybullet`` with file descriptors 1 and 2 pointed at ``/dev/null``. Imports nothing heavy.
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib.abc
import importlib.machinery
import os
import sys
from collections.abc import Iterator
from types import ModuleType
from typing import Any

__all__ = ["quiet_pybullet_import", "silenced"]


@contextlib.contextmanager
def silenced() -> Iterator[None]:
    """File descriptors 1 and 2 go to /dev/null inside the block (C-level prints included)."""
    saved: list[tuple[int, int]] = []
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd, stream in ((1, sys.stdout), (2, sys.stderr)):
            with contextlib.suppress(OSError, ValueError, AttributeError):
                stream.flush()
            try:
                saved.append((fd, os.dup(fd)))
            except OSError:  # not open: nothing to silence
                continue
            os.dup2(null, fd)
        yield
    finally:
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None).fflush(None)  # the extension's buffered C stdio
        for fd, copy in saved:
            os.dup2(copy, fd)
            os.close(copy)
        os.close(null)


class _QuietLoader(importlib.abc.Loader):
    def __init__(self, inner: Any):
        self.inner = inner

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        with silenced():
            return self.inner.create_module(spec)

    def exec_module(self, module: ModuleType) -> None:
        with silenced():
            self.inner.exec_module(module)


class _QuietPyBullet(importlib.abc.MetaPathFinder):
    def find_spec(self, name: str, path: Any, target: Any = None) -> importlib.machinery.ModuleSpec | None:
        if name != "pybullet":
            return None
        spec = importlib.machinery.PathFinder.find_spec(name, path)
        if spec is not None and spec.loader is not None:
            spec.loader = _QuietLoader(spec.loader)
        return spec


def quiet_pybullet_import() -> None:
    """Put the finder on ``sys.meta_path`` (once), unless PyBullet is imported already."""
    if "pybullet" not in sys.modules and not any(isinstance(f, _QuietPyBullet) for f in sys.meta_path):
        sys.meta_path.insert(0, _QuietPyBullet())
