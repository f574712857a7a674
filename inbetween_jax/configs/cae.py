"""Convolutional inpainting AE configuration (Kaufmann et al. 2020, Sec. 3), ``get_config()``.

Frozen dataclasses; override with ``inbetween_jax.train.apply_overrides``, e.g.
``model.variant=vanilla model.channels=16,32,64,128,128 batch_size=16``.
``get_config("tiny")`` is the small variant used by tests; ``get_config("cpu")`` the quarter-width model (half at the last unit), batch 16 and
short "epochs" used for the CPU-bounded real run (see ``docs/results/cae.md``).
"""
from __future__ import annotations

import dataclasses


@dataclasses.dataclass(frozen=True)
class ModelConfig:
    variant: str = "cae"                        # cae | vanilla | holden1d
    channels: tuple = (32, 64, 128, 256, 256)   # encoding-unit outputs (paper, Fig. 4)
    leak: float = 0.2                           # leaky-ReLU slope
    holden_hidden: int = 256                    # holden1d: hidden channels
    holden_width: int = 25                      # holden1d: temporal kernel width


@dataclasses.dataclass(frozen=True)
class DataConfig:
    clip_length: int = 240       # T for training (paper: 240 frames)
    epoch_stride: int = 40       # an "epoch" = the number of clips at this stride / batch_size (if steps_per_epoch=0)
    std_eps: float = 1e-3        # floor of the per-row std (rows that never vary, e.g. root x / z)
    max_motions: int = 0         # >0: use only the first N training motions (tests)


@dataclasses.dataclass(frozen=True)
class MaskConfig:
    curriculum: bool = True      # mu_e schedule; False -> gaps of fixed mean ``fixed_mu``
    mu_start: float = 10.0       # "We initialize mu_e to 10, and increase it until 120 by steps of 10 every 5 epochs"
    mu_end: float = 120.0
    mu_step: float = 10.0
    every_epochs: int = 5
    fixed_mu: float = 60.0       # the paper's "(60)" models
    sigma: float = 20.0          # gap-length std (fixed)
    p_joint: float = 0.3         # probability of the joint-row corruption instead of a gap
    max_joints: int = 3          # 1..max_joints joints removed over the whole clip


@dataclasses.dataclass(frozen=True)
class Config:
    model: ModelConfig = ModelConfig()
    data: DataConfig = DataConfig()
    mask: MaskConfig = MaskConfig()
    lr: float = 1e-3             # Adam, fixed
    batch_size: int = 80
    num_epochs: int = 200
    num_steps: int = 0           # >0 overrides num_epochs * steps_per_epoch
    steps_per_epoch: int = 0     # 0: from data.epoch_stride
    log_every: int = 20
    ckpt_every: int = 200
    seed: int = 0


def get_config(name: str = "paper") -> Config:
    """``paper`` (defaults above), ``cpu`` (real CPU run) or ``tiny`` (tests)."""
    if name == "paper":
        return Config()
    if name == "cpu":
        return Config(model=ModelConfig(channels=(8, 16, 32, 64, 128)), batch_size=16, steps_per_epoch=20,
                      num_epochs=80, log_every=20, ckpt_every=100)
    if name == "tiny":
        return Config(model=ModelConfig(channels=(4, 4, 8, 8, 8), holden_hidden=16, holden_width=5),
                      data=DataConfig(clip_length=64, max_motions=2), batch_size=4, steps_per_epoch=2,
                      num_epochs=4, log_every=2, ckpt_every=4)
    raise ValueError(f"unknown CAE config {name!r}; choose paper, cpu or tiny")
