"""Behaviour (gait) generators for each robot type."""
