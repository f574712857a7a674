"""Evaluation protocols and result tables.

lafan1: the official LaFAN1 baseline table (10 past frames) and the S-CVAE paper's Table 1 layout;
tables: one markdown formatter and the flat ``rows`` records of ``results/bench.json``.
Model-specific protocols live beside them (``infilling``: the CAE gap-filling protocol; ``interaction``:
the two-character Table 1 protocol).
"""
from inbetween_jax.evaluation.lafan1 import (  # noqa: F401
    BASELINES, CM_TO_M, TABLE_COLUMNS, baseline_table1, official_baseline_table, official_errors,
    transition_metrics)
from inbetween_jax.evaluation.tables import flat_rows, format_value, markdown_table  # noqa: F401
