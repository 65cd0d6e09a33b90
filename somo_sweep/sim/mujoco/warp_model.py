"""Many compiled MuJoCo models of one structure as one MuJoCo Warp model with per-world fields.

A trial batch compiles one MuJoCo model per world (C MuJoCo, as engine ``mujoco`` does). Warp
holds most model fields once for all worlds; 121 of them can instead hold one value per world
(Warp's ``batch_sizes``): body positions, geom sizes, masses and inertias, friction, actuator
gains, and the constants MuJoCo derives from them. :func:`batched_model` compares the worlds'
models field by field: a field they share stays shared, a field they differ in becomes per world
if Warp can hold it so, and any other difference is refused by name (the worlds then differ in
structure: another finger link count or DSR split is another batch). Each world's values are
those Warp makes of that world's own model, so no conversion is written here twice.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Sequence
from typing import Any

import mujoco
import mujoco_warp as mjw
import numpy as np

from somo_sweep.errors import SimulationError

__all__ = ["IGNORED_FIELDS", "batched_model", "differing_fields"]

#: Model fields that may differ without consequence on Warp: names, which no step reads, and
#: dof_length, which only MuJoCo Warp's sleeping reads (the worlds never sleep).
IGNORED_FIELDS = ("dof_length",)


def _warp_fields() -> tuple[set[str], set[str]]:
    """The array fields of Warp's model, and those of them that can hold one value per world."""
    from mujoco_warp._src import types, warp_util

    arrays = {f.name: f.type for f in dataclasses.fields(types.Model) if warp_util.is_array_spec(f.type)}
    per_world = {name for name, spec in arrays.items() if getattr(spec, "shape", ())[:1] == ("*",)}
    return set(arrays), per_world


def _arrays(model: Any) -> dict[str, np.ndarray]:
    out = {}
    for name in dir(model):
        if name.startswith("_") or name.startswith("name"):
            continue
        value = getattr(model, name, None)
        if isinstance(value, np.ndarray):
            out[name] = value
    return out


def differing_fields(models: Sequence[Any]) -> list[str]:
    """The array fields (names aside) in which some model differs from the first, or the
    model options (``opt.<name>``) they differ in."""
    first = _arrays(models[0])
    out: set[str] = set()
    for model in models[1:]:
        for name, value in _arrays(model).items():
            ref = first.get(name)
            if ref is None or ref.shape != value.shape or not np.array_equal(ref, value, equal_nan=True):
                out.add(name)
        for name in dir(model.opt):
            if not name.startswith("_") and _option(model, name) != _option(models[0], name):
                out.add(f"opt.{name}")
    return sorted(out)


def _option(model: Any, name: str) -> Any:
    value = getattr(model.opt, name)
    return tuple(np.ravel(value)) if isinstance(value, np.ndarray) else value


def batched_model(models: Sequence[Any]) -> tuple[Any, Any]:
    """One MuJoCo Warp model for ``models`` (one per world, in order): the host model it was put
    from (the first, MuJoCo's automatic reset cleared as Warp needs) and the device model.

    Raises:
        SimulationError: The models differ in structure, options or a field Warp holds once.
    """
    arrays, per_world = _warp_fields()
    differ = [f for f in differing_fields(models) if f not in IGNORED_FIELDS]
    refused = [f for f in differ if f.startswith("opt.") or (f in arrays and f not in per_world)]
    refused += [f for f in differ if not f.startswith("opt.") and f not in arrays and _structural(f)]
    if refused:
        raise SimulationError(
            "a mujoco_warp batch needs worlds of one structure; these differ in "
            f"{', '.join(sorted(refused))} (run them in separate batches)"
        )
    batched = [f for f in differ if f in per_world]
    hosts = [_for_warp(m) for m in models]
    device = mjw.put_model(hosts[0], batch_sizes={f: len(models) for f in batched})
    if batched:
        own = [mjw.put_model(h) for h in hosts]  # each world's values as Warp makes them
        for name in batched:
            values = np.stack([getattr(w, name).numpy()[0] for w in own])
            getattr(device, name).assign(values)
    return hosts[0], device


def _structural(name: str) -> bool:
    """Whether a field Warp does not hold would change what a step computes if it differed
    (integer fields describe structure; MuJoCo's own float caches, e.g. bounding volumes, do not)."""
    return name in _INTEGER_FIELDS


_INTEGER_FIELDS = {
    name
    for name, value in _arrays(mujoco.MjModel.from_xml_string("<mujoco/>")).items()
    if np.issubdtype(value.dtype, np.integer)
}


def _for_warp(model: Any) -> Any:
    host = copy.copy(model)
    host.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)  # Warp refuses it
    return host
