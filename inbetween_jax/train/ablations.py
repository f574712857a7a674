"""The ablation sweep's rows and defaults (S-CVAE paper, Table 6), without JAX: ``inbetween sweep`` checks its
arguments against them before :mod:`inbetween_jax.train.sweep` (which imports JAX) is loaded."""
from __future__ import annotations

__all__ = ["ABLATIONS", "DEFAULT_STEPS", "SWEEP_PRESETS"]

# model -> row name -> (label of Table 6, ModelConfig switch turned off; None = full model)
ABLATIONS = {"scvae": {
    "full": ("S-CVAE (full)", None), "no_bs": ("w/o BS", "bidirectional"), "no_li": ("w/o LI", "latent_interp"),
    "no_ba": ("w/o BA", "aligning"), "no_pm": ("w/o PM", "phase_moe"), "no_lstm": ("w/o LSTM", "encoder_lstm"),
    "no_d": ("w/o D", "discriminators"), "no_sl": ("w/o SL", "stitch_loss")}}
DEFAULT_STEPS = {"tiny": 200, "cpu": 2000, "paper": 20000}
SWEEP_PRESETS = tuple(DEFAULT_STEPS)
