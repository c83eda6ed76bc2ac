"""Benchmarks, run from the repository root as modules: ``.venv/bin/python -m bench.<name>``
(shared parts in :mod:`bench.harness`; results in ``bench/results/``)."""
