"""The lab of somo-sweep: benchmarks and cross-checks, run from the repository, never installed.

Each module is one benchmark, run from the repository root as ``python -m benchmarks.NAME``
(``--help`` lists its options) or through its ``make bench…`` target (README.md beside this file
lists them). They use the package's public API and write only what they are asked to.
"""
