"""Benchmarks: `python -m bench [NAME ...]`, each printing ratios against a baseline."""
