"""The SoMo paper's figures (Figs. 3, 5-8, the Fig. 6 ablation and comparison, the palm study).

Each module builds one figure from a study's results or its own runs and returns it as
:class:`~somo_sweep.paper.artifacts.Artifacts`; ``somo-sweep paper …`` writes them. The
benchmarks and cross-checks are not part of the package: they live in ``benchmarks/`` of the
repository.
"""
