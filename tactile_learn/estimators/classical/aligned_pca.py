"""A data-driven baseline: onset-aligned curves -> standardise -> PCA -> linear discriminant.

What a user can train on a handful of labelled touches without any physics (issue 11's baseline
was scaler + PCA + SVM): each touch's curves from ``PRE_S`` before its onset to ``d`` seconds after
it, every channel minus its value at the onset (the absolute temperature is not the material),
standardised per sample, projected on the leading principal components of the training curves, and
classified by a linear discriminant with a shared, shrunk covariance (an SVM needs more than nine
examples to place its margin; with so few, a shrunk LDA is the stable linear rule). One model per
contact duration, trained on that duration's curves. numpy only.
"""

from __future__ import annotations

import numpy as np

from tactile_learn.estimators.classical.curve_match import softmax

__all__ = ["PRE_S", "AlignedPca", "aligned_curves"]

#: seconds of each curve before the onset
PRE_S = 0.25


def aligned_curves(records: list[np.ndarray], onset_s: np.ndarray, fs: float, duration_s: float) -> np.ndarray:
    """Features (N, S * L): each of the S channel records (N, R) from ``PRE_S`` before the onset to
    ``duration_s`` after it (linear interpolation, the record's ends repeated), minus the value at
    the onset."""
    n_pts = round((PRE_S + duration_s) * fs) + 1
    t = np.asarray(onset_s, dtype=np.float64)[:, None] - PRE_S + np.arange(n_pts)[None, :] / fs
    feats = []
    for rec in records:
        rec = np.asarray(rec, dtype=np.float64)
        pos = np.clip(t * fs, 0, rec.shape[1] - 1)
        lo = np.floor(pos).astype(np.int64)
        hi = np.minimum(lo + 1, rec.shape[1] - 1)
        frac = pos - lo
        rows = np.arange(len(rec))[:, None]
        values = rec[rows, lo] * (1 - frac) + rec[rows, hi] * frac
        at = np.clip(np.asarray(onset_s) * fs, 0, rec.shape[1] - 1)
        a_lo = np.floor(at).astype(np.int64)
        a_hi = np.minimum(a_lo + 1, rec.shape[1] - 1)
        base = rec[np.arange(len(rec)), a_lo] * (1 - (at - a_lo)) + rec[np.arange(len(rec)), a_hi] * (at - a_lo)
        feats.append(values - base[:, None])
    return np.concatenate(feats, axis=1)


class AlignedPca:
    """Standardise -> PCA (``components``) -> shrunk linear discriminant; ``fit`` then ``predict_proba``."""

    def __init__(self, components: int = 4, shrinkage: float = 0.2) -> None:
        self.components = components
        self.shrinkage = shrinkage

    def fit(self, x: np.ndarray, y: np.ndarray, n_classes: int) -> AlignedPca:
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.int64)
        self.mean_ = x.mean(axis=0)
        self.scale_ = np.maximum(x.std(axis=0), 1e-6)  # flat samples (the onset itself): no division by 0
        z = (x - self.mean_) / self.scale_
        _, _, vt = np.linalg.svd(z, full_matrices=False)
        self.axes_ = vt[: min(self.components, len(vt))]
        p = z @ self.axes_.T
        self.n_classes_ = n_classes
        self.centres_ = np.zeros((n_classes, p.shape[1]))
        self.prior_ = np.full(n_classes, 1e-9)
        for k in range(n_classes):
            if (y == k).any():
                self.centres_[k] = p[y == k].mean(axis=0)
                self.prior_[k] = (y == k).mean()
        resid = p - self.centres_[y]
        cov = resid.T @ resid / max(len(p) - n_classes, 1)
        target = np.trace(cov) / len(cov) * np.eye(len(cov))
        self.precision_ = np.linalg.inv((1 - self.shrinkage) * cov + self.shrinkage * target + 1e-9 * np.eye(len(cov)))
        return self

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        p = ((np.asarray(x, dtype=np.float64) - self.mean_) / self.scale_) @ self.axes_.T
        d = p[:, None, :] - self.centres_[None, :, :]
        score = -0.5 * np.einsum("nki,ij,nkj->nk", d, self.precision_, d) + np.log(self.prior_)[None, :]
        return softmax(score)
