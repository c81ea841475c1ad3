"""Rotations as unit quaternions (w, x, y, z), matrices and random draws.

Conversions go through `scipy.spatial.transform.Rotation` (whose quaternions are x, y, z, w:
converted here). Quaternions returned here have w >= 0 (q and -q are the same rotation).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .errors import InputError


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices from quaternions.

    Args:
        q: (N, 4) quaternions (w, x, y, z); normalised here, must be non-zero.

    Returns:
        (N, 3, 3) float64 rotation matrices R with R @ v rotating column vectors v.
    """
    q = np.asarray(q, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 4:
        raise InputError(f"quaternions must have shape (N, 4), got {q.shape}")
    norm = np.linalg.norm(q, axis=1)
    if np.any(~np.isfinite(norm)) or np.any(norm == 0):
        raise InputError("quaternions must be finite and non-zero")
    if len(q) == 0:
        return np.zeros((0, 3, 3))
    return Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix()


def matrix_to_quat(r: np.ndarray) -> np.ndarray:
    """Quaternions from rotation matrices.

    Args:
        r: (N, 3, 3) rotation matrices.

    Returns:
        (N, 4) unit quaternions (w, x, y, z) with w >= 0.
    """
    m = np.asarray(r, dtype=np.float64)
    if m.ndim != 3 or m.shape[1:] != (3, 3):
        raise InputError(f"rotation matrices must have shape (N, 3, 3), got {m.shape}")
    if len(m) == 0:
        return np.zeros((0, 4))
    q = Rotation.from_matrix(m).as_quat()[:, [3, 0, 1, 2]]
    return canonical(q)


def canonical(q: np.ndarray) -> np.ndarray:
    """(N, 4) quaternions (w, x, y, z) with the sign that makes w >= 0 (in place)."""
    q[q[:, 0] < 0] *= -1.0
    return q


def random_quaternions(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n,4) uniformly distributed unit quaternions w,x,y,z (Shoemake), w >= 0.

    Drawn by hand rather than with `Rotation.random`, whose draw differs: the packings of a
    seed depend on this stream.
    """
    u1, u2, u3 = rng.random((3, n))
    a = np.sqrt(1 - u1)
    b = np.sqrt(u1)
    q = np.stack([a * np.sin(2 * np.pi * u2), a * np.cos(2 * np.pi * u2),
                  b * np.sin(2 * np.pi * u3), b * np.cos(2 * np.pi * u3)], axis=1)
    return canonical(q)


def placement_matrices(
    rotations: np.ndarray, translations: np.ndarray, scales: np.ndarray
) -> np.ndarray:
    """Placement matrices [R(q) * s | t] taking object local frame to container frame.

    Args:
        rotations: (N, 4) quaternions (w, x, y, z).
        translations: (N, 3) container frame, container units.
        scales: (N,) uniform scales.

    Returns:
        (N, 4, 4) float64 homogeneous matrices.
    """
    q = np.asarray(rotations, dtype=np.float64).reshape(-1, 4)
    t = np.asarray(translations, dtype=np.float64).reshape(-1, 3)
    s = np.asarray(scales, dtype=np.float64).reshape(-1)
    if not q.shape[0] == t.shape[0] == s.shape[0]:
        raise InputError(
            f"rotations, translations and scales disagree on the number of objects: "
            f"{q.shape[0]}, {t.shape[0]}, {s.shape[0]}"
        )
    out = np.zeros((q.shape[0], 4, 4))
    out[:, :3, :3] = quat_to_matrix(q) * s[:, None, None]
    out[:, :3, 3] = t
    out[:, 3, 3] = 1.0
    return out
