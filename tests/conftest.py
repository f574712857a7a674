"""Shared test fixtures: where the real mocap lives."""
import os
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

# Real LaFAN1 files: $LAFAN1_DIR, else the shared data folder beside the repository.
_DEFAULT = os.path.join(os.path.dirname(os.path.dirname(HERE)), "shared", "data", "lafan1")
LAFAN1_DIR = os.environ.get("LAFAN1_DIR") or _DEFAULT
SHARED_DATA = os.path.dirname(_DEFAULT)
HAS_LAFAN1 = os.path.isdir(LAFAN1_DIR) and any(f.endswith(".bvh") for f in os.listdir(LAFAN1_DIR))
requires_lafan1 = pytest.mark.skipif(not HAS_LAFAN1, reason="LaFAN1 BVH files not found (set LAFAN1_DIR)")

# Tests write their window caches into a private folder so they never reuse a user's cache.
os.environ.setdefault("INBETWEEN_JAX_CACHE", os.path.join(HERE, "..", ".cache", "test"))
