"""Convolutional inpainting AE configuration (Kaufmann et al. 2020, Sec. 3): ``get_config(preset)``.

Frozen dataclasses ``Config(model, data, loss, train)``; override with ``key=value`` strings
(:func:`inbetween_jax.train.apply_overrides`), e.g. ``model.variant=vanilla model.channels=16,32,64,128,128
train.batch_size=16 data.mask.curriculum=false``.

Presets:

* ``paper`` -- the paper's model and training: channels (32, 64, 128, 256, 256), Adam at 1e-3, batch 80,
  200 epochs.  An epoch is ``ceil(#clips at stride data.epoch_stride / batch_size)`` steps of the training
  data (``data.steps_per_epoch = 0``); ``train.num_steps`` = 200 x 33 = 6600, the 200 epochs of the LaFAN1
  training files (subjects 1-4, 24 files: 2615 clips at stride 40, 33 steps per epoch).
* ``cpu`` -- the CPU-bounded real run of ``docs/results/cae.md``: quarter width (half at the last unit),
  batch 16, 20 steps per epoch, 80 epochs (1600 steps).
* ``improved`` (default) -- the ``cpu`` budget (same widths, batch 16, 20 steps per epoch, 1600 steps) with
  these departures from the paper, each a switch that the other presets leave off:

  - ``model.residual=true``: the gap is pre-filled by linear interpolation
    (:func:`~inbetween_jax.models.cae.masks.linear_prefill`), the network sees that image plus the mask as a
    second channel and predicts a residual added to the pre-filled image; its last conv is zero-initialised,
    so the untrained model returns linear fill in the gap and the input elsewhere.  Why: the paper's CAE must
    reconstruct the whole clip through a 3 x 8 bottleneck; at CPU size its reconstruction error alone
    (8.2 cm) is about linear fill's whole 1 s gap error, so it cannot win short gaps.  The residual form
    starts at linear fill and only has to learn the correction.
  - ``model.fill=hermite``: the pre-fill under the residual is the limited cubic Hermite fill
    (:func:`inbetween_jax.baselines.hermite_fill`: per row, the cubic through the gap's two edge frames with
    tangents from one-sided second-order differences just outside the gap, limited against the secant slope
    as Fritsch & Carlson's, factor 3) instead of the straight line (``model.fill=linear``, the default, so
    runs written before the switch -- the shipped weights among them -- keep linear fill).  Why: the CAE sees
    both sides of the gap, so the fill can match the velocities at both edges; on the embedded CMU test clips
    the fill alone is 0.91x / 0.96x / 0.99x linear fill's error at 1 / 2 / 4 s (0.95x / 1.00x / 1.02x on 123
    CMU training clips); the plain, unlimited Hermite cubic is 1.2x / 1.6x / 3.0x (docs/results/cae.md).  The
    bench lists the Hermite fill as a baseline row beside linear fill.
  - ``model.paste_known=true``: known entries are pasted back (output = input where mask = 1), in training
    and inference alike, so the loss only sees the missing entries and the reconstruction error is 0 by
    construction.  The price: an all-known input (de-noising, Table 2) is returned unchanged.
  - ``loss.gap_weight=4``: missing entries weigh 4x in the L1 (the paper's plain L1 is ``gap_weight=1``).
    With ``paste_known`` the known entries' error is 0 anyway; the weight matters without it.
  - ``data.mask.eval_matched=true`` with a short curriculum (mu 30 -> 120 by 30 every 2 epochs, 120 steps):
    after the curriculum, gap lengths are a uniform mixture around 30 / 60 / 120 frames (+-25 %), the
    evaluation's 1 s / 2 s / 4 s at 30 Hz, instead of N(120, 20^2) (which made the ``cpu`` run trade short
    gaps for long ones, docs/results/cae.md).
  - ``train.lr_schedule=cosine`` (20 warm-up steps, down to 5 % of 1e-3): the ``cpu`` run only improved
    once its lr was lowered by hand.
  - ``train.split=fit``: about 10 % of the training files are held out and the checkpoint is chosen on them
    at the end of the run (``bench.val_score``: gap error / linear fill's at 1 s and 2 s, 96-frame clips).

  Not in ``improved``, measured and left as a switch: ``model.skips=true`` (U-Net skip connections, each
  decoder unit also sees the matching encoder unit's activation).  Without them the residual never leaves
  linear fill (a 200-step probe on CMU moved the gap L1 from 0.5791 to 0.5791; with skips to 0.5345).  With
  them the full 1,600-step CMU run beats linear fill on its training clips (0.87x / 0.83x / 0.80x at 1 / 2 / 4 s)
  but is 1.81x / 1.47x / 1.27x worse than linear on the test subjects 13 / 14 (docs/results/cae.md): the
  correction it learns does not carry over, so the default stays at linear fill plus a negligible correction.

  Also beyond the paper and off in every preset, both a left-right mirror of the representation
  (:func:`~inbetween_jax.models.cae.features.mirror_rows`): ``data.mirror=p`` mirrors each training clip with
  probability p, and ``model.mirror_average=true`` (inference only; ``ship_weights --set`` accepts it) returns
  the mean of the fill and the un-mirrored fill of the mirrored clip, so the fill is mirror-equivariant.  They
  matter only where the residual has learnt something (LaFAN1 with skips: 0.89x -> 0.87x linear at 4 s,
  docs/results/cae.md); on the shipped CMU weights, which stay at their fill, the average moves the validation
  score by 0.1 %.  ``data.tempo`` (off in every preset; e.g. ``data.tempo=0.8,1.25``) adds, for each speed
  ``s``, the training motions read at ``30 / s`` fps and played at 30 (``s`` > 1 faster): the same real motion
  at other paces, as the S-CVAE's ``data.tempo``.
* ``tiny`` -- tests: tiny widths, 64-frame clips from 2 motions, batch 4, 2 steps per epoch, 8 steps.
"""
from __future__ import annotations

import dataclasses

from inbetween_jax.train.config import TrainConfig

__all__ = ["ModelConfig", "MaskConfig", "DataConfig", "LossConfig", "Config", "PRESETS", "DEFAULT_PRESET",
           "get_config"]

PRESETS = ("improved", "cpu", "paper", "tiny")
DEFAULT_PRESET = "improved"


@dataclasses.dataclass(frozen=True)
class ModelConfig:
    variant: str = "cae"                        # cae | vanilla | holden1d
    channels: tuple = (32, 64, 128, 256, 256)   # encoding-unit outputs (paper, Fig. 4)
    leak: float = 0.2                           # leaky-ReLU slope
    holden_hidden: int = 256                    # holden1d: hidden channels
    holden_width: int = 25                      # holden1d: temporal kernel width
    residual: bool = False                      # linear pre-fill + mask channel in, residual out (not the paper)
    paste_known: bool = False                   # output = input where mask = 1 (not the paper)
    skips: bool = False                         # U-Net skip connections, CAE variant only (not the paper)
    fill: str = "linear"                        # residual form's pre-fill: linear | hermite (not the paper)
    mirror_average: bool = False                # inference: mean of the fill and the un-mirrored fill of the
                                                # left-right mirrored clip (not the paper)
    ood_gate: bool = False                      # inference: blend toward the fill as the gap's context leaves the
                                                # training motion (ood.npz, models/ood.py; on in the shipped weights)
    knn_gate: bool = True                       # ... capped by the k-NN cap of ood.npz when it holds one (novel
                                                # contexts: cae/gate.py)
    net_edge_fade: float = 0.0                  # inference: the network's fill meets each keyframe at the capture's
                                                # speed, the difference fading as exp(-this * frames) (edges.py)
    base_edge_fade: float = 0.0                 # inference, model.fill=hermite: the gate's base for whole gaps gives
                                                # back the edge velocity the tangent limiter cut, fading as
                                                # exp(-this * frames) from each edge (hermite_fill(edge_fade=)); 0: the
                                                # pre-fill itself
    root_bound: float = 0.0                     # inference: the root path stays within this many metres of the
                                                # base's root path (0: unbounded, the paper)
    root_edge_fade: float = 0.0                 # inference, with root_bound: that base root path gives back the edge
                                                # velocity its tangent limiter cut, fading as exp(-this * frames)
                                                # (features.root_base_path); 0: the limited Hermite
    match_k: int = 0                            # inference, inside a file: blend in the k nearest training windows
                                                # of each gap's context (bank.npz, models/cae/bank.py); 0: off
    match_lo: float = 0.0                       # match distance at and below which the matched fill is kept whole
    match_hi: float = 0.0                       # match distance at and above which the gap keeps its fill
    match_disp: float = 0.25                    # weight of the root's displacement and turn across the gap
    match_departure: float = 0.5                # a match departing further from the fill than this share of the
                                                # body's travel beside the gap is not used (bank.departure)
    match_speed_scale: float = 0.0              # > 0: the gate reads the distance / (1 + root speed beside the gap
                                                # / this, cm per frame) (bank.gate_distance); 0: the distance
    global_base_near: float = 0.0               # inference, inside a file: the gate's base is the limited Hermite of
                                                # the global joint positions where the root is expected to travel at
                                                # most this many metres across the gap (global_base.py) ...
    global_base_far: float = 0.0                # ... the body-frame base from this many metres, a blend between;
                                                # 0: off (the body-frame base everywhere)
    global_base_fade: float = 0.2               # that global Hermite's edge fade per frame (hermite_fill(edge_fade=))


@dataclasses.dataclass(frozen=True)
class MaskConfig:
    """Training corruption (Sec. 3.3): a gap of mean ``mu_e`` (curriculum over epochs) or 1-3 joints removed."""
    curriculum: bool = True      # mu_e schedule; False -> gaps of fixed mean ``fixed_mu``
    mu_start: float = 10.0       # "We initialize mu_e to 10, and increase it until 120 by steps of 10 every 5 epochs"
    mu_end: float = 120.0
    mu_step: float = 10.0
    every_epochs: int = 5
    fixed_mu: float = 60.0       # the paper's "(60)" models
    sigma: float = 20.0          # gap-length std (fixed)
    p_joint: float = 0.3         # probability of the joint-row corruption instead of a gap
    max_joints: int = 3          # 1..max_joints joints removed over the whole clip
    eval_matched: bool = False   # after the curriculum (or from step 0 without it): gap lengths matched to evaluation
    matched_frames: tuple = (30, 60, 120)   # eval_matched: mixture centres (frames), one drawn uniformly
    matched_spread: float = 0.25            # eval_matched: length uniform on centre x [1 - spread, 1 + spread]


@dataclasses.dataclass(frozen=True)
class DataConfig:
    clip_length: int = 240       # T for training (paper: 240 frames)
    steps_per_epoch: int = 0     # steps per curriculum epoch; 0: the clips at ``epoch_stride`` / batch_size
    epoch_stride: int = 40       # clip stride that defines an epoch when steps_per_epoch = 0
    std_eps: float = 1e-3        # floor of the per-row std (rows that never vary, e.g. root x / z)
    max_motions: int = 0         # >0: use only the first N training motions (tests)
    mirror: float = 0.0          # probability that a training clip is mirrored left-right (not the paper)
    tempo: tuple = ()            # extra copies of the training motions played at these speeds (not the paper)
    mask: MaskConfig = MaskConfig()


@dataclasses.dataclass(frozen=True)
class LossConfig:
    """The paper's loss is the plain L1 error ``mean |X - X_hat|`` over the whole clip (every row and frame,
    known and missing alike; ``gap_weight = 1``).  ``gap_weight`` w > 1 weighs missing entries w times:
    ``sum(W |X - X_hat|) / sum(W)`` (:func:`inbetween_jax.models.cae.losses.weighted_l1`)."""
    gap_weight: float = 1.0


@dataclasses.dataclass(frozen=True)
class Config:
    model: ModelConfig = ModelConfig()
    data: DataConfig = DataConfig()
    loss: LossConfig = LossConfig()
    train: TrainConfig = TrainConfig(num_steps=200 * 33, batch_size=80, lr=1e-3, log_every=20, ckpt_every=200,
                                     seed=0)


def get_config(preset: str = DEFAULT_PRESET) -> Config:
    """The ``paper``, ``cpu``, ``improved`` or ``tiny`` preset (see the module docstring)."""
    if preset == "paper":
        return Config()
    if preset == "cpu":
        return Config(model=ModelConfig(channels=(8, 16, 32, 64, 128)), data=DataConfig(steps_per_epoch=20),
                      train=TrainConfig(num_steps=80 * 20, batch_size=16, lr=1e-3, log_every=20, ckpt_every=100))
    if preset == "improved":
        cpu = get_config("cpu")
        mask = dataclasses.replace(cpu.data.mask, mu_start=30.0, mu_step=30.0, every_epochs=2, eval_matched=True)
        return Config(model=dataclasses.replace(cpu.model, residual=True, paste_known=True, fill="hermite"),
                      data=dataclasses.replace(cpu.data, mask=mask), loss=LossConfig(gap_weight=4.0),
                      train=dataclasses.replace(cpu.train, lr_schedule="cosine", lr_final=0.05, warmup_steps=20,
                                                split="fit", keep_checkpoints=0))
    if preset == "tiny":
        return Config(model=ModelConfig(channels=(4, 4, 8, 8, 8), holden_hidden=16, holden_width=5),
                      data=DataConfig(clip_length=64, max_motions=2, steps_per_epoch=2),
                      train=TrainConfig(num_steps=4 * 2, batch_size=4, lr=1e-3, log_every=2, ckpt_every=4))
    raise ValueError(f"unknown CAE preset {preset!r}; choose {', '.join(PRESETS)}")
