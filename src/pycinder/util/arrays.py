"""Small array helpers shared across layers."""

from __future__ import annotations

import numpy as np


def sum3(x: np.ndarray) -> np.ndarray:
    """``x.sum(axis=-1)`` of an axis of 3, as NumPy adds it (``(x0 + x1) + x2``): the same
    bits, without a reduction's cost per row (several times slower along so short an axis).

    Parameters
    ----------
    x : (..., 3) float

    Returns
    -------
    (...) float
    """
    out = x[..., 0] + x[..., 1]
    out += x[..., 2]
    return out


def det3(m: np.ndarray) -> np.ndarray:
    """Determinants of (N, 3, 3) matrices by cofactors along the first row (a few element-wise
    products of columns: many times faster than an LU per 3 x 3 matrix). A product that
    overflows gives inf or NaN, which the caller checks where it matters.

    Parameters
    ----------
    m : (N, 3, 3) float

    Returns
    -------
    (N,) float
    """
    a, b, c = m[:, 0, 0], m[:, 0, 1], m[:, 0, 2]
    d, e, f = m[:, 1, 0], m[:, 1, 1], m[:, 1, 2]
    g, h, i = m[:, 2, 0], m[:, 2, 1], m[:, 2, 2]
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


__all__ = ["det3", "sum3"]
