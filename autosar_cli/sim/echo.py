"""FMCW beat-signal synthesis for a TDM-MIMO radar and a scene of point scatterers, still or moving (numba kernel).

Signal model (one chirp, Tx k, Rx q, scatterer p, ADC sample time t = n / fs from the first sample):

    tau(t)  = (|p(t) - tx_k(t)| + |p(t) - rx_q(t)|) / c         bistatic delay, linear over the chirp
    s(t)    = A * exp(+j 2 pi (f0 tau + K tau t - K tau^2 / 2))   complex I/Q beat (dechirp tx x conj(rx))
    A       = amplitude_lsb * sqrt(rcs) * P(az, el) / r^2       radar equation in amplitude
    P       = cos(az)^n_az cos(el)^n_el                         one-way power pattern = two-way amplitude

f0 is the RF frequency at the first ADC sample. The delay varies linearly over the 40 us window (the
intra-chirp Doppler); its quadratic phase term (K dtau/dt t^2 <= 0.03 rad at 5 m/s) is linearised
about the window centre, leaving < 0.007 rad. Scatterers beyond the IF band (beat >= 0.98 fs) or behind
the antenna plane are not received.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from autosar_cli.config import SPEED_OF_LIGHT

IF_BAND_FRACTION = 0.98
#: a scatterer within this height (m) of the road is on it: its image in the road is itself
ON_ROAD_M = 0.01
SEGMENT = 136  # samples between exact re-anchoring of the tone recurrence
# fastmath without "contract": whether LLVM fuses a multiply and an add into an FMA depends on the context it
# optimises in, and the copy numba caches is optimised once more than the one a fresh compile runs, so with
# contraction a compiled and a cached kernel differ in the last bit. Reassociating the sum is a property of the
# loop alone (it is what lets the scatterer sum vectorise).
SUM_FASTMATH = {"reassoc", "nsz", "nnan", "ninf", "arcp"}


def pattern_exponent(beamwidth_deg: float) -> float:
    """Exponent n of cos^n whose one-way power is -3 dB at half the beamwidth."""
    return math.log(0.5) / math.log(math.cos(math.radians(beamwidth_deg / 2.0)))


@nb.njit(cache=True, fastmath=SUM_FASTMATH)
def _accumulate_tones(p_re, p_im, s_re, s_im, nv, out_row):  # pragma: no cover - compiled
    """out_row[n] = sum_i p_i * s_i^n: phasor recurrence, vectorised over scatterers."""
    for n in range(out_row.shape[0]):
        acc_re = np.float32(0.0)
        acc_im = np.float32(0.0)
        for i in range(nv):
            a = p_re[i]
            b = p_im[i]
            acc_re += a
            acc_im += b
            p_re[i] = a * s_re[i] - b * s_im[i]
            p_im[i] = a * s_im[i] + b * s_re[i]
        out_row[n] = complex(acc_re, acc_im)


@nb.njit(cache=True)
def _phasors(turns, amp, re, im, n):  # pragma: no cover - compiled
    """re + j im = amp * exp(j 2 pi turns) for turns in [-1/2, 1/2]: octant reduction and Taylor series
    (phase error < 4e-7 rad, modulus normalised), branch-free so that the loop vectorises (libm sin/cos do not)."""
    for i in range(n):
        r = np.float32(turns[i])
        q = np.float32(math.floor(r * np.float32(4.0) + np.float32(0.5)))
        t = (r - q * np.float32(0.25)) * np.float32(2.0 * np.pi)
        t2 = t * t
        sn = t * (np.float32(1.0) + t2 * (np.float32(-1.0 / 6.0) + t2 * (np.float32(1.0 / 120.0)
                                                                        + t2 * np.float32(-1.0 / 5040.0))))
        cs = np.float32(1.0) + t2 * (np.float32(-0.5) + t2 * (np.float32(1.0 / 24.0) + t2 * (
            np.float32(-1.0 / 720.0) + t2 * np.float32(1.0 / 40320.0))))
        qi = int(q) & 3
        c_out = cs if qi == 0 else (-sn if qi == 1 else (-cs if qi == 2 else sn))
        s_out = sn if qi == 0 else (cs if qi == 1 else (-sn if qi == 2 else -cs))
        # unit modulus to float32 rounding, so that a 540-step recurrence keeps its amplitude
        a = np.float32(amp[i]) / math.sqrt(c_out * c_out + s_out * s_out)
        re[i] = a * c_out
        im[i] = a * s_out


@nb.njit(cache=True)
def _leg(dx, dy, dz, enu_to_radar, f, n_az, n_el):  # pragma: no cover - compiled
    """Range (m) towards (dx, dy, dz) (ENU m from the radar's origin at frame f) and the two-way amplitude
    pattern's azimuth and elevation factors there (cos^n each; 0 behind the antenna plane or within 5 cm)."""
    r = math.sqrt(dx * dx + dy * dy + dz * dz)
    if r < 0.05:
        return r, 0.0, 0.0
    ux = (enu_to_radar[f, 0, 0] * dx + enu_to_radar[f, 0, 1] * dy + enu_to_radar[f, 0, 2] * dz) / r
    if ux <= 0.0:
        return r, 0.0, 0.0
    uy = (enu_to_radar[f, 1, 0] * dx + enu_to_radar[f, 1, 1] * dy + enu_to_radar[f, 1, 2] * dz) / r
    horiz = math.sqrt(ux * ux + uy * uy)
    return r, (ux / horiz) ** n_az, min(horiz, 1.0) ** n_el


@nb.njit(cache=True, parallel=True)
def _synthesize(tx0, tx1, rx0, rx1, origin, enu_to_radar, targets, sqrt_rcs, velocity, t_start, f0, slope, fs,
                amplitude, n_az, n_el, max_path, mirror_z, cross_gain, bounce_gain, out):  # pragma: no cover
    n_frames, n_tx, n_rx, n_samp = out.shape
    n_tgt = targets.shape[0]
    first_moving = n_tgt - velocity.shape[0]  # the last targets move (velocity), the others stand still
    c = 299792458.0
    t_win = n_samp / fs
    t_mid = 0.5 * (n_samp - 1) / fs
    for f in nb.prange(n_frames):
        # tone i: target idx[i] by way of path[i] (bit 0: the Tx leg mirrored in the road, bit 1: the Rx leg)
        idx = np.empty(4 * n_tgt, np.int64)
        path = np.empty(4 * n_tgt, np.int64)
        gain = np.empty(4 * n_tgt, np.float64)
        nv = 0
        for m in range(n_tgt):
            dx = targets[m, 0] - origin[f, 0]
            dy = targets[m, 1] - origin[f, 1]
            dz = targets[m, 2] - origin[f, 2]
            if m >= first_moving:  # where the frame's first chirp starts
                dx += velocity[m - first_moving, 0] * t_start[f, 0]
                dy += velocity[m - first_moving, 1] * t_start[f, 0]
                dz += velocity[m - first_moving, 2] * t_start[f, 0]
            r, g_az, g_el = _leg(dx, dy, dz, enu_to_radar, f, n_az, n_el)
            if r < 0.05:
                continue
            a = amplitude * sqrt_rcs[m]
            if g_az > 0.0 and 2.0 * r < max_path:
                gain[nv] = a * g_az * g_el / (r * r)
                idx[nv] = m
                path[nv] = 0
                nv += 1
            if cross_gain[m] == 0.0 and bounce_gain[m] == 0.0:
                continue
            # the image in the road: the scatterer mirrored in the horizontal plane at mirror_z
            ri, gi_az, gi_el = _leg(dx, dy, 2.0 * (mirror_z[m] - origin[f, 2]) - dz, enu_to_radar, f, n_az, n_el)
            # a one-way leg carries the square root of the two-way pattern
            if cross_gain[m] != 0.0 and g_az > 0.0 and gi_az > 0.0 and r + ri < max_path:
                for leg in (1, 2):
                    gain[nv] = a * cross_gain[m] * math.sqrt(g_az * g_el * gi_az * gi_el) / (r * ri)
                    idx[nv] = m
                    path[nv] = leg
                    nv += 1
            if bounce_gain[m] != 0.0 and gi_az > 0.0 and 2.0 * ri < max_path:
                gain[nv] = a * bounce_gain[m] * gi_az * gi_el / (ri * ri)
                idx[nv] = m
                path[nv] = 3
                nv += 1
        p_re = np.empty(nv, np.float32)
        p_im = np.empty(nv, np.float32)
        s_re = np.empty(nv, np.float32)
        s_im = np.empty(nv, np.float32)
        turn0 = np.empty(nv, np.float64)
        turn1 = np.empty(nv, np.float64)
        ones = np.ones(nv, np.float64)
        turn_seg = np.empty(nv, np.float64)
        for k in range(n_tx):
            for q in range(n_rx):
                for i in range(nv):
                    m = idx[i]
                    px = targets[m, 0]
                    py = targets[m, 1]
                    pz = targets[m, 2]
                    # a mover's positions at the chirp's first and one-past-last ADC sample, as the antennas'
                    qx, qy, qz = px, py, pz
                    if m >= first_moving:
                        j = m - first_moving
                        t0 = t_start[f, k]
                        qx = px + velocity[j, 0] * (t0 + t_win)
                        qy = py + velocity[j, 1] * (t0 + t_win)
                        qz = pz + velocity[j, 2] * (t0 + t_win)
                        px = px + velocity[j, 0] * t0
                        py = py + velocity[j, 1] * t0
                        pz = pz + velocity[j, 2] * t0
                    # each leg to the scatterer or to its image in the road
                    ptz = 2.0 * mirror_z[m] - pz if path[i] & 1 else pz
                    prz = 2.0 * mirror_z[m] - pz if path[i] & 2 else pz
                    qtz = 2.0 * mirror_z[m] - qz if path[i] & 1 else qz
                    qrz = 2.0 * mirror_z[m] - qz if path[i] & 2 else qz
                    d0 = (math.sqrt((px - tx0[f, k, 0]) ** 2 + (py - tx0[f, k, 1]) ** 2 + (ptz - tx0[f, k, 2]) ** 2)
                          + math.sqrt((px - rx0[f, k, q, 0]) ** 2 + (py - rx0[f, k, q, 1]) ** 2
                                      + (prz - rx0[f, k, q, 2]) ** 2))
                    d1 = (math.sqrt((qx - tx1[f, k, 0]) ** 2 + (qy - tx1[f, k, 1]) ** 2 + (qtz - tx1[f, k, 2]) ** 2)
                          + math.sqrt((qx - rx1[f, k, q, 0]) ** 2 + (qy - rx1[f, k, q, 1]) ** 2
                                      + (qrz - rx1[f, k, q, 2]) ** 2))
                    tau0 = d0 / c
                    tau_dot = (d1 - d0) / c / t_win
                    tau_m = tau0 + tau_dot * t_mid
                    cycles_mid = f0 * tau_m + slope * tau_m * t_mid - 0.5 * slope * tau_m * tau_m
                    freq = f0 * tau_dot + slope * tau_dot * t_mid + slope * tau_m - slope * tau_m * tau_dot
                    cyc0 = cycles_mid - freq * t_mid
                    # phases in turns, reduced in float64; sin/cos below in vectorised float32
                    turn0[i] = cyc0 - math.floor(cyc0 + 0.5)
                    step = freq / fs
                    turn1[i] = step - math.floor(step + 0.5)
                _phasors(turn1, ones, s_re, s_im, nv)
                # re-anchor the float32 recurrence on the exact phase every SEGMENT samples
                for n0 in range(0, n_samp, SEGMENT):
                    for i in range(nv):
                        t = turn0[i] + n0 * turn1[i]
                        turn_seg[i] = t - math.floor(t + 0.5)
                    _phasors(turn_seg, gain, p_re, p_im, nv)
                    _accumulate_tones(p_re, p_im, s_re, s_im, nv, out[f, k, q, n0 : min(n0 + SEGMENT, n_samp)])


def synthesize_beat(
    tx_start: NDArray[np.float64],
    tx_end: NDArray[np.float64],
    rx_start: NDArray[np.float64],
    rx_end: NDArray[np.float64],
    radar_origin: NDArray[np.float64],
    enu_to_radar: NDArray[np.float64],
    targets: NDArray[np.float64],
    rcs_m2: NDArray[np.float64],
    *,
    start_frequency_hz: float,
    slope_hz_per_s: float,
    sample_rate_hz: float,
    num_samples: int,
    amplitude_lsb: float,
    beamwidth_az_deg: float,
    beamwidth_el_deg: float,
    target_velocity: NDArray[np.float64] | None = None,
    chirp_start_s: NDArray[np.float64] | None = None,
    road_reflection: float = 0.0,
    road_height: NDArray[np.float64] | None = None,
    retroreflector: NDArray[np.bool_] | None = None,
) -> NDArray[np.complex64]:
    """Noise-free complex beat samples (F, T, R, N), in ADC LSB.

    Args:
        tx_start, tx_end: ENU positions (m) of each Tx at the first / one-past-last ADC sample of its
            chirp, (F, T, 3).
        rx_start, rx_end: ENU positions (m) of each Rx during Tx k's chirp, same instants, (F, T, R, 3).
        radar_origin: ENU position (m) of the radar frame origin per frame, (F, 3) (pattern, path loss).
        enu_to_radar: rotation ENU -> radar frame per frame, (F, 3, 3).
        targets: scatterer ENU positions (m), (M, 3); rcs_m2: their radar cross sections (M,).
        target_velocity: each scatterer's ENU velocity (m/s), (M, 3), None: all stand still; a mover is at
            ``targets + target_velocity * t`` at time t (s).
        chirp_start_s: with ``target_velocity``, the time (s, the movers' clock) of each Tx chirp's first ADC
            sample, (F, T): the instants of ``tx_start``.
        road_reflection: the road's specular amplitude reflection coefficient Gamma (real, -1 < Gamma < 1; 0: no
            path by way of the road), for every scatterer more than ``ON_ROAD_M`` above ``road_height``, the ENU
            height (m) of the road beneath each (M,) (0 where not given); ``retroreflector`` (M,): those that
            return only their direct and two-bounce paths.
    """
    n_frames, n_tx = tx_start.shape[:2]
    n_rx = rx_start.shape[2]
    out = np.zeros((n_frames, n_tx, n_rx, num_samples), dtype=np.complex64)
    max_path = IF_BAND_FRACTION * sample_rate_hz * SPEED_OF_LIGHT / slope_hz_per_s
    targets = np.asarray(targets, np.float64)
    sqrt_rcs = np.sqrt(np.asarray(rcs_m2, np.float64))
    mirror_z = np.zeros(len(targets)) if road_height is None else np.asarray(road_height, np.float64).copy()
    above = targets[:, 2] - mirror_z > ON_ROAD_M
    retro = np.zeros(len(targets), bool) if retroreflector is None else np.asarray(retroreflector, bool)
    cross_gain = np.where(above & ~retro, road_reflection, 0.0)
    bounce_gain = np.where(above, road_reflection ** 2, 0.0)
    velocity = np.zeros((0, 3))
    t_start = np.zeros((n_frames, n_tx))
    if target_velocity is not None and np.any(target_velocity != 0.0):
        if chirp_start_s is None:
            raise ValueError("moving targets need the chirps' start times (chirp_start_s)")
        # the kernel takes the movers last: the still ones' sum keeps its order
        moving = np.any(np.asarray(target_velocity) != 0.0, axis=1)
        order = np.concatenate([np.flatnonzero(~moving), np.flatnonzero(moving)])
        targets, sqrt_rcs = targets[order], sqrt_rcs[order]
        mirror_z, cross_gain, bounce_gain = mirror_z[order], cross_gain[order], bounce_gain[order]
        velocity = np.asarray(target_velocity, np.float64)[moving]
        t_start = np.asarray(chirp_start_s, np.float64)
    _synthesize(
        np.ascontiguousarray(tx_start, np.float64), np.ascontiguousarray(tx_end, np.float64),
        np.ascontiguousarray(rx_start, np.float64), np.ascontiguousarray(rx_end, np.float64),
        np.ascontiguousarray(radar_origin, np.float64), np.ascontiguousarray(enu_to_radar, np.float64),
        np.ascontiguousarray(targets), sqrt_rcs, np.ascontiguousarray(velocity),
        np.ascontiguousarray(t_start), float(start_frequency_hz), float(slope_hz_per_s), float(sample_rate_hz),
        float(amplitude_lsb),
        pattern_exponent(beamwidth_az_deg), pattern_exponent(beamwidth_el_deg), float(max_path),
        np.ascontiguousarray(mirror_z), np.ascontiguousarray(cross_gain, np.float64),
        np.ascontiguousarray(bounce_gain, np.float64), out,
    )
    return out
