"""Shared fixtures: bundled model paths and small model builders."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml

from somo_sweep.model.tables import bundled_path

ROOT = Path(__file__).resolve().parent.parent
#: The bundled models, read from the package (as an installed copy would).
MODELS = bundled_path("models")


@pytest.fixture(autouse=True)
def _private_cache(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> None:
    """Generated URDFs go to a per-session temporary cache, never the user's."""
    monkeypatch.setenv("SOMO_SWEEP_CACHE", str(tmp_path_factory.getbasetemp() / "cache"))


def load_yaml(name: str) -> dict[str, Any]:
    """A bundled model file as a dict (a fresh copy each call)."""
    return copy.deepcopy(yaml.safe_load((MODELS / name).read_text()))


def ihm_finger_dict(
    motor_limit: float | None = 0.0,
    damping: float | None = None,
    added_inertia: float | None = None,
) -> dict[str, Any]:
    """The IHM finger with chosen joint motor limit, viscous damping and inertia shaping."""
    data = load_yaml("ihm_finger.yaml")
    act = data["manipulator"]["actuators"][0]
    for joint in act["joints"]:
        joint["motor_limit_n_m"] = motor_limit
        if damping is not None:
            joint["damping_n_m_s_per_rad"] = damping
    if added_inertia is not None:
        act["link"]["added_inertia_kg_m2"] = added_inertia
    return data


def signals_as_in_a_shell() -> None:
    """``preexec_fn`` for a child that a test sends SIGINT: it starts with SIGINT at its default
    and unblocked, as a shell starts a command. Both are inherited across exec, and a test
    process launched in the background (``pytest &`` in a script) has SIGINT ignored, which
    ``somo-sweep run`` then keeps."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
