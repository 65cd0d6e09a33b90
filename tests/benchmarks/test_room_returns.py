"""The room-returns benchmark counts a stay per run of calls into one module, and a return per stay
in a module entered before."""

from __future__ import annotations

import json
from pathlib import Path

from benchmarks.room_returns import Trip, main, traced_run


def test_a_stay_is_a_run_of_calls_into_one_module_and_a_return_a_stay_in_one_entered_before() -> None:
    trip = Trip()
    for module in ["a", "a", "b", "a", "c", "c", "a", "b"]:
        trip.enter(module)
    assert trip.stays == ["a", "b", "a", "c", "a", "b"]
    assert (trip.rooms, trip.returns) == (3, 3)
    assert trip.by_module() == [("a", 2), ("b", 1)]


def test_a_traced_run_goes_through_the_sweep_s_stages(tmp_path: Path) -> None:
    trip = traced_run(1)
    entered = set(trip.stays)
    assert {
        "cli/sweep.py",
        "sweep/run/runner.py",
        "sweep/store/result_store.py",
        "sweep/views/plots.py",
    } <= entered
    assert all(m.startswith(("sweep/", "cli/")) for m in entered)
    assert main(["--trials", "1", "--json", str(tmp_path / "trip.json")]) == 0
    record = json.loads((tmp_path / "trip.json").read_text())
    assert record["returns"] == record["stays"] - record["rooms"] > 0
