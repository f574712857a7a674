"""Frechet distance between Gaussians fitted to two feature sets (the FID of the interaction table, on the
evaluation classifier's features).  NumPy / SciPy, not jitted."""
from __future__ import annotations

import numpy as np

__all__ = ["frechet_distance"]


def frechet_distance(fa, fb) -> float:
    """``|m_a - m_b|^2 + tr(C_a + C_b - 2 (C_a C_b)^(1/2))`` of features fa (N, D) and fb (M, D): float."""
    import scipy.linalg
    fa, fb = np.asarray(fa, np.float64), np.asarray(fb, np.float64)
    ma, mb = fa.mean(0), fb.mean(0)
    ca, cb = np.cov(fa, rowvar=False), np.cov(fb, rowvar=False)
    covmean = scipy.linalg.sqrtm(ca @ cb)
    covmean = np.real(covmean)
    return float(np.sum((ma - mb) ** 2) + np.trace(ca + cb - 2.0 * covmean))
