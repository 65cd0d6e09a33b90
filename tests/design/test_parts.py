"""The design search's parts, each against what it must do: variables, the objects' order and rungs,
a cell's state from its runs, the halving's cut, the Wilson interval and the Pareto front."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from somo_sweep.design.cells import CellState, Tally, cell_state, next_replica
from somo_sweep.design.halving import promoted, undecided
from somo_sweep.design.objects import object_order, rung_sizes
from somo_sweep.design.ranking import wilson
from somo_sweep.design.variables import as_asked, parse_variable

IN, OUT = ("ok", {"grasp": "pinch"}), ("ok", {"grasp": "power"})


def _var(spec: dict[str, object]):  # type: ignore[no-untyped-def]
    variable, problems = parse_variable("task.a", spec, "design.variables.task.a")
    assert problems == [] and variable is not None
    return variable


def test_a_range_of_integers_is_an_integer_variable_and_its_last_value_lies_on_the_step() -> None:
    v = _var({"low": 8, "high": 17, "step": 2})
    assert (v.kind, v.low, v.high, v.n_values) == ("int", 8, 16, 5)
    assert v.distribution().step == 2


def test_a_float_range_on_a_step_ends_on_the_step_without_round_off() -> None:
    v = _var({"low": 0.05, "high": 0.52, "step": 0.05})
    assert (v.kind, v.high, v.n_values) == ("float", 0.5, 10)
    assert _var({"low": 0.2, "high": 1.2, "log": True}).n_values is None


def test_choices_keep_their_values_as_written_and_stored_values_map_back() -> None:
    v = _var({"choices": [150, 0.5, "box", True]})
    assert v.choices == (150, 0.5, "box", True)
    assert as_asked(v, 150.0) == 150 and isinstance(as_asked(v, 150.0), int)
    assert as_asked(_var({"low": 100, "high": 250, "step": 50}), 200.0) == 200
    assert v.contains("box") and not v.contains("hull")


def test_objects_are_taken_stratum_by_stratum_and_spread_inside_each() -> None:
    points = [{"w": w, "c": c} for w in (20, 40, 60) for c in range(4)]
    order = object_order(points, "w")
    assert sorted(order) == list(range(12))
    first = [points[i] for i in order[:3]]
    assert sorted(p["w"] for p in first) == [20, 40, 60]  # every stratum in the first three
    firsts = [points[i]["c"] for i in order[:6]]
    assert len(set(firsts[:3])) == 3  # the strata do not all start on the same object
    assert object_order(points, "w") == order  # a function of the objects alone


def test_rungs_grow_by_the_reduction_and_the_first_holds_every_stratum() -> None:
    assert rung_sizes(12, 3, 3) == [4, 12]
    assert rung_sizes(154, 7, 3) == [18, 52, 154]
    assert rung_sizes(6, 6, 3) == [6]
    assert rung_sizes(1, 1, 3) == [1]


@pytest.mark.parametrize(
    ("plain", "replicas", "state"),
    [
        (None, [], CellState.UNKNOWN),
        (OUT, [], CellState.MISS),
        (("error", {}), [], CellState.MISS),
        (IN, [None, None, None], CellState.OPEN),
        (IN, [IN, None, None], CellState.OPEN),
        (IN, [IN, OUT, None], CellState.BROKEN),
        (IN, [IN, ("unstable", {}), None], CellState.BROKEN),
        (IN, [IN, IN, IN], CellState.ROBUST),
    ],
)
def test_a_cell_counts_only_when_its_trial_and_every_replica_give_the_label(plain, replicas, state) -> None:  # type: ignore[no-untyped-def]
    assert cell_state(plain, replicas, 3, "grasp", "pinch") is state


def test_an_open_cell_runs_its_first_missing_replica_next() -> None:
    assert next_replica([IN, None, None], 3) == 2
    assert next_replica([], 3) == 1


def _tally(robust: int, open_: int, unknown: int = 0, objects: int = 4) -> Tally:
    return Tally(objects, robust, open_, unknown, objects - robust - open_ - unknown)


def test_replicas_run_only_for_designs_whose_place_at_the_cut_is_open() -> None:
    tallies = {
        0: _tally(3, 0),  # surely above a cut of 1: no other can reach 3
        1: _tally(0, 2),  # at most 2: surely below
        2: _tally(0, 1),
    }
    assert undecided(tallies, 1) == []
    assert promoted(tallies, 3) == [0]
    close = {0: _tally(1, 2), 1: _tally(2, 0), 2: _tally(0, 0)}
    assert undecided(close, 1) == [0, 1]  # 0 may pass 1 or not; 2 is surely below
    assert undecided(close, 3) == []  # every design goes on: no replica needed now


def test_ties_go_to_the_design_registered_first() -> None:
    assert promoted({5: _tally(2, 0), 3: _tally(2, 0), 9: _tally(1, 0)}, 2) == [3, 5]


def test_the_wilson_interval_matches_its_closed_form() -> None:
    low, high = wilson(11, 12)
    assert (round(low, 4), round(high, 4)) == (0.6461, 0.9851)
    assert wilson(0, 12)[0] == 0.0 and wilson(12, 12)[1] == 1.0
    assert wilson(0, 0) == (0.0, 1.0)
    n, k = 154, 120
    p, z = k / n, 1.959963984540054
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    assert wilson(k, n) == pytest.approx((centre - half, centre + half), abs=1e-15)


def test_the_pareto_front_holds_the_complete_designs_no_other_beats_on_both() -> None:
    from types import SimpleNamespace

    from somo_sweep.design.ranking import pareto_front

    trade = SimpleNamespace(metric=None, variable="task.pressure_kpa", direction="minimize", reduce="mean")
    study = SimpleNamespace(trade_off=trade)
    frame = pd.DataFrame(
        {
            "robust_share": [1.0, 0.9, 0.9, 0.5, 1.0],
            "task.pressure_kpa": [250, 150, 200, 100, 100],
            "complete": [True, True, True, True, False],
        }
    )
    assert pareto_front(frame, study).tolist() == [True, True, False, True, False]  # type: ignore[arg-type]


def test_a_folder_without_trials_ranks_no_design_with_every_column(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from design_studies import ball_study

    from somo_sweep.design import load_design, rank_designs
    from somo_sweep.design.report import finalists

    study = load_design(ball_study(tmp_path), tmp_path / "out")
    ranking = rank_designs(pd.DataFrame(columns=["job_id", "trial", "replica", "status"]), study)
    assert ranking.empty and {"robust_share", "complete", "task.u"} <= set(ranking.columns)
    assert finalists(ranking, study).empty
