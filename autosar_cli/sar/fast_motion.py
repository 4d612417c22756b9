"""The radar's fast across-track motion from many scatterers: what the residual-motion autofocus's few points miss.

The residual-motion autofocus (:mod:`autosar_cli.sar.residual_motion`) fits a few bright, isolated points 3-16 m
from the track. On a rough road they see part of the drive (test1 seed 0: 61 % of its frames), and the far swath's
focus needs the across-track motion above 0.5 Hz where they do not (``benches/bench_af_oracle.py``). This stage
takes it, above ``cut_hz``, from many scatterers over the whole swath, after that autofocus and along its track:

* the scatterers: local maxima of the autofocus's first image out to the radar's range, two per 1.5 m of
  travel in each of its bands, within 25 dB of the most reflective, holding 10 % of their 7 x 7 neighbourhood
  (:func:`~autosar_cli.sar.point_selection.select_points` with looser limits);
* each one's history over +-28 deg (two channels, :mod:`autosar_cli.sar.phase_history`), low-passed along the
  pulses (31-pulse Hann) and taken every 10 pulses. A pulse's range sample holds every scatterer at that range in
  the real beam; for a point on a wall, the wall's mirror image about broadside is one, at twice the point's
  Doppler, so samples where that Doppler aliases to within 80 Hz of the point's own are left out;
* the phase steps of each history, less their own average over 0.6 s (a column's scatterers interfere slowly as
  the aspect turns: each keeps its own slow phase), fitted by a correction across track on 10 ms nodes (a prior of
  0.3 mm, and 1 mm on each node's change), each history weighted by its own residual and dropped above 0.5 rad RMS.
  The fit's part above ``cut_hz`` is the correction. The scatterers are also fitted in two halves: where those
  disagree (correlation ``r`` <= 0) nothing is corrected, else ``r`` and the whole fit's reliability
  ``2 r / (1 + r)``, the share of its variance the halves agree on, are reported (``apply_reliability`` scales the
  correction by it: nearer the radar's own motion, but the far swath blurrier; docs/AUTOFOCUS.md). Each history's
  normal equations are formed once in band form (:mod:`autosar_cli.sar.step_normals`) and shared by the three fits
  and their reweighting passes.

Unlike the few points' fit, this one cannot tell a point's own motion from the track's at low frequencies: each
history's slow phase is taken out, so it measures only the fast part, where the many histories agree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from autosar_cli.config import Config
from autosar_cli.sar.normal_equations import BandedCholesky, node_difference, node_posterior_std
from autosar_cli.sar.phase_history import PhaseHistories, focus_history, frame_geometry, pair_antennas
from autosar_cli.sar.step_normals import (
    HistoryNormals,
    add_normals,
    apply_model,
    history_normals,
    remove_moving_average,
)
from autosar_cli.types import MotionCorrection, Trajectory

Array = NDArray[np.float64]


@dataclass(frozen=True)
class FastMotionOptions:
    """Parameters of the fast-motion stage (their reasons: the module's docstring and docs/AUTOFOCUS.md)."""

    cut_hz: float = 2.0  #: the correction's part above this is applied (below it, the few points' fit holds)
    half_beam_deg: float = 28.0  #: half-width of the beam over which each scatterer's history is taken
    channels: int = 2  #: channels of the histories (sar.focus.channel_pairs)
    #: range bins kept around each pulse's path (read along the track they are focused along: the two that the
    #: interpolation takes, and one either side)
    window_bins: int = 4
    #: scatterers per ``point_spacing_m`` of travel and band (3-12 m, 12 m to the radar's range; the autofocus's
    #: spacing and bands): on test1 s0 / test2 s1 / test3 s1 the far swath ended −0.34 / +0.10 / −0.76 % from the
    #: truth's with 2, −0.59 / +0.08 / −0.73 % with 4, which took 1.7 s against 1.2 (in process, test2)
    per_segment: int = 2
    min_concentration: float = 0.1  #: share of its 7 x 7 neighbourhood's intensity a scatterer holds
    within_db: float = 25.0  #: scatterers within this of the most reflective
    taps: int = 31  #: Hann low-pass along the pulses of each history
    every: int = 10  #: pulses between the low-passed samples whose phase steps are fitted
    alias_hz: float = 80.0  #: samples whose mirror image's Doppler aliases to within this of their own: left out
    window_s: float = 0.6  #: span of each history's own slow phase step taken out
    node_s: float = 0.01  #: spacing of the correction's nodes (s)
    prior_m: float = 3e-4  #: prior std of the correction
    step_m: float = 1e-3  #: prior std of its change from one node to the next
    max_rms_rad: float = 0.5  #: histories fitting worse than this are dropped
    #: and, before the fit, those whose phase steps (less their slow part) scatter by more than this (test2 seed 1:
    #: the 107 that fit scatter by 0.03-0.6 rad, half of the 327 by 1.2-1.9, near a random phase's 1.8)
    screen_rms_rad: float = 1.0
    min_histories: int = 3  #: fewer histories fitting: no correction
    iterations: int = 5  #: reweighting passes at most
    #: scale the correction by its halves' reliability: nearer the radar's own fast motion (on five drives, in both
    #: bands, than the track's), but the far swath within 0.2 % of the truth's on 22 of the 40, at most 0.2 % above
    #: on 31 (the whole fit: 22 and 39; docs/AUTOFOCUS.md)
    apply_reliability: bool = False


@dataclass
class FastMotion:
    """Result of :func:`fast_motion`."""

    correction: MotionCorrection | None  #: the across-track correction above ``cut_hz`` (ENU m), None where refused
    histories: int  #: histories fitted (one per scatterer's unbroken run of pulses)
    histories_used: int  #: those that fit
    coverage: float  #: fraction of the nodes their samples span
    reason: str = ""
    seen: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))  #: (M,) the nodes covered
    halves_correlation: float = 0.0  #: the two halves' correlation above ``cut_hz`` (:func:`fast_motion`)
    reliability: float = 0.0  #: the whole fit's, 2 r / (1 + r) (its gain where ``apply_reliability``)

    @property
    def applied(self) -> bool:
        return self.correction is not None

    def correction_rms_mm(self) -> float:
        c = self.correction
        return 0.0 if c is None else float(1e3 * np.sqrt(np.mean(np.sum(c.offset_enu**2, axis=1))))

    def to_dict(self) -> dict[str, object]:
        return {"applied": self.applied, "reason": self.reason, "histories": self.histories,
                "histories_used": self.histories_used, "coverage": round(self.coverage, 4),
                "halves_correlation": round(self.halves_correlation, 4), "reliability": round(self.reliability, 4),
                "correction_rms_mm": round(self.correction_rms_mm(), 4)}

    def summary(self) -> str:
        if not self.applied:
            return f"fast motion not corrected: {self.reason}"
        return (f"fast motion corrected by {self.correction_rms_mm():.3f} mm RMS from {self.histories_used} of "
                f"{self.histories} scatterer histories seen over {100 * self.coverage:.0f} % of the drive (their "
                f"halves' correlation {self.halves_correlation:.2f}, its reliability {self.reliability:.2f})")


@dataclass
class HistorySteps:
    """The phase steps :func:`fast_motion` fits: step m between the samples at times ``t[m]`` (s from the track's
    start) of history ``segment[m]``, whose lines of sight's across-track components are ``gain[m]``."""

    t: Array  #: (M, 2) s
    step: Array  #: (M,) rad
    gain: Array  #: (M, 2)
    segment: NDArray[np.int64]  #: (M,)
    runs: list[NDArray[np.int64]]  #: each history's pairs (indices into the histories), in pulse order
    prf_hz: float  #: the frames' rate

    @property
    def n_histories(self) -> int:
        return len(self.runs)


def history_steps(hist: PhaseHistories, z: NDArray[np.complex128], los: Array, track: Trajectory, config: Config,
                  opts: FastMotionOptions) -> HistorySteps:
    """The low-passed phase steps of every scatterer's unbroken runs of pulses (the module's docstring) from its
    back-projected values ``z`` (N,) and lines of sight ``los`` (N, 3) (:func:`focus_history` along ``track``)."""
    from scipy.ndimage import convolve1d

    t_f = (hist.frame_t_ns - int(track.t_ns[0])) / 1e9
    prf = 1.0 / float(np.median(np.diff(t_f)))
    speed = np.interp(hist.frame_t_ns, track.t_ns, np.abs(track.speed))
    _, f_across, f_along = frame_geometry(track, hist.frame_t_ns, config)
    taper = np.hanning(opts.taps + 2)[1:-1]
    taper /= taper.sum()
    # every (point, frame) pair in point then frame order; a run: one point's unbroken frames
    order = np.lexsort((hist.frame, hist.point))
    point, frame = hist.point[order], hist.frame[order]
    run_start = np.flatnonzero(np.r_[True, (np.diff(point) != 0) | (np.diff(frame) != 1)])
    run_len = np.diff(np.r_[run_start, len(order)])
    long = run_len >= 3 * opts.taps
    run_start, run_len = run_start[long], run_len[long]
    # the low-passed samples kept: taps on from each run's start, every ``every``, ending taps before its end, so
    # each one's taps lie within its run (low-passing all runs together gives each the same sums)
    per_run = (run_len - 2 * opts.taps + opts.every - 1) // opts.every
    run_of = np.repeat(np.arange(len(run_start)), per_run)
    keep = run_start[run_of] + opts.taps + opts.every * (np.arange(len(run_of)) - np.repeat(
        np.cumsum(per_run) - per_run, per_run))
    zs = np.nan_to_num(z[order])
    low = (convolve1d(zs.real, taper, mode="constant") + 1j * convolve1d(zs.imag, taper, mode="constant"))[keep]
    f, u = frame[keep], los[order[keep]]
    mirror = 4.0 * speed[f] * np.einsum("nk,nk->n", u, f_along[f]) * hist.cycles_per_m
    alias = np.abs((mirror + prf / 2) % prf - prf / 2)
    ok = (alias > opts.alias_hz) | (np.abs(mirror) < opts.alias_hz / 4)
    a = np.flatnonzero(ok[1:] & ok[:-1] & (run_of[1:] == run_of[:-1]))
    # runs with fewer than 5 steps left out; the rest numbered in order
    fitted = np.bincount(run_of[a], minlength=len(run_start)) >= 5
    a = a[fitted[run_of[a]]]
    if len(a) == 0:
        return HistorySteps(np.zeros((0, 2)), np.zeros(0), np.zeros((0, 2)), np.zeros(0, np.int64), [], prf)
    g = np.einsum("nk,nk->n", u, f_across[f])
    segment = (np.cumsum(fitted) - 1)[run_of[a]]
    runs = [order[start:start + n] for start, n in zip(run_start[fitted], run_len[fitted], strict=True)]
    return HistorySteps(np.stack([t_f[f][a], t_f[f][a + 1]], -1), np.angle(low[a + 1] * np.conj(low[a])),
                        np.stack([g[a], g[a + 1]], -1), segment.astype(np.int64), runs, prf)


def step_columns(t: Array, gain: Array, n_nodes: int, node_s: float, kappa: float) -> tuple[NDArray[np.int64], Array]:
    """Each phase step's change with the motion ``e`` on the nodes (linear between them), as ``step = kappa (g_b
    e(t_b) - g_a e(t_a))`` for the samples a, b at times ``t`` (M, 2) (s) and gains ``gain``: the nodes (M, 4) and
    rad per m (M, 4) of its four entries."""
    cols, vals = [], []
    for end, sign in ((0, -1.0), (1, 1.0)):
        pos = np.clip(t[:, end] / node_s, 0.0, n_nodes - 1.000001)
        n0 = np.floor(pos).astype(np.int64)
        cols += [n0, n0 + 1]
        vals += [sign * kappa * gain[:, end] * (1 - (pos - n0)), sign * kappa * gain[:, end] * (pos - n0)]
    return np.stack(cols, axis=1), np.stack(vals, axis=1)


def step_design(t: Array, gain: Array, n_nodes: int, node_s: float, kappa: float) -> sp.csr_matrix:
    """(M, n_nodes) sparse, :func:`step_columns`' entries as a matrix."""
    cols, vals = step_columns(t, gain, n_nodes, node_s, kappa)
    return sp.csr_matrix((vals.ravel(), (np.repeat(np.arange(len(t)), 4), cols.ravel())), shape=(len(t), n_nodes))


def moving_average_removal(segment: NDArray[np.int64], half: int) -> sp.csr_matrix:
    """Sparse (M, M): each sample less the mean of the samples of its ``segment`` within ``half`` of it."""
    m = len(segment)
    starts = np.flatnonzero(np.r_[True, segment[1:] != segment[:-1]])
    first = np.repeat(starts, np.diff(np.r_[starts, m]))
    last = np.repeat(np.r_[starts[1:], m], np.diff(np.r_[starts, m]))
    idx = np.arange(m)
    lo, hi = np.maximum(idx - half, first), np.minimum(idx + half + 1, last)
    count = hi - lo
    rows = np.repeat(idx, count)
    cols = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count) + np.repeat(lo, count)
    average = sp.csr_matrix((np.repeat(1.0 / count, count), (rows, cols)), shape=(m, m))
    return sp.identity(m, format="csr") - average


def node_prior(n_nodes: int, prior_m: float, step_m: float) -> sp.csc_matrix:
    """(n, n) the inverse covariance of a correction on ``n_nodes`` nodes: ``prior_m`` on each, ``step_m`` on each
    change between neighbours."""
    change = node_difference(n_nodes)
    return (sp.identity(n_nodes) / prior_m**2 + change.T @ change / step_m**2).tocsc()


def closest_approach_ns(track_xy: Array, t_ns: NDArray[np.int64], points_enu: Array) -> NDArray[np.int64]:
    """For each point (P, 3) (ENU m), the time (ns) of the sample of ``track_xy`` (K, 2) (ENU m, at ``t_ns``) nearest
    it: its closest approach to the nearest sample (the slow quantities moved by it change little over a sample)."""
    from scipy.spatial import cKDTree

    points = np.asarray(points_enu, dtype=np.float64).reshape(-1, 3)
    return np.asarray(t_ns, dtype=np.int64)[cKDTree(track_xy).query(points[:, :2])[1]]


def fast_motion(hist: PhaseHistories, track: Trajectory, config: Config, points_enu: Array,
                opts: FastMotionOptions | None = None) -> FastMotion:
    """The across-track correction of ``track`` above ``opts.cut_hz`` that the histories ``hist`` of the
    scatterers ``points_enu`` (P, 3) (ENU m, where ``track`` focuses them) measure (the module's docstring), read
    along ``track`` (:func:`~autosar_cli.sar.phase_history.gather_phase_histories` with ``opts``' beam, window and
    channels).

    The scatterers are fitted in two halves (even and odd), each on its own, and all together; the correction is the
    whole fit's. Where the halves disagree (``r`` <= 0, their correlation above ``cut_hz`` where both see) nothing is
    corrected. Its reliability ``2 r / (1 + r)`` (Spearman-Brown's, of twice a half's data: the share of its variance
    that the halves agree on) is reported, and with ``opts.apply_reliability`` scales the correction: the gain that
    leaves the least error against what the halves agree on."""
    from scipy.signal import butter, sosfiltfilt

    opts = opts or FastMotionOptions()
    points = np.asarray(points_enu, dtype=np.float64).reshape(-1, 3)
    t0 = int(track.t_ns[0])
    n_nodes = int(math.ceil((int(track.t_ns[-1]) - t0) / 1e9 / opts.node_s)) + 1
    nodes_ns = t0 + np.round(np.arange(n_nodes) * opts.node_s * 1e9).astype(np.int64)
    z, los = focus_history(hist, *pair_antennas(hist, track, config), points)
    hs = history_steps(hist, z, los, track, config, opts)
    parity = np.array([hist.point[run[0]] % 2 for run in hs.runs], dtype=np.int64)
    problem = _StepProblem.of(hs, n_nodes, 4.0 * math.pi * hist.cycles_per_m, opts)
    fits = [_fit_histories(problem, parity == half, opts) for half in (0, 1)]
    used = sum(int(f.used.sum()) for f in fits)
    seen = np.zeros(n_nodes, dtype=bool)
    for f in fits:
        seen |= f.seen
    short = [int(f.used.sum()) for f in fits if f.used.sum() < opts.min_histories]
    if short:
        return FastMotion(None, hs.n_histories, used, float(seen.mean()),
                          f"{min(short)} scatterer histories fit within {opts.max_rms_rad:g} rad RMS in one of its two "
                          f"halves, fewer than {opts.min_histories}", seen=seen)
    sos = butter(4, opts.cut_hz, "highpass", fs=1.0 / opts.node_s, output="sos")
    high = [-sosfiltfilt(sos, f.motion) for f in fits]
    both = fits[0].seen & fits[1].seen
    r = float(np.corrcoef(high[0][both], high[1][both])[0, 1]) if both.sum() > 2 else 0.0
    if not r > 0.0:
        return FastMotion(None, hs.n_histories, used, float(seen.mean()),
                          f"the two halves of its scatterers disagree (correlation {r:.2f} above {opts.cut_hz:g} Hz)",
                          seen=seen, halves_correlation=r)
    reliability = 2.0 * r / (1.0 + r)
    gain = reliability if opts.apply_reliability else 1.0
    whole = _fit_histories(problem, np.ones(hs.n_histories, dtype=bool), opts)
    _, across, _ = frame_geometry(track, nodes_ns, config)
    correction = MotionCorrection(nodes_ns, (-gain * sosfiltfilt(sos, whole.motion))[:, None] * across,
                                  (gain * whole.std)[:, None] * np.abs(across))
    return FastMotion(correction, hs.n_histories, int(whole.used.sum()), float(whole.seen.mean()), seen=whole.seen,
                      halves_correlation=r, reliability=reliability)


@dataclass
class _HistoryFit:
    """One set of histories' fit (:func:`_fit_histories`): the motion ``e`` on the nodes (m; the correction
    undoes it), its posterior std, the histories that fit and the nodes their samples span."""

    motion: Array
    std: Array
    used: NDArray[np.bool_]
    seen: NDArray[np.bool_]


@dataclass
class _StepProblem:
    """What every fit of one set of histories shares: the steps' model (:func:`step_columns`), the steps less their
    moving average, each history's normal equations (:mod:`autosar_cli.sar.step_normals`) and the prior's band."""

    hs: HistorySteps
    n_nodes: int
    cols: NDArray[np.int64]  #: (M, 4)
    vals: Array  #: (M, 4) rad per m
    starts: NDArray[np.int64]  #: (S + 1,) each history's first step
    half: int  #: steps either side in the moving average
    data: Array  #: (M,) rad
    normals: HistoryNormals
    prior_band: Array  #: (bandwidth + 1, n_nodes)

    @classmethod
    def of(cls, hs: HistorySteps, n_nodes: int, kappa: float, opts: FastMotionOptions) -> _StepProblem:
        half = max(1, int(round(0.5 * opts.window_s * hs.prf_hz / opts.every)))
        starts = np.searchsorted(hs.segment, np.arange(hs.n_histories + 1)).astype(np.int64)
        cols, vals = step_columns(hs.t, hs.gain, n_nodes, opts.node_s, kappa)
        data = remove_moving_average(hs.step, starts, half)
        normals = history_normals(cols, vals, data, starts, half)
        prior = np.zeros((max(normals.bandwidth, 1) + 1, n_nodes))
        tridiagonal = node_prior(n_nodes, opts.prior_m, opts.step_m)
        prior[0], prior[1, :-1] = tridiagonal.diagonal(), tridiagonal.diagonal(-1)
        return cls(hs, n_nodes, cols, vals, starts, half, data, normals, prior)

    def factor(self, weight: Array) -> tuple[BandedCholesky, Array]:
        """The factorised normal matrix and right-hand side of the histories weighted by ``weight`` (S,)."""
        added, rhs = add_normals(self.normals, weight, self.n_nodes)
        band = self.prior_band.copy()
        band[:len(added)] += added
        return BandedCholesky(band), rhs


def _fit_histories(problem: _StepProblem, chosen: NDArray[np.bool_], opts: FastMotionOptions) -> _HistoryFit:
    """The motion the ``chosen`` histories (n_histories,) of ``problem`` measure: each history's phase steps less
    their slow part, those that scatter by more than ``opts.screen_rms_rad`` left out, the rest fitted on the nodes,
    reweighted by each one's residual and dropped above ``opts.max_rms_rad``."""
    hs, n_nodes, data = problem.hs, problem.n_nodes, problem.data
    n_seg = hs.n_histories
    counts = np.maximum(np.diff(problem.starts), 1)
    # a history whose phase steps scatter by more than ``screen_rms_rad`` before any fit cannot fit within
    # ``max_rms_rad`` (the motion moves them by ~0.2 rad RMS): left out of the fit
    rms = np.sqrt(np.bincount(hs.segment, data**2, n_seg) / counts)
    used = chosen & (rms <= opts.screen_rms_rad)
    var = np.full(n_seg, 0.3**2)
    e, chol = np.zeros(n_nodes), None
    for _ in range(opts.iterations):
        if not used.any():
            break
        chol, rhs = problem.factor(used / var)
        e = chol.solve(rhs)
        r = data - apply_model(problem.cols, problem.vals, problem.starts, problem.half, e)
        rms = np.sqrt(np.bincount(hs.segment, r**2, n_seg) / counts)
        var = np.maximum(rms, 0.02) ** 2
        bad = used & (rms > opts.max_rms_rad)
        if not bad.any():
            break
        used &= ~bad
        chol = None
    if chol is None and used.any():  # the last pass dropped some: the solution without them
        chol, rhs = problem.factor(used / var)
        e = chol.solve(rhs)
    seen = np.zeros(n_nodes, dtype=bool)
    # each history's steps in time order: its first and last sample times
    first, last = hs.t[problem.starts[:-1], 0], hs.t[problem.starts[1:] - 1, 0]
    for s in np.flatnonzero(used):  # the nodes each used history's samples span
        seen[int(first[s] / opts.node_s):int(last[s] / opts.node_s) + 1] = True
    std = node_posterior_std(chol, n_nodes, 1, every=50)[:, 0] if chol is not None else np.full(n_nodes, opts.prior_m)
    return _HistoryFit(e, std, used, seen)
