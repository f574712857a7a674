"""S-CVAE configuration (paper sections 4.1 and 4.3), flax-examples style ``get_config()``.

Frozen dataclasses; override from the command line with ``inbetween_jax.train.apply_overrides``, e.g.
``model.lstm_hidden=64 train.batch_size=8``.  ``get_config("tiny")`` is the small variant used by tests.
"""
from __future__ import annotations

import dataclasses


@dataclasses.dataclass(frozen=True)
class ModelConfig:
    enc_hidden: int = 512          # state / offset / target encoders: 3 FC layers in -> 512 -> 512 -> 256
    enc_out: int = 256             # also the time-to-arrival embedding size
    tta_basis: float = 10000.0
    tta_max: int = 60              # tta is clipped to this (frames)
    lstm_hidden: int = 768         # encoder LSTM
    head_hidden: int = 768         # latent heads: FC 768 -> FC 2*latent (mu, log-variance)
    latent_dim: int = 16
    dec_lstm_hidden: int = 768     # decoder LSTM (input z + state emb + target emb = 16 + 256 + 256 = 528)
    expert_hidden: tuple = (512, 256)   # experts 768 -> 512 -> 256 -> out
    num_experts: int = 4
    gating_hidden: tuple = (64, 32)     # gating 4 -> 64 -> 32 -> 4
    phase_hidden: int = 256        # phase-update network
    disc_hidden: tuple = (512, 256)
    disc_long: int = 10            # long discriminator window (frames)
    disc_short: int = 2            # short discriminator window (frames)
    buffer_k: int = 4              # K, synthesis-buffer length (clipped to floor(L/2) - 1)
    # ablation switches (Table 6)
    bidirectional: bool = True     # False: "w/o BS", forward generator only
    latent_interp: bool = True     # False: "w/o LI", sample from the current-frame distribution
    aligning: bool = True          # False: "w/o BA", always condition on the true end frame
    phase_moe: bool = True         # False: "w/o PM", one MLP expert instead of the phase-gated MoE
    encoder_lstm: bool = True      # False: "w/o LSTM", MLP in place of the encoder LSTM
    discriminators: bool = True    # False: "w/o D"
    stitch_loss: bool = True       # False: "w/o SL"


@dataclasses.dataclass(frozen=True)
class LossConfig:
    beta_quat: float = 1.0
    beta_vel: float = 1.0
    beta_contact: float = 0.1
    alpha_kl: float = 1.0
    alpha_stitch: float = 0.5
    alpha_fk: float = 0.5
    alpha_d: float = 0.1
    alpha_g: float = 0.1
    phase: float = 1.0             # phase-network regression loss (its own parameters only)


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    lr: float = 1e-4
    b1: float = 0.5
    b2: float = 0.9
    weight_decay: float = 1e-5
    batch_size: int = 32
    grad_clip: float = 1.0
    trans_start: int = 5           # progressive training: transition length (frames between keyframes - 1)
    trans_max: int = 48            # 50-frame windows with one past frame allow at most 48 transition frames
    epochs_per_increment: float = 2.0   # +1 frame every 2 epochs
    num_steps: int = 20000
    log_every: int = 50
    ckpt_every: int = 500
    seed: int = 0
    deferred_wgrad: bool = True    # speed only: the largest weight gradients as one matmul after the scan


@dataclasses.dataclass(frozen=True)
class Config:
    model: ModelConfig = ModelConfig()
    loss: LossConfig = LossConfig()
    train: TrainConfig = TrainConfig()


def get_config(variant: str = "paper") -> Config:
    """``"paper"``: sizes and weights of the paper.  ``"tiny"``: small widths for tests.
    ``"cpu"``: half widths, for long CPU runs."""
    cfg = Config()
    if variant == "paper":
        return cfg
    if variant == "tiny":
        return dataclasses.replace(cfg, model=dataclasses.replace(
            cfg.model, enc_hidden=32, enc_out=16, lstm_hidden=32, head_hidden=32, latent_dim=4,
            dec_lstm_hidden=32, expert_hidden=(32, 16), gating_hidden=(8, 8), phase_hidden=16,
            disc_hidden=(16, 16), buffer_k=2),
            train=dataclasses.replace(cfg.train, batch_size=4, trans_start=10, trans_max=10, log_every=5,
                                      ckpt_every=5, lr=1e-3))
    if variant == "cpu":
        return dataclasses.replace(cfg, model=dataclasses.replace(
            cfg.model, enc_hidden=256, enc_out=128, lstm_hidden=384, head_hidden=384,
            dec_lstm_hidden=384, expert_hidden=(256, 128), phase_hidden=128, disc_hidden=(256, 128)))
    raise ValueError(f"unknown S-CVAE config variant {variant!r}; choose paper, tiny or cpu")


def config_from_dict(d: dict) -> Config:
    """Inverse of ``inbetween_jax.train.config_to_dict`` for this config (lists become tuples)."""
    def build(cls, sub):
        kw = {k: tuple(v) if isinstance(v, list) else v for k, v in (sub or {}).items()}
        return cls(**kw)
    return Config(model=build(ModelConfig, d.get("model")), loss=build(LossConfig, d.get("loss")),
                  train=build(TrainConfig, d.get("train")))
