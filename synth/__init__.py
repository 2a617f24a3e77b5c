"""Synthesis: the clingo driver, disambiguation dialogue, regression suites and the CLI."""
