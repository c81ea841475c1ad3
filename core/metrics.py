"""Packing quality metrics: density, type-share error (TVD) and clumping (3D Clark-Evans NNI).

The definitions are the ones in DESIGN.md ("Definitions"); tests and benchmarks report these.
All lengths are in container units (e.g. mm), volumes in container units^3, positions in the
container frame. Every function is pure and returns plain Python numbers, so results can be
written to JSON as they are.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from .errors import InputError

#: Mean nearest-neighbour distance of a 3D Poisson process of unit intensity:
#: Gamma(4/3) * (3 / (4 pi))^(1/3).
CLARK_EVANS_3D = 0.55396


def _type_index(type_index: np.ndarray, n_types: int) -> np.ndarray:
    """Check and return `type_index` as an (N,) int64 array with values in [0, n_types)."""
    idx = np.asarray(type_index)
    if idx.size == 0:
        return np.zeros(0, dtype=np.int64)
    if idx.ndim != 1:
        raise InputError(f"type_index must be a 1-D array of type numbers, got shape {idx.shape}")
    if not np.issubdtype(idx.dtype, np.integer):
        raise InputError(f"type_index must hold integers, got dtype {idx.dtype}")
    idx = idx.astype(np.int64)
    if n_types < 1 or idx.min() < 0 or idx.max() >= n_types:
        raise InputError(
            f"type_index holds values in [{idx.min()}, {idx.max()}] but there are "
            f"{n_types} types; every value must be in [0, {n_types - 1}]"
        )
    return idx


def _container_volume(container_volume: float) -> float:
    v = float(container_volume)
    if not np.isfinite(v) or v <= 0.0:
        raise InputError(
            f"container volume must be a positive number, got {container_volume!r}; "
            "check that the container mesh is closed and outward facing"
        )
    return v


def density(placed_volumes: np.ndarray, container_volume: float) -> float:
    """Packing density: sum of placed object volumes over the container volume.

    Args:
        placed_volumes: (N,) exact mesh volume of each placed object (container units^3),
            i.e. the type's mesh volume times scale^3.
        container_volume: exact mesh volume of the container (container units^3), > 0.

    Returns:
        The dimensionless density (0.0 for an empty packing).
    """
    vols = np.asarray(placed_volumes, dtype=np.float64).reshape(-1)
    return float(vols.sum() / _container_volume(container_volume))


def type_shares(type_index: np.ndarray, n_types: int) -> np.ndarray:
    """Achieved share of each type, by count.

    Args:
        type_index: (N,) int, type of each placed object, values in [0, n_types).
        n_types: T, the number of types.

    Returns:
        (T,) float64 shares summing to 1, or all zeros when N == 0.
    """
    idx = _type_index(type_index, n_types)
    counts = np.bincount(idx, minlength=n_types).astype(np.float64)
    if idx.size == 0:
        return counts
    return counts / idx.size


def _normalised_shares(target_shares: np.ndarray) -> np.ndarray:
    q = np.asarray(target_shares, dtype=np.float64).reshape(-1)
    if q.size == 0 or not np.all(np.isfinite(q)) or np.any(q < 0) or q.sum() <= 0:
        raise InputError(
            f"target shares must be non-negative numbers with a positive sum, got {q.tolist()}"
        )
    return q / q.sum()


def equivalent_radius(volume: np.ndarray | float) -> np.ndarray | float:
    """f(V) = (3V / 4pi)^(1/3): the radius of the sphere of volume V (container units).

    The cube root is libm's (`math.cbrt`): numpy's own differs by an ulp on CPUs with
    AVX-512, and the solver's chaos turned that into other packings for the same seed
    (docs/notes-core.md, "Same packing on every machine").
    """
    a = 3.0 * np.asarray(volume, dtype=np.float64) / (4.0 * np.pi)
    r = np.fromiter(map(math.cbrt, a.ravel().tolist()), np.float64, a.size).reshape(a.shape)
    return float(r) if r.ndim == 0 else r


def tvd_of_counts(counts: np.ndarray, shares: np.ndarray) -> float:
    """Total variation distance of type counts (T,) from target shares (T,) summing to 1;
    with no objects p = 0."""
    n = counts.sum()
    if n <= 0:
        return 0.5 * float(np.abs(shares).sum())
    return 0.5 * float(np.abs(counts / n - shares).sum())


def rounded_counts(shares: np.ndarray, n: int) -> np.ndarray:
    """(T,) int64 counts of n objects nearest to target shares (T,) summing to 1: each
    share of n rounded down, and the largest remainders rounded up until they add to n."""
    want = shares * n
    counts = np.floor(want).astype(np.int64)
    short = int(n - counts.sum())
    if short > 0:
        counts[np.argsort(-(want - counts), kind="stable")[:short]] += 1
    return counts


def best_tvd(shares: np.ndarray, n: int) -> float:
    """The smallest TVD any n objects can have against target shares (T,): counts rounded
    by largest remainders (`rounded_counts`)."""
    return tvd_of_counts(rounded_counts(shares, n), shares)


def tvd(type_index: np.ndarray, target_shares: np.ndarray) -> float:
    """Total variation distance between achieved and target type shares.

    TVD = 1/2 * sum_t |p_t - q_t|, with p_t the share (by count) of placed objects of type t
    and q_t the target share (normalised here to sum 1). With no objects p = 0 and TVD = 0.5.

    Args:
        type_index: (N,) int, type of each placed object, values in [0, T).
        target_shares: (T,) non-negative target shares (any positive sum).

    Returns:
        TVD in [0, 1] (0 = exact mix).
    """
    q = _normalised_shares(target_shares)
    counts = np.bincount(_type_index(type_index, q.size), minlength=q.size)
    return tvd_of_counts(counts.astype(np.float64), q)


def nni(
    centres: np.ndarray, type_index: np.ndarray, n_types: int, container_volume: float
) -> dict:
    """Clark-Evans nearest-neighbour index in 3D, per type.

    For each type t with n_t >= 2 objects:
    R_t = mean distance from each object's centre to the nearest centre of the same type,
    divided by 0.55396 * (V / n_t)^(1/3), the expected value for a random (Poisson) layout of
    n_t points in volume V. R < 1 clumped, R ~ 1 random, R > 1 regular.

    Args:
        centres: (N, 3) object centres (container frame, container units).
        type_index: (N,) int, type of each object, values in [0, n_types).
        n_types: T, the number of types.
        container_volume: V, the container mesh volume (container units^3).

    Returns:
        {"per_type": [R_t (float) or None if n_t < 2] * T,
         "mean": count-weighted mean of R_t over types with n_t >= 2, or None if none}.
    """
    v = _container_volume(container_volume)
    idx = _type_index(type_index, n_types)
    pts = np.asarray(centres, dtype=np.float64)
    if pts.size == 0:
        pts = pts.reshape(0, 3)
    if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] != idx.size:
        raise InputError(
            f"centres must have shape ({idx.size}, 3) to match type_index, got {pts.shape}"
        )
    per_type: list[float | None] = []
    weighted_sum = 0.0
    weight = 0
    for t in range(n_types):
        p = pts[idx == t]
        n_t = p.shape[0]
        if n_t < 2:
            per_type.append(None)
            continue
        dist, _ = cKDTree(p).query(p, k=2)
        mean_nn = float(dist[:, 1].mean())
        r_t = mean_nn / (CLARK_EVANS_3D * (v / n_t) ** (1.0 / 3.0))
        per_type.append(float(r_t))
        weighted_sum += n_t * r_t
        weight += n_t
    mean = float(weighted_sum / weight) if weight else None
    return {"per_type": per_type, "mean": mean}


def compute_metrics(
    type_index: np.ndarray,
    centres: np.ndarray,
    placed_volumes_per_type: np.ndarray,
    target_shares: np.ndarray,
    container_volume: float,
) -> dict:
    """All metrics of a finished packing (objects at scale 1), as plain JSON-ready values.

    Args:
        type_index: (N,) int, type of each placed object, values in [0, T).
        centres: (N, 3) object centres = placement translations (container frame, units).
        placed_volumes_per_type: (T,) exact mesh volume of one object of each type
            (container units^3).
        target_shares: (T,) target shares (normalised here).
        container_volume: exact container mesh volume (container units^3).

    Returns:
        {"count": N, "count_per_type": [n_t] * T, "density": float, "tvd": float,
         "nni_per_type": [R_t or None] * T, "nni_mean": float or None,
         "shares": [p_t] * T (achieved, by count)}.
    """
    q = _normalised_shares(target_shares)
    n_types = q.size
    vols = np.asarray(placed_volumes_per_type, dtype=np.float64).reshape(-1)
    if vols.size != n_types:
        raise InputError(
            f"got {vols.size} type volumes but {n_types} target shares; give one of each per type"
        )
    idx = _type_index(type_index, n_types)
    counts = np.bincount(idx, minlength=n_types)
    clump = nni(centres, idx, n_types, container_volume)
    return {
        "count": int(idx.size),
        "count_per_type": [int(c) for c in counts],
        "density": density(vols[idx], container_volume),
        "tvd": tvd(idx, q),
        "nni_per_type": clump["per_type"],
        "nni_mean": clump["mean"],
        "shares": [float(s) for s in type_shares(idx, n_types)],
    }


def mix_cap(counts: np.ndarray, shares: np.ndarray, max_tvd: float) -> float:
    """The largest TVD a cavity insertion may leave: max_tvd, or the current TVD (an
    insertion may always improve the mix), or, with few objects, where one object moves
    the TVD by about 1/n, anything within one object of the best mix the next count allows.
    max_tvd 0 asks for the mix as close as the count allows: the best mix of the next
    count, without that one object.
    """
    n_next = int(counts.sum()) + 1
    slack = 1.0 / n_next if max_tvd > 0 else 1e-12
    return max(max_tvd, tvd_of_counts(counts, shares) - 1e-12,
               best_tvd(shares, n_next) + slack)
