"""Stripmap weighting W(psi) (paper Sec. III-C): which pulses each pixel integrates.

The processed beam points at 90 deg to the direction of motion and has a constant angular half-width
``psi_max = lambda / (4 rho)`` for a cross-range resolution ``rho``, so the synthetic aperture grows with
range and the resolution stays constant. A pulse p contributes to pixel x when the angle psi between the
line of sight and the zero-Doppler plane of the pulse is small: ``|sin psi| = |(x - a_p) . v_p| / |x - a_p|
<= sin psi_max`` (a_p: antenna, v_p: unit velocity). Along a drive sin psi decreases monotonically as
the radar passes a pixel, so the contributing pulses form one interval [lo, hi), found by bisection.

The beam alone does not bound the resolution in a curve: where the car turns towards a pixel (the pixel near
the centre of curvature), the velocity turns with the line of sight, psi stays small for much longer, and the
pixel sees the track over many times 2 psi_max of look angle (test3's zig-zag turns on a ~20 m radius: facade
pillars at 16 m focused to a few mm across the track, and the image's entropy moved by up to 2 % when its grid
moved by half a pixel). The window is therefore also cut to the pulses whose line of sight (pixel to antenna) is within
psi_max of the line of sight at zero Doppler (psi = 0). On a straight track that is the same interval (the
angle between the two lines of sight is psi), so the aperture spans 2 psi_max of look angle everywhere. Where the
drive ends before the pixel reaches zero Doppler, the drive's last pulse stands in for it; where it starts after,
its first.

Focus works in blocks of pulses; a block's windows come from the block plus the pulses within
:func:`look_angle_margin_m` of travel either side (:func:`block_context`), so a pixel's zero-Doppler pulse is found
even where it lies in a neighbouring block, and the windows are those of the whole drive cut to the block.
One pass of the beam is assumed: beyond a turn's centre of curvature sin psi is not monotone, and the bisections
find one of its crossings.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray


def processed_half_width(wavelength_m: float, resolution_m: float) -> float:
    """Half-width psi_max = lambda / (4 rho) (rad) of the processed beam for cross-range resolution rho."""
    if resolution_m <= 0:
        raise ValueError(f"cross-range resolution {resolution_m} m: must be positive")
    return wavelength_m / (4.0 * resolution_m)


def cross_range_width_theory(resolution_m: float) -> float:
    """-3 dB width (m) of the cross-range response of a uniformly weighted beam of half-width lambda/(4 rho).

    The aperture spans 2 psi_max = lambda / (2 rho) of angle, so the response is a sinc of first null at rho
    and -3 dB width 0.886 rho.
    """
    return 0.8859 * resolution_m


@nb.njit(cache=True, inline="always")
def _sin_psi(px, py, pz, ax, ay, az, vx, vy, vz):  # pragma: no cover - compiled
    dx = px - ax
    dy = py - ay
    dz = pz - az
    return (dx * vx + dy * vy + dz * vz) / math.sqrt(dx * dx + dy * dy + dz * dz)


@nb.njit(cache=True, inline="always")
def _unit(x, y, z):  # pragma: no cover - compiled
    n = math.sqrt(x * x + y * y + z * z)
    return x / n, y / n, z / n


@nb.njit(cache=True, inline="always")
def _sin_angle(px, py, pz, ax, ay, az, ux, uy, uz):  # pragma: no cover - compiled
    """sin of the angle between the line of sight pixel -> antenna and the unit vector u."""
    dx, dy, dz = _unit(ax - px, ay - py, az - pz)
    cx = dy * uz - dz * uy
    cy = dz * ux - dx * uz
    cz = dx * uy - dy * ux
    return math.sqrt(cx * cx + cy * cy + cz * cz)


@nb.njit(cache=True, inline="always")
def _window(px, py, pz, ant, vel, s_max, side, b0, b1, open_start, open_end):  # pragma: no cover - compiled
    """[first, last) pulses of one pixel within the block [b0, b1) of the context ``ant`` (see the module
    docstring); ``open_start`` / ``open_end``: the context starts / ends where the drive does."""
    n_p = ant.shape[0]
    # first pulse with sin psi <= s_max, then first with sin psi < -s_max (sin psi decreases with p)
    lo = 0
    hi = n_p
    while lo < hi:
        m = (lo + hi) // 2
        if _sin_psi(px, py, pz, ant[m, 0], ant[m, 1], ant[m, 2], vel[m, 0], vel[m, 1], vel[m, 2]) <= s_max:
            hi = m
        else:
            lo = m + 1
    first = lo
    hi = n_p
    while lo < hi:
        m = (lo + hi) // 2
        if _sin_psi(px, py, pz, ant[m, 0], ant[m, 1], ant[m, 2], vel[m, 0], vel[m, 1], vel[m, 2]) < -s_max:
            hi = m
        else:
            lo = m + 1
    if lo > first:
        # the zero-Doppler pulse m0: the first with sin psi <= 0
        a = first
        b = lo
        while a < b:
            m = (a + b) // 2
            if _sin_psi(px, py, pz, ant[m, 0], ant[m, 1], ant[m, 2], vel[m, 0], vel[m, 1], vel[m, 2]) <= 0.0:
                b = m
            else:
                a = m + 1
        m0 = a
        if m0 == lo:
            # no pulse of the beam past zero Doppler: psi jumps past zero after its last pulse (the nearest
            # pixels), or the drive ends first (take its last pulse), or the context does (below)
            m0 = lo - 1
        if (m0 == n_p - 1 and a == n_p and not open_end) or (m0 == 0 and not open_start):
            # zero Doppler beyond this end of the context (at or before its first pulse): the margin puts
            # the block's pulses outside the look-angle cut
            lo = first
        else:
            # only the pulses whose line of sight is within psi_max of m0's (on straight stretches all of them:
            # test the ends before bisecting)
            ux, uy, uz = _unit(ant[m0, 0] - px, ant[m0, 1] - py, ant[m0, 2] - pz)
            a = first
            b = m0
            if _sin_angle(px, py, pz, ant[a, 0], ant[a, 1], ant[a, 2], ux, uy, uz) <= s_max:
                b = a
            while a < b:
                m = (a + b) // 2
                if _sin_angle(px, py, pz, ant[m, 0], ant[m, 1], ant[m, 2], ux, uy, uz) <= s_max:
                    b = m
                else:
                    a = m + 1
            first = a
            a = m0
            b = lo
            if _sin_angle(px, py, pz, ant[b - 1, 0], ant[b - 1, 1], ant[b - 1, 2], ux, uy, uz) <= s_max:
                a = b
            while a < b:
                m = (a + b) // 2
                if _sin_angle(px, py, pz, ant[m, 0], ant[m, 1], ant[m, 2], ux, uy, uz) > s_max:
                    b = m
                else:
                    a = m + 1
            lo = a
    first = max(first, b0)
    lo = max(first, min(lo, b1))
    if side != 0.0 and lo > first:
        # the radar sees one side only: a pixel on the other side would alias onto its mirror image
        m = (first + lo) // 2
        cross = vel[m, 0] * (py - ant[m, 1]) - vel[m, 1] * (px - ant[m, 0])
        if cross * side <= 0.0:
            lo = first
    return first - b0, lo - b0


@nb.njit(parallel=True, cache=True, nogil=True)
def _windows(pix, ant, vel, s_max, side, b0, b1, open_start, open_end, out):  # pragma: no cover - compiled
    for k in nb.prange(pix.shape[0]):
        out[k, 0], out[k, 1] = _window(pix[k, 0], pix[k, 1], pix[k, 2], ant, vel, s_max, side, b0, b1,
                                       open_start, open_end)


@nb.njit(cache=True, nogil=True)
def _windows_serial(pix, ant, vel, s_max, side, b0, b1, open_start, open_end, out):  # pragma: no cover - compiled
    for k in range(pix.shape[0]):
        out[k, 0], out[k, 1] = _window(pix[k, 0], pix[k, 1], pix[k, 2], ant, vel, s_max, side, b0, b1,
                                       open_start, open_end)


@nb.njit(cache=True, nogil=True)
def _zero_doppler(pix, ant, vel, out):  # pragma: no cover - compiled
    n_p = ant.shape[0]
    for k in range(pix.shape[0]):
        lo = 0
        hi = n_p
        while lo < hi:  # the first pulse with the pixel abeam or behind (sin psi <= 0; it decreases with p)
            m = (lo + hi) // 2
            if _sin_psi(pix[k, 0], pix[k, 1], pix[k, 2], ant[m, 0], ant[m, 1], ant[m, 2], vel[m, 0], vel[m, 1],
                        vel[m, 2]) <= 0.0:
                hi = m
            else:
                lo = m + 1
        out[k] = min(lo, n_p - 1)


def zero_doppler_pulses(pixels: ArrayLike, antenna: ArrayLike, velocity: ArrayLike,
                        context: tuple[int, int] | None = None) -> NDArray[np.int64]:
    """Index (N,) into ``antenna`` of each pixel's zero-Doppler pulse, the first with the pixel abeam or behind,
    searched within ``context`` = (c0, c1) (default: all) and clamped to its ends; the same bisection as
    :func:`stripmap_windows`'s. ``pixels`` (N, 3), ``antenna`` (P, 3): ENU m; ``velocity`` (P, 3): any scale."""
    c0, c1 = context if context is not None else (0, len(np.asarray(antenna).reshape(-1, 3)))
    pix, ant, unit = _search_arrays(pixels, antenna, velocity, c0, c1)
    out = np.zeros(len(pix), np.int64)
    if len(ant) and len(pix):
        _zero_doppler(pix, ant, unit, out)
    return out + c0


def _search_arrays(pixels: ArrayLike, antenna: ArrayLike, velocity: ArrayLike, c0: int, c1: int
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The kernels' inputs: pixels (N, 3), the context's antenna positions (c1 - c0, 3) and unit velocities."""
    pix = np.ascontiguousarray(np.asarray(pixels, dtype=np.float64).reshape(-1, 3))
    ant = np.ascontiguousarray(np.asarray(antenna, dtype=np.float64).reshape(-1, 3)[c0:c1])
    vel = np.asarray(velocity, dtype=np.float64).reshape(-1, 3)[c0:c1]
    speed = np.linalg.norm(vel, axis=1, keepdims=True)
    return pix, ant, np.ascontiguousarray(vel / np.where(speed > 0, speed, 1.0))


def look_angle_margin_m(max_range_m: float, half_width_rad: float) -> float:
    """Travel (m) beyond which no pulse is within ``half_width_rad`` of look angle of a pixel's zero-Doppler line of
    sight, for pixels up to ``max_range_m`` away: seen from the pixel the line of sight turns by at least
    cos(psi_max) / R per metre of travel inside the beam. Padded by a quarter for the slant and the track's bends."""
    return 1.25 * max_range_m * math.tan(half_width_rad) / math.cos(half_width_rad)


def block_context(travel_m: NDArray[np.float64], start: int, stop: int, margin_m: float) -> tuple[int, int]:
    """Pulses [c0, c1) within ``margin_m`` of travel of the block [start, stop), ``travel_m`` (P,) the cumulative
    distance travelled at each pulse: what :func:`stripmap_windows` needs to find the block's windows as if it saw
    the whole drive."""
    c0 = int(np.searchsorted(travel_m, travel_m[start] - margin_m, side="left"))
    c1 = int(np.searchsorted(travel_m, travel_m[stop - 1] + margin_m, side="right"))
    return min(c0, start), max(c1, stop)


def stripmap_windows(pixels: ArrayLike, antenna: ArrayLike, velocity: ArrayLike, half_width_rad: float,
                     side: float = 0.0, *, parallel: bool = True, block: tuple[int, int] | None = None,
                     context: tuple[int, int] | None = None) -> NDArray[np.int64]:
    """Pulse interval [lo, hi) (N, 2) integrated by each pixel (empty: lo == hi).

    ``pixels`` (N, 3) and ``antenna`` (P, 3): ENU metres (the antenna is the reference phase centre of each
    pulse of the drive); ``velocity`` (P, 3): its velocity (any scale; only the direction is used). ``side`` > 0:
    only pixels left of the track get pulses, < 0: only those on the right, 0: both. ``parallel=False``: one
    thread, for a caller that runs beside other numba-parallel work (no nested parallel launch).

    ``block`` = (start, stop): only these pulses are wanted (default: all), and the intervals are returned relative
    to ``start``. ``context`` = (c0, c1) around it: the pulses searched, for the zero-Doppler line of sight of
    pixels whose aperture straddles the block's ends (default: all; :func:`block_context` with
    :func:`look_angle_margin_m` gives enough).
    """
    n = len(np.asarray(antenna).reshape(-1, 3))
    start, stop = block if block is not None else (0, n)
    c0, c1 = context if context is not None else (0, n)
    if not 0 <= c0 <= start <= stop <= c1 <= n:
        raise ValueError(f"block {start}..{stop} in context {c0}..{c1}: not nested within the {n} pulses given")
    pix, ant, vel = _search_arrays(pixels, antenna, velocity, c0, c1)
    out = np.zeros((len(pix), 2), np.int64)
    if len(ant) and len(pix):
        (_windows if parallel else _windows_serial)(pix, ant, vel, math.sin(half_width_rad), float(np.sign(side)),
                                                     start - c0, stop - c0, c0 == 0, c1 == n, out)
    return out
