"""Fast reading of the plain vertex and triangle elements of a 3MF mesh (numba).

The 3MF writer of :mod:`jampacked.export.io` (and most slicers) writes one element per line,
``<vertex x="1.5" y="-2" z="3e-05"/>`` and ``<triangle v1="0" v2="1" v3="2"/>``. The scanners
here accept exactly that form (any whitespace between elements) and report failure on
anything else, so that the caller can fall back to its general parser: what they accept,
they read exactly as Python's ``float()`` and ``int()`` do.

Decimal to float64 conversion is the Eisel-Lemire algorithm (D. Lemire, "Number Parsing at
a Gigabyte per Second", Software: Practice and Experience 51(8), 2021), which gives the
correctly rounded value or says it cannot decide; the numbers it cannot decide (more than
19 significant digits, subnormal, out of range, or too close to a halfway point) are
converted by the caller with numpy, as before.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["POW5", "parse_float", "scan_triangles", "scan_vertices", "skip_space"]

_SMALLEST_POWER = -342
_LARGEST_POWER = 308


def _power5_table() -> np.ndarray:
    """(651, 2) uint64: the high and low words of 5**q normalised to 128 bits (truncated for
    q >= 0; for q < 0 the reciprocal, rounded up), q = -342 ... 308."""
    rows = []
    for q in range(_SMALLEST_POWER, _LARGEST_POWER + 1):
        if q < 0:
            power5 = 5**-q
            z = power5.bit_length() if power5 & (power5 - 1) else power5.bit_length() - 1
            # z: the least z with 2**z >= 5**-q (5**-q is never a power of two, for q < 0)
            if q >= -27:
                c = 2 ** (z + 127) // power5 + 1
            else:
                c = 2 ** (2 * z + 128) // power5 + 1
                c >>= max(0, c.bit_length() - 128)
        else:
            c = 5**q
            c <<= max(0, 128 - c.bit_length())
            c >>= max(0, c.bit_length() - 128)
        rows.append((c >> 64, c & 0xFFFFFFFFFFFFFFFF))
    return np.array(rows, dtype=np.uint64)


#: the Eisel-Lemire table of powers of five
POW5 = _power5_table()
#: 10**0 ... 10**22, all exact doubles
_POWERS_OF_TEN = np.array([float(10**k) for k in range(23)])

@njit(cache=True, inline="always")
def _mul128(a, b):
    """Full 64 x 64 -> 128-bit product of two uint64: (high, low)."""
    m32 = np.uint64(0xFFFFFFFF)
    s32 = np.uint64(32)
    a_lo, a_hi = a & m32, a >> s32
    b_lo, b_hi = b & m32, b >> s32
    p0 = a_lo * b_lo
    p1 = a_lo * b_hi
    p2 = a_hi * b_lo
    p3 = a_hi * b_hi
    mid = (p0 >> s32) + (p1 & m32) + (p2 & m32)
    lo = (p0 & m32) | (mid << s32)
    hi = p3 + (p1 >> s32) + (p2 >> s32) + (mid >> s32)
    return hi, lo


@njit(cache=True)
def _eisel_lemire(w, q, negative, pow5):
    """The float64 nearest to w * 10**q (w: uint64 > 0), or (0.0, False) when the 128-bit
    approximation cannot decide it (or it is subnormal, infinite or out of the table)."""
    if q < -342 or q > 308:
        return 0.0, False
    lz = 0  # leading zeros of w (w > 0), by halving the search
    x = w
    for shift in (32, 16, 8, 4, 2, 1):
        if (x >> np.uint64(64 - shift)) == np.uint64(0):
            x <<= np.uint64(shift)
            lz += shift
    row = q + 342
    # one product suffices unless the bits below the 55 kept are all ones
    hi, lo = _mul128(x, pow5[row, 0])
    mask = np.uint64(0x1FF)
    if (hi & mask) == mask:
        hi2, lo2 = _mul128(x, pow5[row, 1])
        lo_sum = lo + hi2
        if hi2 > lo_sum:
            hi += np.uint64(1)
        lo = lo_sum
    if lo == np.uint64(0xFFFFFFFFFFFFFFFF) and (q < -27 or q > 55):
        return 0.0, False
    upperbit = np.int64(hi >> np.uint64(63))
    shift = np.uint64(upperbit + 9)
    mantissa = hi >> shift
    power2 = (((q * (152170 + 65536)) >> 16) + 63) + upperbit - lz + 1023
    if power2 <= 0:
        return 0.0, False  # subnormal or zero: left to the caller
    if (lo <= np.uint64(1) and -4 <= q <= 23 and (mantissa & np.uint64(3)) == np.uint64(1)
            and (mantissa << shift) == hi):
        mantissa &= ~np.uint64(1)  # exactly halfway: round to even (down)
    mantissa += mantissa & np.uint64(1)
    mantissa >>= np.uint64(1)
    if mantissa >= (np.uint64(2) << np.uint64(52)):
        mantissa = np.uint64(1) << np.uint64(52)
        power2 += 1
    if power2 >= 0x7FF:
        return 0.0, False  # infinite
    # mantissa (53 bits, the leading one included) * 2**(power2 - 1075): exact, normal
    value = math.ldexp(float(mantissa), power2 - 1075)
    return -value if negative else value, True


@njit(cache=True, inline="always")
def _digits(buf, i, stop, w, significant):
    """Read decimal digits from buf[i]: the first 19 significant ones accumulate into w.
    Returns (index after them, w, significant digits so far, digits read)."""
    digits = 0
    while i < stop and 48 <= buf[i] <= 57:
        d = np.uint64(buf[i] - 48)
        if significant or d:
            significant += 1
            if significant <= 19:
                w = w * np.uint64(10) + d
        digits += 1
        i += 1
    return i, w, significant, digits


@njit(cache=True)
def parse_float(buf: np.ndarray, start: int, stop: int, pow5: np.ndarray
                ) -> tuple[float, int]:
    """Decimal number in buf[start:stop] (uint8): ``[+-]digits[.digits][(e|E)[+-]digits]``
    with at least one digit. Returns (value, status): 0 read, 1 well formed but left to the
    caller (not decided here), 2 not of that form."""
    i = start
    negative = False
    if i < stop and (buf[i] == 45 or buf[i] == 43):  # - +
        negative = buf[i] == 45
        i += 1
    i, w, significant, digits = _digits(buf, i, stop, np.uint64(0), 0)
    fraction = 0
    if i < stop and buf[i] == 46:  # .
        i, w, significant, fraction = _digits(buf, i + 1, stop, w, significant)
        digits += fraction
    if digits == 0:
        return 0.0, 2
    exponent = 0
    if i < stop and (buf[i] == 101 or buf[i] == 69):  # e E
        i += 1
        exp_negative = False
        if i < stop and (buf[i] == 45 or buf[i] == 43):
            exp_negative = buf[i] == 45
            i += 1
        exp_digits = 0
        while i < stop and 48 <= buf[i] <= 57:
            if exp_digits < 6:
                exponent = exponent * 10 + (buf[i] - 48)
            exp_digits += 1
            i += 1
        if exp_digits == 0:
            return 0.0, 2
        if exp_digits >= 6:
            return 0.0, 1
        if exp_negative:
            exponent = -exponent
    if i != stop:
        return 0.0, 2
    if significant == 0:
        return -0.0 if negative else 0.0, 0
    if significant > 19:
        return 0.0, 1
    q = exponent - fraction
    if w < np.uint64(1 << 53) and -22 <= q <= 22:
        # Clinger's fast path: w and 10**|q| are exact doubles, one rounding
        value = float(w) * _POWERS_OF_TEN[q] if q >= 0 else float(w) / _POWERS_OF_TEN[-q]
        return -value if negative else value, 0
    value, ok = _eisel_lemire(w, q, negative, pow5)
    return value, 0 if ok else 1


@njit(cache=True, inline="always")
def skip_space(buf: np.ndarray, i: int, stop: int) -> int:
    """Index of the first byte from buf[i] that is not XML whitespace (stop if none)."""
    while i < stop and (buf[i] == 32 or buf[i] == 10 or buf[i] == 13 or buf[i] == 9):
        i += 1
    return i


@njit(cache=True, inline="always")
def _match(buf, i, stop, word):
    """Index after ``word`` if buf[i:] starts with it, else -1."""
    n = word.shape[0]
    if i + n > stop:
        return -1
    for k in range(n):
        if buf[i + k] != word[k]:
            return -1
    return i + n


@njit(cache=True)
def _quoted_end(buf, i, stop):
    """Index of the closing quote of a value starting at i (-1 if none)."""
    while i < stop:
        if buf[i] == 34:  # "
            return i
        i += 1
    return -1


@njit(cache=True, inline="always")
def _after_field(buf, i, stop, k, mid1, mid2, tail):
    """Index after the text that follows field k (0, 1, 2) of an element: mid1, mid2 or
    tail (-1 if it is not there)."""
    if k == 0:
        return _match(buf, i, stop, mid1)
    if k == 1:
        return _match(buf, i, stop, mid2)
    return _match(buf, i, stop, tail)


@njit(cache=True, inline="always")
def _capacity(start, stop, head, mid1, mid2, tail):
    """Room for the numbers of every element buf[start:stop] can hold: three per element,
    each element at least its fixed text plus one character per number."""
    return 3 * ((stop - start) // (head.shape[0] + mid1.shape[0] + mid2.shape[0]
                                   + tail.shape[0] + 3) + 1)


@njit(cache=True)
def scan_vertices(buf: np.ndarray, start: int, stop: int, head: np.ndarray, mid1: np.ndarray,
                  mid2: np.ndarray, tail: np.ndarray, pow5: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, int, bool]:
    """Numbers of the plain elements ``head N mid1 N mid2 N tail`` from buf[start], with
    only whitespace around elements, e.g. head = b'<vertex x="', tail = b'"/>'; the scan
    ends at ``stop`` or at the first other tag.

    Returns (values, spans, end, ok): (3K,) float64; (M, 2) start and stop of the numbers
    left to the caller (their values are NaN); where the scan ended (``stop``, or the "<" of
    the other tag); ok False when an element starting with ``head`` has another form.
    """
    cap = _capacity(start, stop, head, mid1, mid2, tail)
    values = np.empty(cap, np.float64)
    spans = np.empty((16, 2), np.int64)
    n_spans = 0
    n = 0
    i = skip_space(buf, start, stop)
    while i < stop:
        end = i
        i = _match(buf, i, stop, head)
        if i < 0 and buf[end] == 60:  # "<": another tag
            return values[:n], spans[:n_spans], end, True
        for k in range(3):
            if i < 0:
                return values[:0], spans[:0], i, False
            j = _quoted_end(buf, i, stop)
            if j < 0:
                return values[:0], spans[:0], i, False
            value, status = parse_float(buf, i, j, pow5)
            if status == 2:
                return values[:0], spans[:0], i, False
            if status == 1:
                if n_spans == spans.shape[0]:
                    grown = np.empty((2 * n_spans, 2), np.int64)
                    grown[:n_spans] = spans
                    spans = grown
                spans[n_spans, 0] = i
                spans[n_spans, 1] = j
                n_spans += 1
                value = np.nan
            values[n] = value
            n += 1
            i = _after_field(buf, j, stop, k, mid1, mid2, tail)
        if i < 0:
            return values[:0], spans[:0], i, False
        i = skip_space(buf, i, stop)
    return values[:n], spans[:n_spans], stop, True


@njit(cache=True)
def scan_triangles(buf: np.ndarray, start: int, stop: int, head: np.ndarray, mid1: np.ndarray,
                   mid2: np.ndarray, tail: np.ndarray) -> tuple[np.ndarray, int, bool]:
    """Indices of the plain elements ``head N mid1 N mid2 N tail`` from buf[start] (N: 1 to
    15 decimal digits), only whitespace around elements; the scan ends at ``stop`` or at the
    first other tag. Returns ((3K,) int64, end, ok) as :func:`scan_vertices`."""
    cap = _capacity(start, stop, head, mid1, mid2, tail)
    values = np.empty(cap, np.int64)
    n = 0
    i = skip_space(buf, start, stop)
    while i < stop:
        end = i
        i = _match(buf, i, stop, head)
        if i < 0 and buf[end] == 60:  # "<": another tag
            return values[:n], end, True
        for k in range(3):
            if i < 0:
                return values[:0], i, False
            value = 0
            digits = 0
            while i < stop and 48 <= buf[i] <= 57:
                value = value * 10 + (buf[i] - 48)
                digits += 1
                i += 1
            if digits == 0 or digits > 15:
                return values[:0], i, False
            values[n] = value
            n += 1
            i = _after_field(buf, i, stop, k, mid1, mid2, tail)
        if i < 0:
            return values[:0], i, False
        i = skip_space(buf, i, stop)
    return values[:n], stop, True
