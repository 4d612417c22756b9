"""Rigid SE(2) alignment of two horizontal point sets (Umeyama / Kabsch without scale).

A trajectory whose absolute position is GNSS-limited (decimetres) still focuses sharply: a rigid offset or
rotation of the whole track only moves the image. To measure what the navigation does to the *shape* of
the image, the estimated track is aligned to the truth with the rigid motion that fits best in the
least-squares sense, and positions are compared after it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Se2:
    """A rigid motion of the horizontal plane: ``p -> R(angle) p + translation`` (ENU metres, angle CCW, rad)."""

    angle_rad: float = 0.0
    translation: tuple[float, float] = (0.0, 0.0)

    @property
    def rotation(self) -> Array:
        """The 2 x 2 rotation matrix."""
        c, s = math.cos(self.angle_rad), math.sin(self.angle_rad)
        return np.array([[c, -s], [s, c]])

    def apply(self, points: ArrayLike) -> Array:
        """Transform points (..., 2) or (..., 3) (ENU m); a third (z) coordinate is passed through unchanged."""
        p = np.array(points, dtype=np.float64)
        p[..., :2] = p[..., :2] @ self.rotation.T + np.asarray(self.translation)
        return p

    def inverse(self) -> Se2:
        """The inverse motion: ``p -> R^T (p - translation)``."""
        t = -(self.rotation.T @ np.asarray(self.translation))
        return Se2(-self.angle_rad, (float(t[0]), float(t[1])))

    def to_dict(self) -> dict[str, float]:
        return {"angle_deg": math.degrees(self.angle_rad), "tx_m": self.translation[0], "ty_m": self.translation[1]}


def fit_se2(source: ArrayLike, target: ArrayLike, weights: ArrayLike | None = None) -> Se2:
    """The rigid motion T minimising ``sum w_i |T(source_i) - target_i|^2`` (closed form, no reflection, no scale).

    ``source`` and ``target``: (N, 2+) corresponding points (only x, y are used), N >= 2 for a defined angle
    (with one point, or all points coincident, the angle is 0 and T is the translation of the centroids).
    """
    src = np.asarray(source, dtype=np.float64)[:, :2]
    dst = np.asarray(target, dtype=np.float64)[:, :2]
    if src.shape != dst.shape or len(src) == 0:
        raise ValueError(f"fit_se2: need matching non-empty point sets, got {src.shape} and {dst.shape}")
    w = np.ones(len(src)) if weights is None else np.asarray(weights, dtype=np.float64)
    w = w / w.sum()
    cs, cd = w @ src, w @ dst
    a, b = src - cs, dst - cd
    # maximise sum w (b . R a) = cos(th) sum w (a.b) + sin(th) sum w (a x b)
    dot = float(np.sum(w * (a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1])))
    cross = float(np.sum(w * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])))
    angle = math.atan2(cross, dot) if (dot != 0.0 or cross != 0.0) else 0.0
    c, s = math.cos(angle), math.sin(angle)
    t = cd - np.array([c * cs[0] - s * cs[1], s * cs[0] + c * cs[1]])
    return Se2(angle, (float(t[0]), float(t[1])))


def fit_similarity_scale(source: ArrayLike, target: ArrayLike) -> float:
    """The scale s of the similarity ``p -> s R p + t`` that fits ``source`` to ``target`` best in least squares
    (Umeyama; the rotation is :func:`fit_se2`'s). ``s - 1`` is how much longer (> 0) the target's distances are
    than the source's: for an estimated track against the truth at the same instants, the scale error of its
    odometry, free of what its path length alone would add (lateral jitter lengthens a path without scaling it).
    """
    src = np.asarray(source, dtype=np.float64)[:, :2]
    dst = np.asarray(target, dtype=np.float64)[:, :2]
    if src.shape != dst.shape or len(src) < 2:
        raise ValueError(f"fit_similarity_scale: need matching point sets of >= 2, got {src.shape} and {dst.shape}")
    a, b = src - src.mean(axis=0), dst - dst.mean(axis=0)
    spread = float(np.sum(a * a))
    if spread == 0.0:
        raise ValueError("fit_similarity_scale: the source points coincide")
    dot = float(np.sum(a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]))
    cross = float(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]))
    return math.hypot(dot, cross) / spread
