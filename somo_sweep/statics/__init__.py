"""The bench statics: a manipulator clamped on the bench, its rows solved as equilibria.

The stage above the engines' worlds and kinematics (:mod:`somo_sweep.sim`), below the tasks and
the calibration that run bench rows; it imports no engine (``tests/test_architecture.py``):

* the rig and the protocols: :mod:`~somo_sweep.statics.bench_rig` (clamp, stop, loads, what is
  measured) and :func:`~somo_sweep.statics.bench.run_bench` (``tip_load``, ``blocked_force``,
  ``free_bending`` as rows), solved statically (:mod:`~somo_sweep.statics.solve`) or by dynamic
  relaxation in a world (:mod:`~somo_sweep.statics.relaxation`);
* the solver: a body on its engine's kinematics (:mod:`~somo_sweep.statics.bench_bodies`,
  :mod:`~somo_sweep.statics.chain_kinematics`), the chain's energy
  (:mod:`~somo_sweep.statics.chain_energy`), Newton's method with a contact QP
  (:mod:`~somo_sweep.statics.static_newton`, :mod:`~somo_sweep.statics.active_set_qp`), load
  continuation (:mod:`~somo_sweep.statics.continuation`), proofs that a row has no equilibrium
  (:mod:`~somo_sweep.statics.no_equilibrium`), the chain and its rows
  (:mod:`~somo_sweep.statics.static_chain`) and the plate forces the rigid model leaves open
  (:mod:`~somo_sweep.statics.plate_force_range`).

The package re-exports nothing: each entry point lives in its own module.
"""

from __future__ import annotations

__all__: list[str] = []
