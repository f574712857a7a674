"""Experiment configurations, flax-examples style: ``get_config(name)`` per model."""
