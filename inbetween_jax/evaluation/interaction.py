"""The two-character in-betweening protocol (the interaction paper's Table 1 layout).

A method maps test windows to predicted frames (``method(windows, steps, samples, key) -> (S, B, 2, >= L,
J, 9)`` in each character's keyframe space).  Test windows (:func:`table1_windows`) hold ``N_INPUT`` = 20
context frames, L transition frames and the keyframe.  Columns (:data:`COLUMNS`): L2P / L2Q at 30 and 50
frames, foot skating (first 50 frames, clamp(2 - 2^(h/H)), H = 2.5 cm, cm/frame), interaction score at
40 / 60 / 80 frames, diversity (APD over 10 samples, metres) at 30 / 50, Frechet distance of classifier
features and 100 x NPSS at 100 / 150 / 200 frames (:data:`NPSS_NOTE`).

The interaction score and Frechet features come from an independently trained interaction classifier
(periodic autoencoder on PJD dynamics + MLP with per-character pose statistics), trained on real pairs
against "fakes" produced without the model under test (time-desynchronised partners, interpolation
in-betweens, jittered poses): :func:`train_classifier`, :func:`classify_windows`.
"""
from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import nnx

from inbetween_jax import metrics
from inbetween_jax.baselines.two_character import two_character_interpolation
from inbetween_jax.evaluation.tables import markdown_table
from inbetween_jax.geometry import quat_fix_sign, quat_from_forward_up
from inbetween_jax.models.interaction.batches import eval_windows, sample_batch
from inbetween_jax.models.interaction.features import to_common_space
from inbetween_jax.models.interaction.layers import Discriminator, PeriodicAE, pjd_dynamics

__all__ = ["CLS_N", "N_INPUT", "LENGTHS", "PAPER_BOXING", "COLUMNS", "HEADERS", "global_quats",
           "InteractionClassifier", "train_classifier", "classify_windows", "table1_windows", "l2p_stats",
           "interpolation_method", "ground_truth_method", "hold_method", "guess_gap_length",
           "guessed_interpolation_method", "independent_method", "keypose_distance_m", "arrival_stats", "pair_l2p",
           "evaluate", "wide_rows", "long_rows", "format_table"]

CLS_N = 30          # PJD frames per classifier window (paper: N = 30)
N_INPUT = 20        # context frames of every test window (paper: T = 20)
LENGTHS = (30, 40, 50, 60, 80, 100, 150, 200)
PAPER_BOXING = dict(l2p_30=0.192, l2p_50=0.208, l2q_30=0.254, l2q_50=0.279, foot_50=0.342, inter_40=0.914,
                    inter_60=0.911, inter_80=0.905, div_30=1.104, div_50=1.802, fid_100=0.282, fid_150=0.287,
                    fid_200=0.289, npss_100=1.398, npss_150=1.430, npss_200=1.531)
COLUMNS = tuple(PAPER_BOXING)
GUESS_NOTE = ("Interpolation (guessed gap length) does not know the gap: per character it divides the mean joint "
              "distance from the last context frame to the keypose by the mean joint speed over the last 10 "
              "context frames, takes the larger of the two characters, rounds and clips to 5-200 frames, "
              "interpolates over that many frames and then holds the keypose (its stop rule).")
NPSS_NOTE = ("NPSS: per window and quaternion channel (both characters' global quaternions), the earth mover's "
             "distance between the normalised cumulative power spectra (real part of the FFT over the frames) is "
             "summed over all frequency bins; channels are then averaged weighted by their ground-truth total "
             "power, pooled over windows (the LaFAN1 benchmark formula), x 100.")
HEADERS = {"l2p": "L2P", "l2q": "L2Q", "foot": "Foot", "inter": "Inter", "div": "Div", "fid": "FD",
           "npss": "100xNPSS"}


def global_quats(feats, prev):
    """Sign-continuous global quaternions of (..., T, J, 9) features, continuing from ``prev`` (..., J, 9)."""
    q = quat_from_forward_up(jnp.concatenate([prev[..., None, :, :], feats], -3)[..., 3:])
    return quat_fix_sign(q, axis=-3)[..., 1:, :, :]


# ----------------------------------------------------------------------------- interaction classifier
class InteractionClassifier(nnx.Module):
    """Clip (B, 2, N + 1, J, 9) in one space -> (logit (B,), features (B, H))."""

    def __init__(self, num_joints: int, joints, H: int = 64, Cp: int = 8, *, rngs: nnx.Rngs):
        self.joints = tuple(joints) if joints else tuple(range(num_joints))
        c = len(self.joints) ** 2
        self.pae = PeriodicAE(c, CLS_N, Cp, 32, rngs=rngs)
        self.head = Discriminator(CLS_N, Cp, H, extra=2 * num_joints * 4, rngs=rngs)

    def __call__(self, clip):
        pos = clip[..., :3]
        pjd = pjd_dynamics(pos[:, 0], pos[:, 1], self.joints, 1.0)
        recon, h, prm = self.pae(pjd)
        rel = pos - pos[:, :, :, :1] * jnp.asarray([1.0, 0.0, 1.0])                   # root-relative (floor)
        speed = jnp.linalg.norm(pos[:, :, 1:] - pos[:, :, :-1], axis=-1)              # (B, 2, N, J)
        extra = jnp.concatenate([jnp.linalg.norm(rel, axis=-1).mean(2), rel[..., 1].mean(2),
                                 speed.mean(2) * 10, speed.std(2) * 10], -1).reshape(clip.shape[0], -1)
        logit, feat = self.head(h, prm, extra)
        return logit, feat, jnp.mean((recon - pjd) ** 2)


def _real_clips(pairs, rng, n, pos_scale):
    """n random real (2, N + 1, J, 9) clips in world space (positions scaled)."""
    out = []
    lens = np.array([p.num_frames - CLS_N - 1 for p in pairs], np.float64).clip(0)
    for i in rng.choice(len(pairs), n, p=lens / lens.sum()):
        s = rng.integers(0, int(lens[i]))
        out.append(pairs[i].feats[:, s:s + CLS_N + 1])
    c = np.stack(out).astype(np.float32)
    c[..., :3] *= pos_scale
    return c


def _fake_clips(pairs, rng, n, pos_scale):
    """Fakes made without the model under test: desynchronised partner / interpolation / jitter."""
    real = _real_clips(pairs, rng, n, pos_scale)
    fake = real.copy()
    kind = rng.integers(0, 3, n)
    for b in range(n):
        if kind[b] == 0:                                              # partner from another time
            other = _real_clips(pairs, rng, 1, pos_scale)[0]
            fake[b, 1] = other[1] - other[1, :1, :1] * np.array([1, 0, 1] + [0] * 6) \
                + real[b, 1, :1, :1] * np.array([1, 0, 1] + [0] * 6)
        elif kind[b] == 1:                                            # interpolation in-between
            fake[b] = np.asarray(two_character_interpolation(jnp.asarray(real[b:b + 1, :, 0]),
                                                             jnp.asarray(real[b:b + 1, :, -1]), CLS_N + 1))[0]
        else:                                                         # jittered poses
            fake[b, ..., :3] += rng.normal(0, 0.03, fake[b, ..., :3].shape)
    return fake


def train_classifier(pairs, num_joints: int, joints=(), steps: int = 300, batch: int = 64, seed: int = 0,
                     pos_scale: float = 0.01):
    """Train the evaluation classifier on ``pairs`` (world space); -> (graphdef, params, final accuracy)."""
    rng = np.random.default_rng(seed)
    model = InteractionClassifier(num_joints, joints, rngs=nnx.Rngs(seed))
    gdef, params = nnx.split(model)
    tx = optax.adam(1e-3)
    opt = tx.init(params)

    def loss_fn(p, clips, labels):
        logit, _, rec = nnx.merge(gdef, p)(clips)
        bce = jnp.mean(optax.sigmoid_binary_cross_entropy(logit, labels))
        return bce + rec, jnp.mean((logit > 0) == (labels > 0.5))

    @jax.jit
    def step(p, o, clips, labels):
        (_, acc), g = jax.value_and_grad(loss_fn, has_aux=True)(p, clips, labels)
        u, o = tx.update(g, o, p)
        return optax.apply_updates(p, u), o, acc

    acc = 0.0
    for _ in range(steps):
        clips = np.concatenate([_real_clips(pairs, rng, batch // 2, pos_scale),
                                _fake_clips(pairs, rng, batch // 2, pos_scale)])
        labels = np.concatenate([np.ones(batch // 2), np.zeros(batch // 2)]).astype(np.float32)
        params, opt, acc = step(params, opt, clips, labels)
    return gdef, params, float(acc)


@functools.lru_cache(maxsize=8)
def _classifier_apply(gdef):
    """One jitted apply per classifier graph (every method and length of a table reuses it)."""
    return jax.jit(lambda p, x: nnx.merge(gdef, p)(x))


def classify_windows(gdef, params, clip, stride: int = 10):
    """Score a long clip (B, 2, T, J, 9) (common space, T >= N + 1) on all (N + 1)-frame windows with
    ``stride``: -> (probabilities (B, W), features (B, W, H))."""
    T = clip.shape[2]
    starts = list(range(0, T - CLS_N, stride)) or [0]
    wins = jnp.stack([clip[:, :, s:s + CLS_N + 1] for s in starts], 1)             # (B, W, 2, N+1, J, 9)
    B, W = wins.shape[:2]
    logit, feat, _ = _classifier_apply(gdef)(params, wins.reshape((B * W,) + wins.shape[2:]))
    return jax.nn.sigmoid(logit).reshape(B, W), feat.reshape(B, W, -1)


# ----------------------------------------------------------------------------- protocol
def table1_windows(test_pairs, pos_scale: float, max_windows: int, lengths=LENGTHS) -> dict:
    """``{L: eval_windows}`` of the test pairs: N_INPUT context frames, L transition frames and the keyframe,
    stride 10 up to 80 frames and 30 beyond, at most ``max_windows`` per length (evenly subsampled)."""
    return {L: eval_windows(test_pairs, N_INPUT, L, 10 if L <= 80 else 30, pos_scale, max_windows) for L in lengths}


def l2p_stats(train_pairs, pos_scale: float, key_range=(50, 70), num: int = 256, seed: int = 0) -> tuple:
    """L2P normalisation ``(mean, std)`` (J*3,) of positions in the common (character A key) space, from
    ``num`` unmirrored 50-frame training samples with keyframes ``key_range`` frames after the window start.
    The bench keeps the default range for every run, so runs trained with other key ranges share one scale."""
    sb = sample_batch(train_pairs, np.random.default_rng(seed), num, 50, key_range, False, pos_scale)
    common = np.asarray(to_common_space(sb["x"], sb["rel_R"], sb["rel_t"]))[..., :3]   # (N, 2, T, J, 3)
    flat = common.reshape(-1, common.shape[-2] * 3)
    return flat.mean(0), flat.std(0) + 1e-6


def _pad_to(out, frames: int, samples: int):
    """(B, 2, L, J, 9) -> (samples, B, 2, max(L, frames), J, 9), holding the last frame."""
    L = out.shape[2]
    pad = np.repeat(out[:, :, -1:], frames - L, axis=2) if frames > L else out[:, :, :0]
    return np.repeat(np.concatenate([out, pad], 2)[None], samples, 0)


def interpolation_method(b, steps, samples, key, n_pred: int = 10):
    """The independent-characters interpolation baseline as a method (deterministic: samples are copies)."""
    L = b["x"].shape[2] - N_INPUT - 1
    out = np.asarray(two_character_interpolation(b["x"][:, :, N_INPUT - 1], b["keypose"], L))
    return _pad_to(out, steps * n_pred, samples)


def ground_truth_method(b, steps, samples, key, n_pred: int = 10):
    """The test windows' own transition frames as a method (the reference row)."""
    L = b["x"].shape[2] - N_INPUT - 1
    return _pad_to(b["x"][:, :, N_INPUT:N_INPUT + L], steps * n_pred, samples)


def hold_method(b, steps, samples, key, n_pred: int = 10):
    """Hold-last-frame baseline: both characters freeze at their last context frame (no stop rule)."""
    last = np.asarray(b["x"][:, :, N_INPUT - 1:N_INPUT])
    return np.repeat(np.repeat(last, steps * n_pred, 2)[None], samples, 0)


def guess_gap_length(b, lo: int = 5, hi: int = 200, n_input: int = N_INPUT) -> np.ndarray:
    """Gap length guessed without the true one: per character, the mean joint distance from the last context
    frame to the keypose divided by the mean joint speed over the last 10 context frames (metres and metres per
    frame, both in the keyframe space); the larger of the two characters, rounded, clipped to [lo, hi].
    ``b["x"]`` (B, 2, F, J, >=3) holds ``n_input`` context frames first.  -> (B,) int."""
    x = np.asarray(b["x"], np.float64)[..., :3]
    dist = np.linalg.norm(np.asarray(b["keypose"], np.float64)[..., :3] - x[:, :, n_input - 1], axis=-1).mean(-1)
    speed = np.linalg.norm(np.diff(x[:, :, n_input - 11:n_input], axis=2), axis=-1).mean((2, 3))
    return np.clip(np.round((dist / np.maximum(speed, 1e-4)).max(1)), lo, hi).astype(int)


def _interp_then_hold(b, gaps, frames: int) -> np.ndarray:
    """Per window: interpolation over ``gaps[i]`` frames, then the keypose held; -> (B, 2, frames, J, 9)."""
    x, kp = np.asarray(b["x"]), np.asarray(b["keypose"])
    out = np.repeat(kp[:, :, None], frames, 2).astype(np.float32)
    for g in np.unique(gaps):
        sel = np.flatnonzero(gaps == g)
        n = min(int(g), frames)
        out[sel, :, :n] = np.asarray(two_character_interpolation(x[sel, :, N_INPUT - 1], kp[sel], int(g)))[:, :, :n]
    return out


def guessed_interpolation_method(b, steps, samples, key, n_pred: int = 10):
    """Interpolation over the guessed gap length (:func:`guess_gap_length`), then the keypose held (its stop
    rule: it stops at the guessed length)."""
    out = _interp_then_hold(b, guess_gap_length(b), steps * n_pred)
    return np.repeat(out[None], samples, 0)


def independent_method(sample):
    """The model run on each character independently: ``sample`` (a method, ``(windows, steps, samples, key) ->
    (S, B, 2, F, J, 9)``) sees, for character c, a pair whose both slots hold c itself (same context, same
    keypose, identity relative space), so nothing of the real partner reaches it; slot 0 of each run is kept."""
    def method(b, steps, samples, key):
        outs = []
        for c in (0, 1):
            bc = {k: b[k] for k in ("x", "keypose")}
            bc = {k: np.repeat(np.asarray(v)[:, c:c + 1], 2, 1) for k, v in bc.items()}
            B = bc["x"].shape[0]
            bc["rel_R"] = np.broadcast_to(np.eye(3, dtype=np.float32), (B, 2, 3, 3)).copy()
            bc["rel_t"] = np.zeros((B, 2, 3), np.float32)
            outs.append(np.asarray(sample(bc, steps, samples, jax.random.fold_in(key, c)))[:, :, 0])
        return np.stack(outs, 2)
    return method


def keypose_distance_m(frames, keypose, pos_scale: float = 0.01) -> np.ndarray:
    """Mean joint distance (metres) of frames (..., 2, F, J, 9) to keypose (..., 2, J, 9), the larger of the two
    characters: -> (..., F)."""
    d = np.linalg.norm(np.asarray(frames)[..., :3] - np.asarray(keypose)[..., None, :, :3], axis=-1).mean(-1)
    return d.max(-2) * (0.01 / pos_scale)


def arrival_stats(method, b, threshold_m: float = 0.15, key=None, pos_scale: float = 0.01) -> dict:
    """Stop-rule statistics on windows ``b``: roll ``method`` out for 2 x the true gap L and find the first frame
    where both characters are within ``threshold_m`` (mean joint distance, metres) of their keyposes.
    -> {reached: share of windows arriving within 2 L, median_frames: median arrival frame of those (1-based),
    true_gap: L, threshold_m}."""
    L = b["x"].shape[2] - N_INPUT - 1
    key = jax.random.key(0) if key is None else key
    frames = np.asarray(method(b, math.ceil(2 * L / 10), 1, key))[0, :, :, :2 * L]
    ok = keypose_distance_m(frames, b["keypose"], pos_scale) < threshold_m
    hit = ok.any(-1)
    first = ok.argmax(-1) + 1
    return dict(reached=float(hit.mean()), median_frames=float(np.median(first[hit])) if hit.any() else float("nan"),
                true_gap=int(L), threshold_m=float(threshold_m))


def pair_l2p(pred, b, stats) -> float:
    """L2P of both characters' frames ``pred`` (B, 2, L, J, 9) against the window's ground truth after its
    context, in the common (character A key) space, averaged over the two characters."""
    L = pred.shape[2]
    P = np.asarray(to_common_space(jnp.asarray(pred), b["rel_R"], b["rel_t"]))
    G = np.asarray(to_common_space(jnp.asarray(b["x"][:, :, N_INPUT:N_INPUT + L]), b["rel_R"], b["rel_t"]))
    return float(np.mean([metrics.l2p(P[:, c, ..., :3], G[:, c, ..., :3], *stats) for c in (0, 1)]))


def evaluate(method, windows, stats, cls, feet, pos_scale, key, num_div=10) -> dict:
    """Table-1 metrics of one method. windows: {length: eval_windows dict}; stats: :func:`l2p_stats`;
    cls: (graphdef, params) of :func:`train_classifier`; feet: foot joint indices.  Returns {column: value}."""
    res = {}
    for L, b in windows.items():
        if not b:
            continue
        steps = math.ceil(L / 10)
        want_div = L in (30, 50)
        pred = method(b, steps, num_div if want_div else 1, jax.random.fold_in(key, L))[:, :, :, :L]
        gt = b["x"][:, :, N_INPUT:N_INPUT + L]
        prev = b["x"][:, :, N_INPUT - 1]
        P = np.asarray(to_common_space(jnp.asarray(pred[0]), b["rel_R"], b["rel_t"]))     # (B, 2, L, J, 9)
        G = np.asarray(to_common_space(jnp.asarray(gt), b["rel_R"], b["rel_t"]))
        prevc = np.asarray(to_common_space(jnp.asarray(prev[:, :, None]), b["rel_R"], b["rel_t"]))[:, :, 0]
        if L in (30, 50):
            res[f"l2p_{L}"] = pair_l2p(pred[0], b, stats)
            qp, qg = global_quats(jnp.asarray(P), prevc), global_quats(jnp.asarray(G), prevc)
            res[f"l2q_{L}"] = float(np.mean([metrics.l2q(qp[:, c], qg[:, c]) for c in (0, 1)]))
            allc = np.stack([np.asarray(to_common_space(jnp.asarray(s), b["rel_R"], b["rel_t"])) for s in pred])
            res[f"div_{L}"] = float(metrics.apd(allc[..., :3].reshape(allc.shape[:2] + (-1,))))
        if L == 50:
            cm = P[..., :3] / pos_scale
            res["foot_50"] = float(np.mean([metrics.foot_skating(cm[:, c], feet) for c in (0, 1)]))
        if L in (40, 60, 80):
            clip = np.concatenate([prevc[:, :, None], P], 2)
            prob, _ = classify_windows(*cls, jnp.asarray(clip))
            res[f"inter_{L}"] = float(np.mean(prob))
        if L in (100, 150, 200):
            _, fp = classify_windows(*cls, jnp.asarray(np.concatenate([prevc[:, :, None], P], 2)), stride=30)
            _, fg = classify_windows(*cls, jnp.asarray(np.concatenate([prevc[:, :, None], G], 2)), stride=30)
            fp, fg = np.asarray(fp).reshape(-1, fp.shape[-1]), np.asarray(fg).reshape(-1, fg.shape[-1])
            res[f"fid_{L}"] = metrics.frechet_distance(fp, fg) if len(fp) > 2 else float("nan")
            qp, qg = global_quats(jnp.asarray(P), prevc), global_quats(jnp.asarray(G), prevc)
            B = qp.shape[0]
            res[f"npss_{L}"] = 100.0 * float(metrics.npss(jnp.moveaxis(qg, 1, 2).reshape(B, L, -1),
                                                          jnp.moveaxis(qp, 1, 2).reshape(B, L, -1)))
    return res


def _header(column: str) -> str:
    name, frames = column.rsplit("_", 1)
    return f"{HEADERS[name]} {frames}"


def wide_rows(results: dict) -> list:
    """``{method: {column: value}}`` -> one row per method with ``"L2P 30"``-style headers (for the table)."""
    return [{"method": name, **{_header(c): r.get(c) for c in COLUMNS}} for name, r in results.items()]


def long_rows(result: dict) -> list:
    """One method's ``{column: value}`` -> rows ``{frames, <metric header>: value}`` (for ``flat_rows``)."""
    rows: dict = {}
    for c, v in result.items():
        name, frames = c.rsplit("_", 1)
        rows.setdefault(int(frames), {"frames": int(frames)})[HEADERS[name]] = v
    return [rows[k] for k in sorted(rows)]


def format_table(results: dict, note: str) -> str:
    """The note, then the markdown table of ``{method: {column: value}}`` (3 decimals, ``-`` for missing)."""
    cols = [_header(c) for c in COLUMNS]
    return note + "\n\n" + markdown_table(wide_rows(results), cols, keys=("method",), digits=3)
