"""The radar's channel gains measured on the drive's own still points, with no calibration target.

Each candidate point's echoes (:func:`autosar_cli.sar.phase_history.gather_phase_histories`, the channels the image
sums, within ``half_beam_deg`` of broadside, in runs of ``frame_runs``) are back-projected onto it pulse by
pulse, channel by channel, along the navigated track. A pulse's channels lie millimetres apart, so the track's
error, however large, puts one phase on all of them: the pulse's channel cross-products ``z z^H`` hold the channels'
own gains, and summed over the point's pulses they make its (C, C) cross-spectral matrix. A point scatterer's is of
rank one, its eigenvector the gains.

Not every bright point is one: a scatterer seen over part of its aperture, or whose echo turns with the look angle,
adds a phase ramp along the virtual array. So the gains are those of the largest set of points whose own
eigenvectors (coherence ``>= min_coherence``) agree within ``agree_deg`` RMS, from the normalised sum of their
matrices. The std of each channel's phase and gain is the spread of those points' own over their number.

Applied only where the mismatch with what is assumed (matched channels, or the calibration a TI capture states)
matters: its phase RMS of ``min_phase_rms_deg`` beyond a ramp along the array (which points crossing the beam alike
show too: along-track interferometry), or its gain RMS of ``min_gain_rms_db``. Matched channels measure
well under both (docs/FOCUS.md), and a mismatch below them costs the image's peak under 0.2 dB.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from autosar_cli.config import Config
from autosar_cli.sar.channel_gains import ChannelGains, normalised, stated_channel_gains
from autosar_cli.sar.focus import FocusOptions, channel_pairs
from autosar_cli.sar.phase_history import (
    PhaseHistories,
    focus_history,
    frame_geometry,
    gather_phase_histories,
    pair_antennas,
)
from autosar_cli.store.drive import Drive
from autosar_cli.types import Trajectory

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ChannelCalibrationOptions:
    half_beam_deg: float = 10.0  #: each point's pulses within this of broadside
    window_bins: int = 8  #: range bins kept around each pulse's expected range
    #: the frames read, runs of ``run`` in every ``period`` (:func:`~autosar_cli.sar.phase_history.
    #: gather_phase_histories`): a pulse's cross-products need no neighbour, and one chunk of the raw cube (64
    #: frames) in four reads a quarter of it (test2 seed 1: 0.7 s for every fourth frame, which reads it all)
    frame_runs: tuple[int, int] = (64, 256)
    min_coherence: float = 0.9  #: a point's largest eigenvalue's share of its matrix's trace
    agree_deg: float = 15.0  #: points whose gains agree within this RMS phase (deg) form one set
    min_points: int = 2  #: fewer agreeing points: not measured
    min_phase_rms_deg: float = 10.0  #: applied where the measured phases' RMS reaches this
    min_gain_rms_db: float = 1.0  #: or the measured gains' RMS (dB) this


@dataclass
class ChannelCalibration:
    """What :func:`measure_channel_gains` found: the gains, whether they are applied, and why (not)."""

    gains: ChannelGains | None  #: the measured gains (None: not measured)
    applied: bool
    reason: str
    points: int = 0  #: candidate points
    points_used: int = 0  #: the agreeing set's
    #: the measured phases' RMS about their mean, and the gains' RMS, against those assumed (matched channels, or
    #: those the drive states)
    phase_rms_deg: float = float("nan")
    gain_rms_db: float = float("nan")
    phase_std_deg: float = float("nan")  #: median over channels of each phase's std
    gain_std_db: float = float("nan")
    peak_loss_db: float = float("nan")  #: what that mismatch costs a point's peak, channels summed
    #: the phases' RMS beyond their ramp along the array, and that ramp end to end (deg)
    phase_beyond_ramp_rms_deg: float = float("nan")
    ramp_deg: float = float("nan")

    def to_dict(self) -> dict[str, Any]:
        def num(v: float, nd: int) -> float | None:
            return None if not np.isfinite(v) else round(float(v), nd)

        return {"applied": self.applied, "reason": self.reason,
                "gains": self.gains.to_dict() if self.gains is not None else None,
                "points": self.points, "points_used": self.points_used,
                "phase_rms_deg": num(self.phase_rms_deg, 2), "gain_rms_db": num(self.gain_rms_db, 3),
                "phase_std_deg": num(self.phase_std_deg, 2), "gain_std_db": num(self.gain_std_db, 3),
                "peak_loss_db": num(self.peak_loss_db, 3),
                "phase_beyond_ramp_rms_deg": num(self.phase_beyond_ramp_rms_deg, 2), "ramp_deg": num(self.ramp_deg, 1)}

    def summary(self) -> str:
        if self.gains is None:
            return f"channel gains not measured: {self.reason}"
        what = "undone" if self.applied else "left as they are"
        return (f"channel gains {what}: phases {self.phase_rms_deg:.1f} deg RMS (±{self.phase_std_deg:.1f}), "
                f"gains {self.gain_rms_db:.2f} dB RMS (±{self.gain_std_db:.2f}), costing {self.peak_loss_db:.2f} dB "
                f"of peak; from {self.points_used} of {self.points} points{'' if self.applied else ': ' + self.reason}")


def cross_spectra(z: NDArray[np.complexfloating], point: NDArray[np.int64], n_points: int) -> NDArray[np.complex128]:
    """Per point (P, C, C): the sum over its pulses of ``z z^H``, ``z`` (N, C) each pulse's channel values
    (pulses with any NaN left out)."""
    ok = np.all(np.isfinite(z), axis=1)
    out = np.zeros((n_points, z.shape[1], z.shape[1]), np.complex128)
    np.add.at(out, point[ok], z[ok][:, :, None] * np.conj(z[ok][:, None, :]))
    return out


def gains_from_spectra(spectra: NDArray[np.complex128], opts: ChannelCalibrationOptions
                       ) -> tuple[NDArray[np.complex128] | None, NDArray[np.bool_], NDArray[np.complex128]]:
    """The channels' complex gains (C,) from the points' cross-spectral matrices (P, C, C) (None where fewer than
    ``opts.min_points`` agree), the points used (P,), and each point's own normalised gains (P, C)."""
    n = len(spectra)
    trace = np.einsum("pcc->p", spectra).real
    own = np.zeros((n, spectra.shape[1]), np.complex128)
    coherence = np.zeros(n)
    for p in range(n):
        if trace[p] <= 0:
            continue
        w, v = np.linalg.eigh(spectra[p])
        coherence[p], own[p] = w[-1] / trace[p], normalised(v[:, -1])
    candidates = np.flatnonzero(coherence >= opts.min_coherence)
    if len(candidates) < opts.min_points:
        return None, np.zeros(n, bool), own
    # pairwise RMS phase between the points' gains; the largest agreeing set (ties: the most coherent seed)
    rel = own[candidates][:, None, :] * np.conj(own[candidates][None, :, :])
    rms = np.degrees(np.sqrt(np.mean(np.angle(rel) ** 2, axis=-1)))
    agree = rms <= opts.agree_deg
    seed = max(range(len(candidates)), key=lambda i: (agree[i].sum(), coherence[candidates[i]]))
    used = np.zeros(n, bool)
    used[candidates[agree[seed]]] = True
    if used.sum() < opts.min_points:
        return None, used, own
    total = np.sum(spectra[used] / trace[used, None, None], axis=0)
    return normalised(np.linalg.eigh(total)[1][:, -1]), used, own


def with_stated_gains(drive_path: str | Path, focus: FocusOptions) -> FocusOptions:
    """``focus`` with the channel gains its drive's radar states, where it gives none itself."""
    if focus.channel_gains is not None:
        return focus
    with Drive(drive_path) as drive:
        return replace(focus, channel_gains=stated_channel_gains(drive.radar(focus.radar).attrs))


def measure_channel_gains(drive_path: str | Path, trajectory: Trajectory, config: Config, points_enu: Array,
                          focus: FocusOptions, opts: ChannelCalibrationOptions | None = None) -> ChannelCalibration:
    """The radar's channel gains from ``points_enu`` (P, 3) (ENU m: the autofocus's candidate points) along
    ``trajectory`` (module docstring), applied where they differ from ``focus.channel_gains`` (the gains the drive
    states, :func:`with_stated_gains`; None: matched channels) beyond the options' limits."""
    opts = opts or ChannelCalibrationOptions()
    points = np.asarray(points_enu, dtype=np.float64).reshape(-1, 3)
    with Drive(drive_path) as drive:
        n_tx, n_rx = (int(v) for v in drive.radar(focus.radar).raw.shape[1:3])
    pairs = channel_pairs(n_tx, n_rx, focus.channels)  # those the image sums
    if len(points) < opts.min_points or len(pairs) < 2:
        return ChannelCalibration(None, False, f"{len(points)} candidate point(s), {len(pairs)} channel(s)",
                                  len(points))
    hist = gather_phase_histories(drive_path, trajectory, config, points, replace(focus, channel_gains=None),
                                  half_beam_deg=opts.half_beam_deg, window_bins=opts.window_bins,
                                  channels=focus.channels, pairs=pairs, frame_runs=opts.frame_runs)
    tx, rx = pair_antennas(hist, trajectory, config)
    z = np.stack([focus_history(hist, tx, rx, points, channels=slice(c, c + 1))[0] for c in range(len(pairs))],
                 axis=1)
    spectra = cross_spectra(z, hist.point, len(points))
    g, used, own = gains_from_spectra(spectra, opts)
    if g is None:
        return ChannelCalibration(None, False, f"fewer than {opts.min_points} point scatterers agree on them",
                                  len(points), int(used.sum()))
    grid, measured = np.ones((n_tx, n_rx), np.complex128), np.zeros((n_tx, n_rx), bool)
    for (t, r), v in zip(pairs, g, strict=True):
        grid[t, r], measured[t, r] = v, True
    gains = ChannelGains.from_complex(grid, measured)
    # against what the reads assume: the gains the drive states (or given), else matched channels
    assumed = np.ones(len(pairs)) if focus.channel_gains is None else 1.0 / focus.channel_gains.correction(pairs)
    rel = normalised(g / assumed)
    phase, level = np.angle(rel), 20 * np.log10(np.abs(rel))
    dev = own[used] / g[None, :]
    k = max(1, int(used.sum()) - 1)
    phase_std = float(np.degrees(np.median(np.sqrt(np.sum(np.angle(dev) ** 2, axis=0) / k / used.sum()))))
    gain_std = float(np.median(np.sqrt(np.sum((20 * np.log10(np.abs(dev))) ** 2, axis=0) / k / used.sum())))
    phase_rms, gain_rms = float(np.degrees(np.sqrt(np.mean(phase**2)))), float(np.sqrt(np.mean(level**2)))
    loss = float(-10 * np.log10(np.abs(np.sum(rel)) ** 2 / (len(rel) * np.sum(np.abs(rel) ** 2))))
    # a phase linear along the array is also what points moving across the beam alike show (along-track
    # interferometry): what the points measure of the channels is the rest
    x = along_track_positions(hist, tx, rx, trajectory, config)
    design = np.column_stack([np.ones_like(x), x])
    ramp = design @ np.linalg.lstsq(design, phase, rcond=None)[0]
    rest_rms = float(np.degrees(np.sqrt(np.mean((phase - ramp) ** 2))))
    ramp_deg = float(np.degrees(ramp[np.argmax(x)] - ramp[np.argmin(x)]))
    applied = rest_rms >= opts.min_phase_rms_deg or gain_rms >= opts.min_gain_rms_db
    assumed_text = "the channels as matched" if focus.channel_gains is None else \
        "the gains the drive states: those kept"
    reason = "" if applied else (
        f"a phase ramp along the array alone ({ramp_deg:+.0f} deg end to end), which points that cross the beam alike "
        f"show as well: {assumed_text}" if phase_rms >= opts.min_phase_rms_deg else
        f"under {opts.min_phase_rms_deg:g} deg and {opts.min_gain_rms_db:g} dB RMS from {assumed_text}")
    return ChannelCalibration(gains, applied, reason, len(points), int(used.sum()), phase_rms, gain_rms, phase_std,
                              gain_std, loss, rest_rms, ramp_deg)


def along_track_positions(hist: PhaseHistories, tx: Array, rx: Array, trajectory: Trajectory, config: Config
                          ) -> Array:
    """Each channel's bistatic midpoint along the track (C,) (m, about the channels' mean), from ``tx``, ``rx``
    (N, C, 3) (ENU m, :func:`~autosar_cli.sar.phase_history.pair_antennas`), averaged over the pulses."""
    along = frame_geometry(trajectory, hist.frame_t_ns, config)[2][hist.frame]  # (N, 3)
    mid = 0.5 * (tx + rx)
    return np.mean(np.einsum("nck,nk->nc", mid - mid.mean(axis=1, keepdims=True), along), axis=0)
