"""The cross-check against the original SoMo code: what runs without the original's checkout."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks.original_fig6 import __main__ as cross_check
from benchmarks.original_fig6.compare_cells import without_friction_anchors
from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path


def _anchors(node: object) -> list[bool]:
    if isinstance(node, dict):
        here = [node["friction"]["anchor"]] if isinstance(node.get("friction"), dict) else []
        return here + [a for v in node.values() for a in _anchors(v)]
    return [a for v in node for a in _anchors(v)] if isinstance(node, list) else []


def _rest(node: object) -> object:
    """``node`` without its ``anchor`` keys."""
    if isinstance(node, dict):
        return {k: _rest(v) for k, v in node.items() if k != "anchor"}
    return [_rest(v) for v in node] if isinstance(node, list) else node


def test_the_anchor_experiment_clears_every_links_friction_anchor_and_nothing_else() -> None:
    model = load_model(bundled_path("models", "pinch_gripper_original.yaml"))
    before = model.model_dump(mode="json")
    assert any(_anchors(before))  # the original finger sets it
    after = without_friction_anchors(model).model_dump(mode="json")
    assert _anchors(after) and not any(_anchors(after))
    assert len(_anchors(after)) == len(_anchors(before))
    assert _rest(after) == _rest(before)


def test_without_the_originals_checkout_it_says_how_to_set_it_up(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as stop:
        cross_check.main(["--somo", str(tmp_path), "--original-python", str(tmp_path / "python")])
    err = capsys.readouterr().err
    assert stop.value.code == 2
    assert f"{tmp_path} is not a checkout of GrauleM/somo at 755978b" in err
    assert "no Python interpreter for the original there" in err
    assert "python3.11 -m venv venv_orig" in err and "make bench-original ORIGINAL_SOMO=" in err


def _coast_speed_m_s(damping: float | None, monkeypatch: pytest.MonkeyPatch) -> float:
    """Speed of a free cube loaded through ``loadURDF`` after 0.5 s of coasting without gravity
    from 1 m/s, with the runner's damping experiment applied."""
    import pybullet as p
    import pybullet_data

    from benchmarks.original_fig6.run_original_cells import patch_body_damping

    monkeypatch.setattr(p, "loadURDF", p.loadURDF)  # restored when the test ends
    patch_body_damping(damping)
    client = p.connect(p.DIRECT)
    try:
        cube = p.loadURDF(str(Path(pybullet_data.getDataPath()) / "cube_small.urdf"), physicsClientId=client)
        p.setGravity(0, 0, 0, physicsClientId=client)
        p.resetBaseVelocity(cube, [1.0, 0.0, 0.0], physicsClientId=client)
        for _ in range(240):
            p.stepSimulation(physicsClientId=client)
        return float(p.getBaseVelocity(cube, physicsClientId=client)[0][0])
    finally:
        p.disconnect(client)


def test_the_damping_experiment_removes_the_drag_pybullet_gives_every_body(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    assert _coast_speed_m_s(None, monkeypatch) < 0.99  # PyBullet's default 0.04, as the original
    assert _coast_speed_m_s(0.0, monkeypatch) == pytest.approx(1.0, abs=1e-9)
