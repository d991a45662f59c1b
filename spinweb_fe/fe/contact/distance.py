"""Distances of cable elements: the closest points of two segments (clamped to both,
parallel and degenerate segments handled) and their distance, for a pair of nodes' elements
and for a whole candidate list.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(inline="always")
def _closest(p00, p01, p02, p10, p11, p12, q00, q01, q02, q10, q11, q12):
    """closest_points on the twelve coordinates (scalars: no array is made, as this runs
    for every close pair of every step)."""
    d10, d11, d12 = p10 - p00, p11 - p01, p12 - p02
    d20, d21, d22 = q10 - q00, q11 - q01, q12 - q02
    w0, w1, w2 = p00 - q00, p01 - q01, p02 - q02
    a = d10 * d10 + d11 * d11 + d12 * d12
    e = d20 * d20 + d21 * d21 + d22 * d22
    f = d20 * w0 + d21 * w1 + d22 * w2
    c = d10 * w0 + d11 * w1 + d12 * w2
    b = d10 * d20 + d11 * d21 + d12 * d22
    if a <= 0.0 or e <= 0.0:  # an element of no length (a folded web's degenerate one)
        if a <= 0.0 and e <= 0.0:
            s, t = 0.0, 0.0
        elif a <= 0.0:
            s, t = 0.0, min(max(f / e, 0.0), 1.0)
        else:
            s, t = min(max(-c / a, 0.0), 1.0), 0.0
    else:
        den = a * e - b * b
        s = min(max((b * f - c * e) / den, 0.0), 1.0) if den > 1e-14 * a * e else 0.0
        t = (b * s + f) / e
        if t < 0.0:
            t, s = 0.0, min(max(-c / a, 0.0), 1.0)
        elif t > 1.0:
            t, s = 1.0, min(max((b - c) / a, 0.0), 1.0)
    x0 = w0 + s * d10 - t * d20
    x1 = w1 + s * d11 - t * d21
    x2 = w2 + s * d12 - t * d22
    return s, t, np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)


@njit(cache=True)
def closest_points(p0, p1, q0, q1):
    """(s, t, distance): the parameters of the closest points of segments p0p1 and q0q1
    (clamped to both segments; parallel segments handled) and their distance [m]."""
    return _closest(p0[0], p0[1], p0[2], p1[0], p1[1], p1[2], q0[0], q0[1], q0[2], q1[0],
                    q1[1], q1[2])


@njit(inline="always")
def closest_nodes(pos, a, b, c, d):
    """closest_points of the segments of nodes a b and c d (rows of ``pos``)."""
    return _closest(pos[a, 0], pos[a, 1], pos[a, 2], pos[b, 0], pos[b, 1], pos[b, 2],
                    pos[c, 0], pos[c, 1], pos[c, 2], pos[d, 0], pos[d, 1], pos[d, 2])


@njit(cache=True)
def segment_distance(p, q, r, s):
    """The least distance [m] between the segments pq and rs."""
    return closest_points(p, q, r, s)[2]
