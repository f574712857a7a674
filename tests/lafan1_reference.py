"""An independent, deliberately plain NumPy re-derivation of the official LaFAN1 benchmark pipeline.

It shares no code with ``inbetween_jax``: its own BVH number parsing, Euler conversion through
rotation matrices, per-joint FK loops, and the benchmark's centring / facing / metric formulas as
described in the LaFAN1 paper's evaluation code. Tests compare the library against it.
"""
import numpy as np


def _rot(axis, deg):
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    if axis == "X":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "Y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _mat_to_quat(m):
    """Shepperd's method, one matrix at a time (w >= 0)."""
    t = np.trace(m)
    if t > 0:
        s = np.sqrt(t + 1.0) * 2
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    return q if q[0] >= 0 else -q


def _qmul(a, b):
    w1, x1, y1, z1 = np.moveaxis(a, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(b, -1, 0)
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], -1)


def _qconj(q):
    return q * np.array([1, -1, -1, -1])


def _qrot(q, v):
    vq = np.concatenate([np.zeros(v.shape[:-1] + (1,)), v], -1)
    return _qmul(_qmul(q, vq), _qconj(q))[..., 1:]


def read_lafan1_bvh(path):
    """LaFAN1 files: root 6 channels, every joint 'Zrotation Yrotation Xrotation'. Returns
    (quats (T, J, 4), positions (T, J, 3), parents)."""
    lines = open(path).read().splitlines()
    parents, offsets, stack = [], [], []
    in_end = False
    for ln in lines:
        w = ln.split()
        if not w:
            continue
        if w[0] in ("ROOT", "JOINT"):
            parents.append(stack[-1] if stack else -1)
            offsets.append(None)
            stack.append(len(parents) - 1)
            in_end = False
        elif w[0] == "End":
            in_end = True
        elif w[0] == "OFFSET" and not in_end:
            offsets[stack[-1]] = [float(x) for x in w[1:4]]
        elif w[0] == "}":
            if in_end:
                in_end = False
            else:
                stack.pop()
        elif w[0] == "MOTION":
            break
    start = lines.index("MOTION") + 3
    data = np.array([ln.split() for ln in lines[start:] if ln.strip()], dtype=np.float64)
    t, j = data.shape[0], len(parents)
    pos = np.tile(np.array(offsets, np.float64), (t, 1, 1))
    pos[:, 0] = data[:, :3]
    eul = data[:, 3:].reshape(t, j, 3)  # degrees, Z Y X
    quats = np.zeros((t, j, 4))
    for f in range(t):
        for k in range(j):
            m = _rot("Z", eul[f, k, 0]) @ _rot("Y", eul[f, k, 1]) @ _rot("X", eul[f, k, 2])
            quats[f, k] = _mat_to_quat(m)
    for f in range(1, t):  # hemisphere continuity over time
        flip = np.sum(quats[f] * quats[f - 1], -1) < 0
        quats[f, flip] *= -1
    return quats, pos, parents


def fk(q, p, parents):
    gq, gp = np.zeros_like(q), np.zeros_like(p)
    for k, par in enumerate(parents):
        if par < 0:
            gq[..., k, :], gp[..., k, :] = q[..., k, :], p[..., k, :]
        else:
            gq[..., k, :] = _qmul(gq[..., par, :], q[..., k, :])
            gp[..., k, :] = _qrot(gq[..., par, :], p[..., k, :]) + gp[..., par, :]
    return gq, gp


def windows(paths, window, offset, n_past=10):
    """Official sliding windows, XZ centring on the mean root and facing +X at frame n_past-1."""
    X, Q, parents = [], [], None
    for path in paths:
        q, p, parents = read_lafan1_bvh(path)
        i = 0
        while i + window < q.shape[0]:
            X.append(p[i:i + window])
            Q.append(q[i:i + window])
            i += offset
    X, Q = np.array(X), np.array(Q)
    X[:, :, 0, [0, 2]] -= X[:, :, 0, [0, 2]].mean(axis=1, keepdims=True)
    gq, gp = fk(Q, X, parents)
    out_q, out_x = np.zeros_like(Q), np.zeros_like(X)
    for n in range(X.shape[0]):
        fwd = _qrot(gq[n, n_past - 1, 0], np.array([0.0, 1.0, 0.0])) * np.array([1, 0, 1])
        fwd /= np.linalg.norm(fwd)
        ang = np.arctan2(-fwd[2], fwd[0])  # heading of fwd about +Y, measured from +X
        yq = np.array([np.cos(ang / 2), 0, np.sin(ang / 2), 0])
        inv = _qconj(yq)
        ngq = _qmul(np.broadcast_to(inv, gq[n].shape), gq[n])
        ngp = _qrot(np.broadcast_to(inv, gq[n].shape), gp[n])
        for k, par in enumerate(parents):  # inverse kinematics
            if par < 0:
                out_q[n, :, k], out_x[n, :, k] = ngq[:, k], ngp[:, k]
            else:
                pinv = _qconj(ngq[:, par])
                out_q[n, :, k] = _qmul(pinv, ngq[:, k])
                out_x[n, :, k] = _qrot(pinv, ngp[:, k] - ngp[:, par])
    return out_x, out_q, parents


def slerp(a, b, t):
    d = np.sum(a * b, -1, keepdims=True)
    b = np.where(d < 0, -b, b)
    d = np.abs(d)
    om = np.arccos(np.clip(d, -1, 1))
    lin = (1 - d) < 0.01
    w0 = np.where(lin, 1 - t, np.sin((1 - t) * om) / np.where(lin, 1, np.sin(om)))
    w1 = np.where(lin, t, np.sin(t * om) / np.where(lin, 1, np.sin(om)))
    r = w0 * a + w1 * b
    return r / np.linalg.norm(r, axis=-1, keepdims=True)


def npss(gt, pred):
    """gt, pred (B, T, D)."""
    gp = np.real(np.fft.fft(gt, axis=1)) ** 2
    pp = np.real(np.fft.fft(pred, axis=1)) ** 2
    gtot, ptot = gp.sum(1), pp.sum(1)
    emd = np.abs(np.cumsum(pp / ptot[:, None], 1) - np.cumsum(gp / gtot[:, None], 1)).sum(1)
    return float(np.sum(emd * gtot) / np.sum(gtot))


def benchmark(X, Q, parents, x_mean, x_std, n_trans, n_past=10):
    """Zero-velocity and interpolation L2Q / L2P / NPSS for one transition length."""
    b, lo, hi = X.shape[0], n_past, n_past + n_trans
    gq, gp = fk(Q[:, lo:hi], X[:, lo:hi], parents)
    zq = np.repeat(Q[:, n_past - 1:n_past], n_trans, 1)
    zx = X[:, lo:hi].copy()
    zx[:, :, 0] = X[:, n_past - 1:n_past, 0]
    w = np.linspace(0, 1, n_trans + 2)[1:-1][None, :, None, None]
    iq = slerp(Q[:, n_past - 1:n_past], Q[:, hi:hi + 1], w)
    ix = X[:, lo:hi].copy()
    ix[:, :, 0] = X[:, n_past - 1:n_past, 0] + w[..., 0, :] * (X[:, hi:hi + 1, 0] - X[:, n_past - 1:n_past, 0])
    norm = lambda p: (p.reshape(b, n_trans, -1).transpose(0, 2, 1) - x_mean) / x_std
    res = {}
    for name, (q, x) in {"zerov": (zq, zx), "interp": (iq, ix)}.items():
        pq, pp = fk(q, x, parents)
        res[name] = dict(
            L2Q=float(np.mean(np.sqrt(np.sum((pq - gq) ** 2, axis=(2, 3))))),
            L2P=float(np.mean(np.sqrt(np.sum((norm(pp) - norm(gp)) ** 2, axis=1)))),
            NPSS=npss(gq.reshape(b, n_trans, -1), pq.reshape(b, n_trans, -1)))
    return res
