"""The active sampler on label fields known in closed form (no study, no process).

A field gives each cell a label, and each replica the label of the cell moved by a seeded jitter,
so the cells near a boundary are not robust; the exhaustive map (every cell with every replica)
is computed alongside and the sampler's map is checked against it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest

from somo_sweep.sweep.run.active import NOT_ROBUST, Run, Sampler, SamplerSettings
from somo_sweep.sweep.run.label_model import Neighbours, Trees, grid_features
from somo_sweep.sweep.run.replica_rule import Verdict, next_replica, verdict

SHAPE = (21, 21)


def disc(x: float, y: float) -> str:
    """A disc of radius 6 around (10, 10): ``inside`` or ``outside``."""
    return "inside" if (x - 10) ** 2 + (y - 10) ** 2 < 36 else "outside"


def half(x: float, y: float) -> str:
    """A half plane: ``left`` below x + y = 20."""
    return "left" if x + y < 20 else "right"


Field = Callable[[int, int], Run]


def field(
    *labels: Callable[[float, float], str], jitter: float = 0.6, shape: tuple[int, int] = SHAPE
) -> Field:
    """The outcome of (cell, replica): each label at the cell, a replica's moved by up to ``jitter``."""

    def outcome(cell: int, number: int) -> Run:
        x, y = np.unravel_index(cell, SHAPE)
        dx, dy = np.random.default_rng([cell, number]).uniform(-jitter, jitter, 2) if number else (0.0, 0.0)
        return tuple(f(float(x + dx), float(y + dy)) for f in labels)

    return outcome


def truth(outcome: Field, k: int, n: int, n_labels: int) -> list[Run]:
    """The exhaustive map: each label's own value where all K replicas agree, else not robust."""
    out = []
    for cell in range(n):
        runs = [outcome(cell, r) for r in range(k + 1)]
        out.append(
            tuple(runs[0][i] if len({r[i] for r in runs}) == 1 else NOT_ROBUST for i in range(n_labels))
        )
    return out


def sample(outcome: Field, settings: SamplerSettings, shape: tuple[int, ...] = SHAPE) -> tuple[Sampler, list]:
    sampler = Sampler(shape, settings)
    asked = [batch for batch in sampler.batches(outcome)]
    return sampler, asked


def agreement(sampler: Sampler, outcome: Field, n_labels: int) -> float:
    want = truth(outcome, sampler.settings.replicas, sampler.n, n_labels)
    return float(np.mean([a == b for a, b in zip(sampler.claims(), want, strict=True)]))


SETTINGS = SamplerSettings(replicas=3, batch=16, initial=30, target_agreement=0.98)


# -- the replica rule ------------------------------------------------------------------------


def test_a_cell_s_replicas_stop_at_the_first_disagreement_whatever_follows() -> None:
    same = "a".__eq__
    assert verdict([], 3, same) is Verdict.OPEN
    assert verdict(["a", None, None], 3, same) is Verdict.OPEN
    assert verdict(["a", "b", None], 3, same) is Verdict.BROKEN
    assert verdict([None, None, "b"], 3, same) is Verdict.BROKEN
    assert verdict(["a", "a", "a"], 3, same) is Verdict.ROBUST
    assert verdict(["a", "a", "a", "b"], 3, same) is Verdict.ROBUST  # replicas above K are not read
    assert next_replica(["a", None], 3) == 2 and next_replica([], 2) == 1
    with pytest.raises(ValueError, match="every replica"):
        next_replica(["a", "a"], 2)


# -- the sampler -----------------------------------------------------------------------------


@pytest.mark.parametrize("model", ["trees", "neighbours"])
def test_the_robust_map_of_a_disc_is_reproduced_from_under_half_the_grid(model: str) -> None:
    outcome = field(disc)
    sampler, asked = sample(outcome, replace(SETTINGS, model=model))
    runs = sum(len(b) for b in asked)
    assert agreement(sampler, outcome, 1) >= 0.97
    assert len(sampler.own) < 0.5 * sampler.n
    assert runs < 0.5 * sampler.n * (SETTINGS.replicas + 1)
    assert sampler.estimate >= SETTINGS.target_agreement


def test_the_same_seed_asks_the_same_runs_and_another_seed_other_runs() -> None:
    outcome = field(disc)
    first = sample(outcome, SETTINGS)[1]
    assert sample(outcome, SETTINGS)[1] == first
    assert sample(outcome, replace(SETTINGS, seed=1))[1] != first


def test_a_label_s_replicas_stop_at_its_first_disagreement_and_a_robust_cell_runs_all_k() -> None:
    outcome = field(disc)
    sampler, asked = sample(outcome, SETTINGS)
    runs = [r for batch in asked for r in batch]
    assert len(runs) == len(set(runs))  # nothing asked twice
    for cell in sampler.chosen:
        numbers = sorted(n for c, n in runs if c == cell and n > 0)
        outs = [outcome(cell, n)[0] for n in numbers]
        own = outcome(cell, 0)[0]
        first_off = next((i for i, o in enumerate(outs) if o != own), None)
        if first_off is None:
            assert numbers == [1, 2, 3]  # robust: every replica, in order
        else:
            assert numbers == list(range(1, first_off + 2))  # none after the one that disagrees
            assert sampler.cell_class(cell) == (NOT_ROBUST,)


def test_with_two_labels_a_cell_goes_on_while_one_label_still_agrees() -> None:
    outcome = field(disc, half)
    sampler, asked = sample(outcome, SETTINGS)
    runs = {r for batch in asked for r in batch}
    split = [
        c
        for c in sampler.chosen
        if sampler.cell_class(c)[0] == NOT_ROBUST and sampler.cell_class(c)[1] != NOT_ROBUST
    ]
    assert split, "the field has cells robust on one label only"
    assert all({(c, 1), (c, 2), (c, 3)} <= runs for c in split)
    assert agreement(sampler, outcome, 2) >= 0.96


def test_replicate_all_replicates_every_simulated_cell_and_no_replicas_asks_none() -> None:
    outcome = field(disc)
    sampler, _ = sample(outcome, replace(SETTINGS, replicate="all"))
    assert sampler.chosen == set(sampler.own)
    sampler, asked = sample(outcome, replace(SETTINGS, replicas=0))
    assert all(n == 0 for batch in asked for _, n in batch) and not sampler.chosen


def test_a_target_of_one_simulates_until_no_cell_is_in_doubt() -> None:
    outcome = field(half, jitter=0.0)  # no cell is fragile: a plain half plane
    sampler, _ = sample(outcome, replace(SETTINGS, target_agreement=1.0, replicas=0))
    assert agreement(sampler, outcome, 1) == 1.0
    assert sampler.estimate == 1.0


def test_the_models_give_probabilities_of_the_classes_they_were_shown() -> None:
    features = grid_features((5, 5))
    classes = (features[:, 0] > 0.5).astype(int)
    train = np.arange(0, 25, 2)
    for model in (Trees(0), Neighbours()):
        p = model.probabilities(features[train], classes[train], features)
        assert p.shape == (25, 2) and np.allclose(p.sum(axis=1), 1.0)
        assert (p.argmax(axis=1) == classes).mean() >= 0.9
