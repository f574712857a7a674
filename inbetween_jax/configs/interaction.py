"""Interaction in-betweening configuration (Zhang et al. 2025, "Motion In-Betweening for Densely Interacting
Characters"), flax-examples style ``get_config()``.

Frozen dataclasses; override from the command line with ``inbetween_jax.train.apply_overrides``, e.g.
``model.hidden=64 train.batch_size=8 model.interaction=false``.  ``get_config("tiny")`` is the test variant.
Ablation switches (Table 1): ``model.interaction`` (False: "w/o interaction modeling", each character
in-betweened independently in its own keypose space), ``model.gan`` ("w/o Inter. GAN"),
``model.refiner`` ("w/o Motion Refiner").
"""
from __future__ import annotations

import dataclasses


@dataclasses.dataclass(frozen=True)
class DataConfig:
    pair_distance: float = 150.0   # constructed pairs: second performer this far in front (file units, cm)
    pos_scale: float = 0.01        # positions enter the model in metres
    n_input: int = 20              # T: observed frames
    n_pred: int = 10               # l: frames predicted per autoregressive step
    key_min: int = 50              # keyframe sampled 50..70 frames after the window start (Sec. 5.1)
    key_max: int = 70
    mirror: bool = True            # mirroring augmentation (p = 0.5)
    split: tuple = (0.85, 0.05, 0.10)   # temporal train / val / test fractions of every pair


@dataclasses.dataclass(frozen=True)
class ModelConfig:
    # sizes chosen for a ~30 min CPU run (the paper does not list layer sizes)
    dct_coeffs: int = 15           # DCT coefficients kept of the (n_input + n_pred)-frame padded window
    conv_channels: int = 8
    hidden: int = 64
    gcn_layers: int = 2
    latent: int = 8                # VAE latent per joint
    refiner_hidden: int = 64
    refiner_latent: int = 16
    pae_channels: int = 15         # C_phi
    pae_hidden: int = 64
    pjd_frames: int = 30           # N (Eq. 9) = ar_steps * n_pred
    pjd_joints: tuple = ()         # subset of joints for the PJD (empty: all)
    pjd_scale: float = 2.0        # PJD values (m^2 / frame) are multiplied by this
    disc_hidden: int = 64
    interaction: bool = True       # cross-space interaction modelling (transform + VAE + FiLM)
    gan: bool = True               # PAE + interaction discriminator
    refiner: bool = True           # motion refiner at inference
    stop_threshold: float = 0.15   # rollout stops when both characters' mean joint distance to keypose < this (m)
    max_frames: int = 200          # rollout cap


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    batch_size: int = 16
    ar_steps: int = 3              # P
    lr: float = 1e-3               # paper: 1e-4 for 100 epochs; raised for short CPU runs
    num_steps: int = 3000
    ss_ramp_steps: int = 1500      # scheduled sampling: P(feed back prediction) ramps 0 -> ss_max
    ss_max: float = 0.5
    w_mse: float = 1.0
    w_coarse: float = 0.5          # auxiliary MSE on the coarse (individual) prediction
    w_kl: float = 1e-3
    w_adv: float = 0.01
    w_pae: float = 1.0
    w_refine: float = 1.0
    grad_clip: float = 1.0
    log_every: int = 50
    ckpt_every: int = 250
    seed: int = 0


@dataclasses.dataclass(frozen=True)
class Config:
    data: DataConfig = DataConfig()
    model: ModelConfig = ModelConfig()
    train: TrainConfig = TrainConfig()


def get_config(variant: str = "default") -> Config:
    """``default`` (the real CPU run) or ``tiny`` (tests)."""
    if variant == "default":
        return Config()
    if variant == "tiny":
        return Config(model=ModelConfig(dct_coeffs=30, conv_channels=4, hidden=32, gcn_layers=1, latent=4,
                                        refiner_hidden=16, refiner_latent=4, pae_channels=3, pae_hidden=8,
                                        pjd_joints=(0, 3, 7, 13), disc_hidden=16, max_frames=60),
                      train=TrainConfig(batch_size=4, num_steps=20, log_every=5, ckpt_every=10,
                                        ss_ramp_steps=10))
    raise ValueError(f"unknown interaction config variant {variant!r}; choose default or tiny")
