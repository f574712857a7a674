"""Position metrics: L2P (LaFAN1 benchmark), ADE / FDE / SLDE (S-CVAE), MPJPE mean and std (CAE).

All functions are pure ``jax.numpy``, ``jit``-able and take global joint positions of shape
``(..., T, J, 3)`` (any number of leading batch dims; the LaFAN1 benchmark uses ``(B, T, J, 3)``).
Pass the *transition* (generated) frames only unless a function says otherwise.
Units: positions are in the data's units (LaFAN1 and CMU: centimetres). ``scale`` multiplies the
result, e.g. ``scale=0.01`` reports centimetre data in metres (the S-CVAE paper reports metres).
"""
from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

__all__ = ["joint_distances", "l2p", "ade", "fde", "slde", "mpjpe"]


@jax.jit
def joint_distances(pred_pos, gt_pos):
    """Per-joint Euclidean error ``d[..., t, j] = ||pred[..., t, j, :] - gt[..., t, j, :]||_2``.

    pred_pos, gt_pos: (..., T, J, 3). Returns (..., T, J) in the input units.
    """
    pred_pos = jnp.asarray(pred_pos)
    gt_pos = jnp.asarray(gt_pos)
    return jnp.sqrt(jnp.sum((pred_pos - gt_pos) ** 2, axis=-1))


def _flat_stats(stat, num_features: int):
    """(1, J*3, 1), (J*3,) or scalar statistics -> broadcastable (J*3,) / scalar."""
    stat = jnp.asarray(stat)
    if stat.ndim == 0:
        return stat
    if stat.size != num_features:
        raise ValueError(f"normalisation stats have {stat.size} entries, expected J*3={num_features}")
    return stat.reshape(num_features)


@jax.jit
def l2p(pred_pos, gt_pos, x_mean, x_std):
    """L2P: the LaFAN1 benchmark's normalised global-position error.

    Exactly ``lafan1/benchmarks.py``: each frame's global positions are flattened to a D = J*3
    vector (features ordered joint-major: j0x, j0y, j0z, j1x, ...), z-normalised feature-wise, and

        L2P = mean_{b,t} sqrt( sum_{d} ( (pred[b,t,d] - mu_d)/sigma_d - (gt[b,t,d] - mu_d)/sigma_d )^2 )

    (the official code transposes to (B, D, T) and sums over axis 1; identical result).

    pred_pos, gt_pos: (..., T, J, 3) global positions of the transition frames.
    x_mean, x_std: (1, J*3, 1) as in the official code, or (J*3,), or scalars.
    Returns a scalar, unitless (positions divided by the std).
    """
    pred_pos = jnp.asarray(pred_pos)
    gt_pos = jnp.asarray(gt_pos)
    num_features = pred_pos.shape[-2] * pred_pos.shape[-1]
    pred = pred_pos.reshape(pred_pos.shape[:-2] + (num_features,))
    gt = gt_pos.reshape(gt_pos.shape[:-2] + (num_features,))
    mean = _flat_stats(x_mean, num_features)
    std = _flat_stats(x_std, num_features)
    pred_n = (pred - mean) / std
    gt_n = (gt - mean) / std
    return jnp.mean(jnp.sqrt(jnp.sum((pred_n - gt_n) ** 2, axis=-1)))


@jax.jit
def ade(pred_pos, gt_pos, scale: float = 1.0):
    """ADE, average displacement error over the generated frames:

        ADE = scale * mean_{batch, t, j} ||pred[..., t, j] - gt[..., t, j]||_2

    pred_pos, gt_pos: (..., T, J, 3). Returns a scalar in input units times ``scale``
    (the benchmark passes ``scale=0.01`` to report LaFAN1 / CMU centimetres in metres).
    """
    return scale * jnp.mean(joint_distances(pred_pos, gt_pos))


@jax.jit
def fde(pred_pos, gt_pos, scale: float = 1.0):
    """FDE, final displacement error: the ADE distance at the last generated frame only,

        FDE = scale * mean_{batch, j} ||pred[..., T-1, j] - gt[..., T-1, j]||_2

    pred_pos, gt_pos: (..., T, J, 3). Returns a scalar in input units times ``scale``.
    In S-CVAE the generated sequence ends with the (re-generated) target keyframe, so this is the
    error at the target frame.
    """
    return scale * jnp.mean(joint_distances(pred_pos[..., -1, :, :], gt_pos[..., -1, :, :]))


@jax.jit
def slde(pred_pos, gt_pos, scale: float = 1.0):
    """SLDE, second-to-last displacement error: the ADE distance at generated frame T-2 only,

        SLDE = scale * mean_{batch, j} ||pred[..., T-2, j] - gt[..., T-2, j]||_2

    pred_pos, gt_pos: (..., T, J, 3) with T >= 2. Returns a scalar in input units times ``scale``.
    When the generated sequence ends with the target keyframe (S-CVAE), frame T-2 is the frame just
    before the target, where a discontinuous transition shows up.
    """
    if pred_pos.shape[-3] < 2:
        raise ValueError("SLDE needs at least 2 generated frames")
    return scale * jnp.mean(joint_distances(pred_pos[..., -2, :, :], gt_pos[..., -2, :, :]))


@functools.partial(jax.jit, static_argnames=('root_relative', 'root_index'))
def mpjpe(pred_pos, gt_pos, mask=None, root_relative: bool = True, root_index: int = 0,
          scale: float = 1.0):
    """Mean (and std) 3D joint error, CAE paper Table 1 style (centimetres for LaFAN1 / CMU data).

    With ``root_relative`` each frame is root-aligned first, ``p'[t, j] = p[t, j] - p[t, root]`` (for
    prediction and ground truth separately; the root joint then contributes a zero error and is
    still counted among the J joints). With e[..., t, j] = ||pred'[..., t, j] - gt'[..., t, j]||_2:

        mean = scale * sum_{b,t,j} w[b,t] e[b,t,j] / (J * sum_{b,t} w[b,t])
        std  = scale * sqrt( sum_{b,t,j} w[b,t] (e[b,t,j] - mean/scale)^2 / (J * sum_{b,t} w[b,t]) )

    i.e. the population (ddof=0) mean and std over every (frame, joint) error in the gap.

    pred_pos, gt_pos: (..., T, J, 3) global positions.
    mask: optional (..., T) weights (1 = frame in the gap); ``None`` = all T frames (pass the gap
        frames only). A mask with no selected frame gives 0, not NaN.
    Returns ``(mean, std)``, two scalars in input units times ``scale`` (cm for cm data).
    """
    pred_pos = jnp.asarray(pred_pos)
    gt_pos = jnp.asarray(gt_pos)
    if root_relative:
        pred_pos = pred_pos - pred_pos[..., root_index:root_index + 1, :]
        gt_pos = gt_pos - gt_pos[..., root_index:root_index + 1, :]
    err = joint_distances(pred_pos, gt_pos)  # (..., T, J)
    if mask is None:
        weights = jnp.ones(err.shape, err.dtype)
    else:
        weights = jnp.broadcast_to(jnp.asarray(mask, err.dtype)[..., None], err.shape)
    total = jnp.sum(weights)
    safe_total = jnp.where(total > 0, total, 1.0)
    mean = jnp.sum(weights * err) / safe_total
    var = jnp.sum(weights * (err - mean) ** 2) / safe_total
    return scale * mean, scale * jnp.sqrt(var)
