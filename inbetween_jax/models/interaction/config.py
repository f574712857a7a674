"""Interaction in-betweening configuration (Zhang et al. 2025, "Motion In-Betweening for Densely Interacting
Characters").

``Config(model, data, loss, train)`` of frozen dataclasses; override from the command line with dotted keys,
e.g. ``model.hidden=64 train.batch_size=8 model.interaction=false``.  Presets (:data:`PRESETS`):

* ``improved`` (default): ``cpu``'s widths, batch and steps plus switches that depart from the paper, each
  against a failure measured with the paper's method (docs/results/interaction.md: L2P equal to holding the
  last frame, 0 % of rollouts reaching the keypose threshold, a GAN that made L2P and foot sliding worse):

  - ``data.key_inside=0.5``: half of every batch has its keyframe inside the predicted frames, the frames
    after it held at the keypose.  The paper places every keyframe 1-21 frames beyond the last supervised
    frame, so its model is never taught to arrive, and its stop rule (within ``stop_threshold``) never fires.
  - ``model.key_offsets``: per-joint offsets keypose - last input frame as input (the paper gives the
    keypose only; the offset is what the motion has to cover).
  - ``model.residual``: the output is a residual on a lerp from the last input frame to the keypose
    (zero-initialised output layers: an untrained model returns the lerp, which beats the trained paper model).
  - ``model.tta``: time-to-arrival input, frames to the keyframe.  The paper states it has no timing
    condition; with it ``--frames N`` in infill and the evaluation's gap lengths are honoured (rollouts
    without a gap guess one from the keypose distance, :func:`.model.guess_gap`).
  - ``data.ar_steps=4`` (40 predicted frames, paper 30), keyframes outside at 60-80 (1-21 frames beyond,
    as the paper), ``data.ss_max=1.0`` over 1,000 steps (full feedback; ``cpu``: 0.5): long rollouts feed
    back their own predictions, so training does too.
  - ``loss.w_adv=0.001`` from step 1,500, ramped over 1,500 steps (``cpu``: 0.01 from step 0, where the
    discriminator dominated the MSE from the start).
  - ``loss.w_pos=20``: the position channels (metres) weigh 20x in every MSE.  With the paper's plain MSE
    over the 9 channels the 6 rotation channels (unit vectors) dominate: the 1,000-step real-pair run
    improved L2Q by 30 % over interpolation while its L2P got worse than its own untrained lerp, on the
    training takes too (3.85 -> 4.16 at 30 frames).
  - ``model.residual`` also starts the refiner at the identity (zero output layer).
  - ``train.split=fit``: one training take is held out (:func:`~.data.split_pairs`) and the checkpoint is
    chosen on it at the end of the run (``bench.val_score``); the paper selects on its 5 % validation part.
  - ``train.lr_schedule=cosine`` (50 warm-up steps, down to 5 % of 1e-3), as the other models' ``improved``
    presets, and batches of 32 for 1,500 steps (scheduled sampling ramped over 1,000): the same 48 k samples as
    ``cpu``'s 3,000 x 16.  With the constant lr the validation score jumped 5.02-5.63 between neighbouring
    checkpoints and stayed at interpolation's level (4.97); with the decay it reaches 4.48 (batch 32, 1,500
    steps), against 4.53 (batch 16, 1,500 steps) and 4.57 / 4.54 (batch 16 / 32, 3,000 steps, ramp over 2,000,
    adversarial term from step 1,500; docs/results/interaction.md).
    The adversarial term starts at step 1,500, so it is off in this budget; ``train.num_steps=3000`` turns it
    on as measured there.
  - ``model.refiner=false``: the refiner is still trained (its loss sees stop-gradient predictions, so the
    generator is the same either way) but not applied at inference: on the held-out take it raised the
    30 / 50-frame L2P from 5.03 to 5.45 (step 750, docs/results/interaction.md).  ``model.refiner=true``
    puts it back.
* ``cpu``: the paper's method at CPU size: sizes and schedule chosen for a ~30 min CPU run (the paper lists
  no layer sizes).
* ``paper``: the values the paper states (Sec. 5.1 / 4.2: T = 20, l = 10, P = 3 (30 predicted frames),
  keyframe 50-70 frames after the window start, mirroring, C_phi = 15, N = 30, 90/5/5 split, Adam
  lr 1e-4, b1 0.9, b2 0.999); everything it does not state keeps the ``cpu`` value (see :func:`get_config`).
* ``tiny``: the test variant.

Ablation switches (Table 1): ``model.interaction`` (False: "w/o interaction modeling", each character
in-betweened independently in its own keypose space), ``model.gan`` ("w/o Inter. GAN"),
``model.refiner`` ("w/o Motion Refiner").  Beyond the paper (all off in ``paper`` / ``cpu``):
``data.key_inside``, ``model.key_offsets``, ``model.residual``, ``model.tta``, ``loss.w_pos``,
``loss.adv_start`` / ``loss.adv_ramp``, ``loss.w_speed`` (0 in every preset: a phase-free motion-energy
term, :func:`.losses.speed_energy`; the model's rollouts move at about 60 % of the capture's joint speed, ninth
round of docs/results/interaction.md).  Training-data augmentation, off in every preset (measured in the
sixth round of docs/results/interaction.md: no gain on the validation take): ``data.tempo`` (copies of the
training takes played faster / slower, e.g. ``data.tempo=0.8,0.9,1.1,1.25``) and ``data.reverse``
(time-reversed copies).  Ensembles: ``model.members=M`` (1 in every preset) trains M networks side by side
in one run (``vmap``; each its own initialisation, batches and keys, so M times the compute) and selects and
ships them as one model whose rollout is the mean of the members' rollouts (:func:`.model.rollout`).  A gap
told as a guess: ``data.tta_guess=p`` (0 in every preset; needs ``model.tta``) tells a fraction p of every batch
the evaluation's distance / speed guess of the gap instead of the true one, with a 4th time-to-arrival input
saying which (:func:`.model.tta_flagged`); rollouts told a guessed gap (the bench's "gap guessed" rows, or a
rollout that guesses its own) pass ``gap_known=False``, so the model can learn how wrong the guess tends to be.
Inference only, off in every preset: the motion bank (:mod:`.bank`; ``model.bank_k`` / ``model.bank_weight``
blend in the mean of the k nearest training windows, warped onto the gap's ends; ``model.texture_sigma`` /
``model.texture_gain`` add the nearest window's high-frequency position band; ``model.bank_guessed`` blends
the in-between in with a guessed gap too, over the gap the network's rollout takes), read from ``bank.npz`` in the run
folder (``inbetween build-bank`` writes it and sets the switches).  The
autoregressive training length (``data.ar_steps``) and the scheduled-sampling curriculum
(``data.ss_ramp_steps``, ``data.ss_max``) are ``data`` fields: they decide which frames a training sample holds
and how often predictions are fed back as inputs.
``model.remat`` is a speed switch only (the losses are unchanged; :mod:`inbetween_jax.train.remat`): the empty
string, every preset's, keeps everything the training autoregression's backward pass reads; ``dots`` keeps the
matmul outputs of each step and recomputes the rest.  ``dots`` is 6 % faster per step in an interleaved A/B, but
whole training runs took 5-7 % longer with it, in five runs of the time-to-quality recipe on two days
(docs/results/speed.md, "the interaction model keeps everything").
"""
from __future__ import annotations

import dataclasses

from inbetween_jax.train.config import TrainConfig

__all__ = ["ModelConfig", "DataConfig", "LossConfig", "Config", "PRESETS", "DEFAULT_PRESET", "get_config"]

PRESETS = ("improved", "cpu", "paper", "tiny")
DEFAULT_PRESET = "improved"


@dataclasses.dataclass(frozen=True)
class DataConfig:
    pair_distance: float = 150.0   # constructed pairs: second performer this far in front (file units, cm)
    pos_scale: float = 0.01        # positions enter the model in metres
    n_input: int = 20              # T: observed frames
    n_pred: int = 10               # l: frames predicted per autoregressive step
    ar_steps: int = 3              # P: autoregressive steps per training sample (P * l predicted frames)
    key_min: int = 50              # keyframe sampled 50..70 frames after the window start (Sec. 5.1)
    key_max: int = 70
    mirror: bool = True            # mirroring augmentation (p = 0.5)
    split: tuple = (0.85, 0.05, 0.10)   # temporal train / val / test fractions of every pair
    ss_ramp_steps: int = 1500      # scheduled sampling: P(feed back prediction) ramps 0 -> ss_max
    ss_max: float = 0.5
    key_inside: float = 0.0        # fraction of each batch whose keyframe lies inside the predicted frames
                                   # (n_input + 1 .. n_input + P*l - 1); frames after it are the held keypose
    tempo: tuple = ()              # real pairs: extra copies of every training take played at these speeds
    reverse: bool = False          # extra time-reversed copies of every training pair (after ``tempo``)
    tta_guess: float = 0.0         # with model.tta: this fraction of each batch is told the guessed gap
                                   # (distance / speed) instead of the true one, and a 4th time-to-arrival
                                   # feature says which (1 true, 0 guessed); inference passes gap_known


@dataclasses.dataclass(frozen=True)
class ModelConfig:
    dct_coeffs: int = 15           # DCT coefficients kept of the (n_input + n_pred)-frame padded window
    conv_channels: int = 8
    hidden: int = 64
    gcn_layers: int = 2
    latent: int = 8                # VAE latent per joint
    refiner_hidden: int = 64
    refiner_latent: int = 16
    pae_channels: int = 15         # C_phi
    pae_hidden: int = 64
    pjd_frames: int = 30           # N (Eq. 9) = data.ar_steps * data.n_pred
    pjd_joints: tuple = ()         # subset of joints for the PJD (empty: all)
    pjd_scale: float = 2.0         # PJD values (m^2 / frame) are multiplied by this
    disc_hidden: int = 64
    interaction: bool = True       # cross-space interaction modelling (transform + VAE + FiLM)
    gan: bool = True               # PAE + interaction discriminator
    refiner: bool = True           # motion refiner at inference
    latent_scale: float = 1.0      # inference: z = mu + latent_scale * sigma * eps (1: as trained; 0: the mean)
    stop_threshold: float = 0.15   # rollout stops when both characters' mean joint distance to keypose < this (m)
    max_frames: int = 200          # rollout cap
    key_offsets: bool = False      # per-joint offsets keypose - last input frame as extra node input
    tta: bool = False              # time-to-arrival input (frames from the last input frame to the keyframe)
    residual: bool = False         # predict a residual on a lerp from the last input frame toward the keypose
    lerp_frames: int = 30          # residual without tta: the lerp reaches the keypose this many frames ahead
    tta_speed: float = 0.03        # tta rollouts without a given gap: guess gap = keypose distance / this (m/frame)
    members: int = 1               # ensemble: this many networks trained side by side; a rollout is the
                                   # mean of the members' whole rollouts
    bank_k: int = 0                # inference: blend in the mean of the k nearest motion-bank windows (0: off)
    bank_weight: float = 0.0       # inference: its weight (0: the network alone; 1: the bank alone)
    texture_sigma: float = 0.0     # inference: add the nearest bank window's position band above a Gaussian
                                   # low-pass of this many frames (0: off)
    texture_gain: float = 1.0      # inference: the texture's gain
    bank_guessed: bool = False     # inference: with a guessed gap, apply the bank over the gap the network's
                                   # own rollout takes (:func:`.bank.arrival_gaps`), not the guess (blend only)
    ease_frames: int = 0           # inference: the last N frames before the keypose take up the jump onto it
                                   # (:func:`.bank.ease_into_keypose`; 0: off, the paper; on in the shipped run)
    bank_sample_weight: float = 0.0  # inference, sampled mode (more than one sample): sample s >= 1 blends in the
                                   # s-th nearest bank window alone at this weight, with its texture (0: off)
    bank_pair_weight: float = 0.0  # inference: the bank's match also counts how the two characters stand at the
                                   # keyframe (:func:`.bank.pair_features`), at this weight (0: off)
    ood_gate: bool = False         # inference: blend toward per-character interpolation as the window's context
                                   # and keyposes leave the training takes (:mod:`.gate`; ood.npz in the run folder)
    bank_sample_gated: bool = True  # inference, with the gate: samples s >= 1 get their window's gate weight too
                                   # (False: only sample 0, the deterministic fill, is gated)
    remat: str = ""                # speed only (same losses): what the autoregression's backward pass keeps
    departure_cap: float = 0.0     # inference, with the gate: the fill departs from interpolation by at most this
                                   # many times interpolation's error as predicted from the context (:mod:`.gate`,
                                   # ``departure_weight``; 0: off)


@dataclasses.dataclass(frozen=True)
class LossConfig:
    w_mse: float = 1.0
    w_pos: float = 1.0             # weight of the position channels (metres) in every MSE; 1 = the paper
    w_coarse: float = 0.5          # auxiliary MSE on the coarse (individual) prediction
    w_kl: float = 1e-3
    w_adv: float = 0.01
    w_pae: float = 1.0
    w_refine: float = 1.0
    adv_start: int = 0             # the adversarial weight is 0 before this step ...
    adv_ramp: int = 0              # ... then ramps linearly to w_adv over this many steps (0: at once)
    w_speed: float = 0.0           # beyond the paper: phase-free motion-energy loss (losses.speed_energy)


# the former real-CPU-run settings of the train group (Adam 1e-3 behind a global-norm clip of 1)
_CPU_TRAIN = TrainConfig(num_steps=3000, batch_size=16, lr=1e-3, grad_clip=1.0, log_every=50, ckpt_every=250,
                         seed=0)


@dataclasses.dataclass(frozen=True)
class Config:
    model: ModelConfig = ModelConfig()
    data: DataConfig = DataConfig()
    loss: LossConfig = LossConfig()
    train: TrainConfig = _CPU_TRAIN


def get_config(preset: str = DEFAULT_PRESET) -> Config:
    """The ``improved``, ``paper``, ``cpu`` or ``tiny`` preset (ValueError naming the choices otherwise).

    ``improved`` is ``cpu`` plus the switches listed in the module docstring.

    ``paper`` differs from ``cpu`` in: ``train.lr`` 1e-4 (paper: Adam, lr 1e-4, b1 0.9, b2 0.999; ``cpu``
    raises the lr for short runs) and ``data.split`` (0.90, 0.05, 0.05) (paper: 90 / 5 / 5; ``cpu`` keeps 10 %
    for testing so that 221-frame long-horizon test windows fit).  The values the paper states and ``cpu``
    already uses: n_input 20, n_pred 10, ar_steps 3, key_min / key_max 50 / 70, mirror, pae_channels 15,
    pjd_frames 30.  Not stated, kept from ``cpu``: layer sizes, loss weights (lambda_mse / lambda_kl are
    named but not given), scheduled sampling, stop threshold, batch size, gradient clip and the number of
    steps (the paper trains 100 epochs, 40-50 h on a GPU).
    """
    if preset == "cpu":
        return Config()
    if preset == "improved":
        return Config(model=ModelConfig(key_offsets=True, residual=True, tta=True, pjd_frames=40, refiner=False),
                      data=DataConfig(ar_steps=4, key_min=60, key_max=80, key_inside=0.5, ss_max=1.0,
                                      ss_ramp_steps=1000),
                      loss=LossConfig(w_pos=20.0, w_adv=0.001, adv_start=1500, adv_ramp=1500),
                      train=dataclasses.replace(_CPU_TRAIN, split="fit", keep_checkpoints=0, lr_schedule="cosine",
                                                lr_final=0.05, warmup_steps=50, batch_size=32, num_steps=1500))
    if preset == "paper":
        return Config(data=DataConfig(split=(0.90, 0.05, 0.05)), train=dataclasses.replace(_CPU_TRAIN, lr=1e-4))
    if preset == "tiny":
        return Config(model=ModelConfig(dct_coeffs=30, conv_channels=4, hidden=32, gcn_layers=1, latent=4,
                                        refiner_hidden=16, refiner_latent=4, pae_channels=3, pae_hidden=8,
                                        pjd_joints=(0, 3, 7, 13), disc_hidden=16, max_frames=60),
                      data=DataConfig(ss_ramp_steps=10),
                      train=dataclasses.replace(_CPU_TRAIN, batch_size=4, num_steps=20, log_every=5,
                                                ckpt_every=10))
    raise ValueError(f"unknown interaction preset {preset!r}; choose {', '.join(PRESETS)}")
