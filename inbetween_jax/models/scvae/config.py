"""S-CVAE configuration (paper sections 4.1 and 4.3): ``Config(model, data, loss, train)``.

Frozen dataclasses; override from the command line with ``inbetween_jax.train.apply_overrides``, e.g.
``model.lstm_hidden=64 train.batch_size=8 data.trans_max=30``.

Presets:

* ``paper`` -- the sizes, weights and schedule of the paper (about 27 M parameters, 20,000 steps).
* ``cpu`` -- the paper's method at a CPU budget: quarter widths (``CPU_WIDTHS``), ``CPU_STEPS`` steps, the
  progressive schedule to 50 frames ramped over the first third of the steps with the scan length bucketed
  (``data.bucket``), AdamW with cosine decay, checkpoint chosen on a validation split of the training files.
  The faithful row of the benchmark.
* ``improved`` (default) -- the same widths, data and budget as ``cpu``, with what the measurements of
  docs/results/scvae.md say the paper's design lacks at this budget:
  - ``model.residual``: the decoder predicts offsets from the Slerp (rotations) / lerp (root) path between
    the keyframes instead of integrating its own velocities; its output layer starts at zero, so the
    untrained model is exactly Slerp (the paper's decoder sees the target only through z, and the KL term
    keeps z nearly empty: its middle frames ignore where the target is);
  - ``model.decoder_target``: the offset-to-target embedding (with time-to-arrival) also enters the decoder;
  - ``loss.kl_reduce="mean"``: KL averaged over the latent dimensions (the paper sums 16 of them against
    element-mean reconstruction terms);
  - ``model.search=8``: the paper's test-time latent pair search (N pairs drawn, vmapped; the pair whose
    generators meet best is kept);
  - ``data.length_mode="mixed"``: after the ramp each batch draws its length up to 50 frames (the paper
    trains at the current length only), so 10-frame transitions are not forgotten;
  - ``model.discriminators=False`` and ``loss.alpha_fk=2.0``: no adversarial terms (no gain measured at this
    budget, a third of the step time) and more weight on joint positions, the L2P metric.
* ``tiny`` -- small widths and a fixed 10-frame transition, for tests.

``model.start_velocity`` (off in every preset) feeds the past frame's root velocity to the forward generator,
for protocols with more than one past frame; ``model.base_velocity`` (with ``residual``) makes the residual base
continue the motion of the frame before the start keyframe (root and every joint, a cubic Hermite offset that
fades into Slerp by the target, :mod:`inbetween_jax.models.scvae.base_path`).  Both together are the
``improved-velocity`` preset: ``improved`` for the official LaFAN1 protocol (10 past frames), trained with the
frame before each start keyframe; its one-keyframe (Table-1) rows see a zero velocity.
``model.base_damping`` (off in every preset) fades the continued motion by ``exp(-base_damping * t)``: alone,
0.1 per frame is better than the plain cubic on both validation splits (which overshoots beyond 15 frames), but
the model trained on it scored worse on the CMU validation windows than the one trained on the plain cubic
(docs/results/scvae.md), so the preset keeps the plain cubic.

Inference only, off in every preset: the transition bank (:mod:`inbetween_jax.models.scvae.bank`;
``model.bank_k`` / ``model.bank_tau`` / ``model.bank_weight``) blends the samples with the warped mean of the
k nearest training transitions, read from ``bank.npz`` in the run folder (``inbetween build-bank`` writes
it and sets the switches).  It helps where the training motion covers the test motion (LaFAN1) and hurts on
the CMU test subjects (docs/results/scvae.md, "Transition bank"), so the shipped CMU weights leave it off.
``model.bank_base`` (with ``residual``; off in every preset) goes further and trains the network on top of the
bank: its residual base is the bank's transition instead of Slerp / lerp.  In training each window's base comes
from a bank of the training files without the window's own file (the run folder's ``bank.npz``, written when
training starts), so the network learns to correct the retrieval it will get on unseen motion.  Measured on
LaFAN1 at 3,000 steps it adds about 1 % to the bank alone and loses to the blend at 50 frames (docs/results/scvae.md).
``model.bank_sample_weight`` (inference only, 0 in every preset, 0.15 in the shipped CMU weights): with more than
one sample, sample 0 stays the fill and sample s >= 1 moves by this weight toward the bank's s-th nearest
transition (:func:`~inbetween_jax.models.scvae.bank.sample_blend`), so the samples differ by captured motion
(docs/results/scvae.md, "the sampled mode").

``model.context_base`` (inference only, off in every preset, on in the shipped CMU weights): where the frames
beside the keyframes are known (``inbetween infill`` inside a file), the fill's departure from Slerp / lerp is
added onto the two-sided Hermite path that continues the motion on both sides
(:mod:`inbetween_jax.models.scvae.context`, damped by ``model.context_damping``), not onto Slerp; the velocity
it continues is capped (``model.context_max_turn`` radians per joint and ``model.context_max_step`` leg lengths
of root travel per frame), so a capture's start-up frame or a glitch beside a keyframe cannot throw it off.  The
Table-1 protocol (two keyframes) is unchanged.

``data.mirror`` (off in every preset) adds every training window's left-right mirror image
(:meth:`~inbetween_jax.data.windows.MotionWindows.mirrored`): twice the windows, a body's motion again.
``data.tempo`` (off in every preset; e.g. ``data.tempo=0.8,1.25``) adds, for each speed ``s``, the training files
read at ``fps / s`` and played at ``fps`` (``s`` > 1 faster): walks at other paces, the same real motion.
``data.balance`` (off in every preset) draws training windows with weight ``n_g ** -balance`` (``n_g``: the
windows of their CMU activity group, :func:`inbetween_jax.data.activities.activity_group`): 1 balances the groups,
0.5 halves their imbalance on a log scale.

``model.motion_latent`` (off in ``paper`` / ``cpu``; :mod:`inbetween_jax.models.scvae.motion_latent`) adds one latent
per transition whose posterior sees the true in-between and whose prior is learned from the keyframes; the decoder
gets it beside z.  The paper's per-step z comes from an encoder that only sees generated frames, so it can carry
nothing and ten samples come out the same.  ``loss.motion_free_bits`` sets how many nats per dimension it may carry
for free; ``loss.prior_path`` also trains the fill from the prior's mean.  ``model.motion_temperature`` and
``model.motion_spread`` shape the draws at inference (docs/results/scvae.md, "Samples that differ").

``model.deferred_wgrad`` is a speed switch only (the largest weight gradients as one matmul after the scan, see
:mod:`inbetween_jax.models.scvae.deferred_grads`); it does not change the losses.  So is ``model.remat`` (on in
every preset, ``dots``): the rollout's backward pass keeps only the matmul outputs of each step and recomputes
the rest (:mod:`inbetween_jax.train.remat`); ``model.remat=`` keeps everything, as before 2026-12-07.
"""
from __future__ import annotations

import dataclasses

from inbetween_jax.train.config import TrainConfig

PRESETS = ("improved", "improved-velocity", "cpu", "paper", "tiny")
DEFAULT_PRESET = "improved"


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
    # speed only (same losses): the largest weight gradients as one matmul after the scan
    deferred_wgrad: bool = True
    remat: str = "dots"            # speed only (same losses): what the rollout's backward pass keeps (train/remat.py)
    # beyond the paper (the ``improved`` preset; all off = the paper's model)
    residual: bool = False         # decoder predicts offsets from the Slerp / lerp path (zero-initialised head)
    decoder_target: bool = False   # the decoder also sees the offset-to-target embedding (with tta added)
    start_velocity: bool = False   # the start keyframe carries the past frame's root velocity (official protocol)
    base_velocity: bool = False    # residual base continues the start's velocity (Hermite, needs the past frame)
    base_damping: float = 0.0      # ... with that offset faded by exp(-base_damping * t) (per frame; 0: plain cubic)
    search: int = 1                # test-time latent pair search: candidates per sample (paper: "N pairs")
    bank_k: int = 0                # inference: blend in the mean of the k nearest bank transitions (0: off; .bank)
    bank_weight: float = 0.0       # inference: its weight (0: the network alone; 1: the bank alone)
    bank_tau: float = 0.0          # inference: > 0 weights the k by exp(-(d - d1) / (tau d1)); 0: uniform
    bank_base: bool = False        # residual base = the bank's k-nearest transition (bank_k, bank_tau), not Slerp
    bank_sample_weight: float = 0.0  # inference, more than one sample: sample s >= 1 blends in the bank's s-th nearest
    bank_sample_gated: bool = False  # ... by that weight times the gate's (with ood_gate): none where the gate closes
    timing_spread: float = 0.0       # sampled mode, two keyframes alone: samples s >= 1 also replayed earlier / later
                                     # (timing.retimed), warp amplitudes up to this (< 1); 0: off
    timing_parts: bool = False       # ... half of them with arms, legs and sides on their own clocks (timing.py)
    timing_spread_fallback: float = 0.0  # ... the two-keyframe spread where the gate falls back to Slerp (its weight
                                     # 0), lerped toward timing_spread as the weight rises
                                     # (bank.sample_timing_spread); 0: off
    timing_spread_in_clip: float = 0.0  # ... the spread inside a clip (frames beside the keyframes known); 0: off
    ood_gate: bool = False         # inference: blend toward Slerp / lerp as the keyframes leave the training motion
    context_base: bool = False     # inference: frames beside the keyframes known -> onto the Hermite path (.context)
    context_gate: bool = True      # ... and there the gate's own thresholds, calibrated against that path (ood.npz's
                                   # context_gate_lo / _hi, when it holds them; else the two-keyframe gate's)
    context_damping: float = 0.1   # ... its velocity terms faded by exp(-context_damping * t) (per frame)
    context_max_turn: float = 0.35  # ... the neighbours' joint turn capped at this many radians per frame (0: no cap)
    context_max_step: float = 0.35  # ... and their root step at this many leg lengths per frame (0: no cap)
    motion_latent: int = 0         # > 0: a per-transition latent of this size, posterior sees the gap (.motion_latent)
    motion_hidden: int = 128       # its posterior / prior MLP width
    motion_spread: int = 1         # sampling: > 1 picks the N motion draws far apart among this x N prior draws
    motion_temperature: float = 1.0  # sampling: the prior's standard deviation scaled by this (0: its mean)
                                   # (the run folder's ood.npz, models/ood.py; on in the shipped weights)

    @property
    def uses_past_frame(self) -> bool:
        """Training and the past-frame protocols give the start keyframe the frame before it."""
        return self.start_velocity or self.base_velocity


@dataclasses.dataclass(frozen=True)
class DataConfig:
    """Progressive training (paper 4.1): the transition length (frames between the keyframes - 1) starts at
    ``trans_start`` and grows by one frame every ``epochs_per_increment`` epochs (an epoch: ``N windows /
    train.batch_size`` steps) up to ``trans_max``; ``trans_max + 1`` also fixes the rollout's static length."""
    trans_start: int = 5
    trans_max: int = 48            # 50-frame windows with one past frame allow at most 48 transition frames
    epochs_per_increment: float = 2.0   # +1 frame every 2 epochs
    ramp_steps: int = 0            # > 0: the same ramp linearly over this many steps (not per epoch)
    length_mode: str = "progressive"    # "mixed": each batch draws its length uniformly up to the current one
    bucket: int = 0                # > 0: scan length rounded up to a multiple of this (cheaper short stages)
    window: int = 0                # training window frames (0: the source's default, 50 at offset 20)
    mirror: bool = False           # add every training window's left-right mirror image (not the paper)
    tempo: tuple = ()              # extra copies of the training files played at these speeds (not the paper)
    balance: float = 0.0           # window weight ~ (its activity group's window count)^-balance (0: uniform)


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
    kl_reduce: str = "sum"         # "sum" over latent dimensions (paper) or "mean"
    free_bits: float = 0.0         # nats per latent dimension not penalised (0: plain KL)
    alpha_motion: float = 1.0      # weight of the motion latent's KL(q || p) term (model.motion_latent > 0)
    motion_free_bits: float = 0.5  # nats per motion-latent dimension the posterior carries at no cost
    prior_path: bool = False       # motion latent: also roll out each window from the prior's mean (2x the batch)


# the CPU-sized model of the ``cpu`` (paper's method) and ``improved`` presets, and their shared budget
CPU_WIDTHS = dict(enc_hidden=128, enc_out=64, lstm_hidden=128, head_hidden=128, dec_lstm_hidden=128,
                  expert_hidden=(128, 64), phase_hidden=64, disc_hidden=(64, 32))
CPU_STEPS = 3000

_TRAIN = TrainConfig(num_steps=20000, batch_size=32, lr=1e-4, b1=0.5, b2=0.9, weight_decay=1e-5, grad_clip=1.0,
                     log_every=50, ckpt_every=500, seed=0)


@dataclasses.dataclass(frozen=True)
class Config:
    model: ModelConfig = ModelConfig()
    data: DataConfig = DataConfig()
    loss: LossConfig = LossConfig()
    train: TrainConfig = _TRAIN


def get_config(preset: str = DEFAULT_PRESET) -> Config:
    """``"paper"``, ``"cpu"``, ``"improved"``, ``"improved-velocity"`` or ``"tiny"`` (module docstring)."""
    cfg = Config()
    if preset == "paper":
        return cfg
    if preset == "tiny":
        return dataclasses.replace(
            cfg,
            model=dataclasses.replace(cfg.model, enc_hidden=32, enc_out=16, lstm_hidden=32, head_hidden=32,
                                      latent_dim=4, dec_lstm_hidden=32, expert_hidden=(32, 16), gating_hidden=(8, 8),
                                      phase_hidden=16, disc_hidden=(16, 16), buffer_k=2),
            data=dataclasses.replace(cfg.data, trans_start=10, trans_max=10),
            train=dataclasses.replace(cfg.train, batch_size=4, log_every=5, ckpt_every=5, lr=1e-3))
    if preset in ("cpu", "improved"):
        cfg = dataclasses.replace(
            cfg, model=dataclasses.replace(cfg.model, **CPU_WIDTHS),
            data=dataclasses.replace(cfg.data, trans_max=50, window=60, ramp_steps=CPU_STEPS // 3, bucket=17),
            train=dataclasses.replace(cfg.train, num_steps=CPU_STEPS, lr=5e-4, b1=0.9, b2=0.99,
                                      lr_schedule="cosine", lr_final=0.04, warmup_steps=100, ckpt_every=250,
                                      log_every=25, split="fit", keep_checkpoints=0))
        if preset == "cpu":
            return cfg
        cfg = dataclasses.replace(
            cfg, model=dataclasses.replace(cfg.model, residual=True, decoder_target=True, search=8,
                                           discriminators=False),
            data=dataclasses.replace(cfg.data, length_mode="mixed"),
            loss=dataclasses.replace(cfg.loss, kl_reduce="mean", alpha_fk=2.0))
        if preset == "improved":
            return cfg
    if preset == "improved-velocity":
        cfg = get_config("improved")
        return dataclasses.replace(cfg, model=dataclasses.replace(cfg.model, start_velocity=True, base_velocity=True))
    raise ValueError(f"unknown S-CVAE preset {preset!r}; choose {', '.join(PRESETS)}")
