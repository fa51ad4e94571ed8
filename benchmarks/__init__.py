"""Benchmark reproductions and performance measurements: ``python -m benchmarks NAME``."""
