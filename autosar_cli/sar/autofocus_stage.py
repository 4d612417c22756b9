"""The autofocus stage between navigation and focusing (``autosar run --autofocus``, compare's ``METHOD+af``): its
steps in order, each in its own module.

1. the points: a coarse first image's bright isolated scatterers (:mod:`autosar_cli.sar.point_selection`);
2. the radar's channel gains on them (:mod:`autosar_cli.sar.channel_calibration`);
3. the slow motion from their ranges over their whole passes (:mod:`autosar_cli.sar.pass_ranges`), the radar's
   clock read again where the passes show it late (:func:`radar_clock_rereads`);
4. the residual motion and the track's scale from their phases (:mod:`autosar_cli.sar.residual_motion`); a point
   whose channels say it moves is left out and the rest fitted again, and where every point moves alike, the
   radar's boresight is tried (:func:`autofocus_residual_motion`);
5. where asked, the fast motion from many scatterers (:mod:`autosar_cli.sar.fast_motion`).

Where a step cannot measure, the track stays as it was and the result says why (docs/AUTOFOCUS.md).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from autosar_cli.config import Config
from autosar_cli.nav.trajectory import phase_centre_lever_arm, with_mounting_yaw
from autosar_cli.sar.channel_calibration import measure_channel_gains, with_stated_gains
from autosar_cli.sar.fast_motion import FastMotion, FastMotionOptions, closest_approach_ns, fast_motion
from autosar_cli.sar.focus import FocusOptions
from autosar_cli.sar.pass_ranges import PassOptions, SlowMotion, estimate_slow_motion, pass_histories, with_correction
from autosar_cli.sar.phase_history import (
    PhaseHistories,
    channel_phase,
    gather_phase_histories,
    histories_of,
    narrow_histories,
    pair_antennas,
)
from autosar_cli.sar.point_selection import points_and_scatterers
from autosar_cli.sar.residual_motion import (
    MAX_MOUNTING_YAW_DEG,
    NARROWING_SLACK_BINS,
    AutofocusOptions,
    ResidualMotion,
    estimate_residual_motion,
)
from autosar_cli.types import Trajectory

Array = NDArray[np.float64]


def autofocus_residual_motion(drive_path: str | Path, trajectory: Trajectory, config: Config,
                              focus: FocusOptions | None = None, opts: AutofocusOptions | None = None,
                              passes: PassOptions | None = None, fast: FastMotionOptions | None = None
                              ) -> ResidualMotion:
    """``trajectory`` corrected by the residual motion its own image's bright points
    (:func:`~autosar_cli.sar.point_selection.candidate_points`) measure, with no truth
    (:func:`residual_motion_of_points`), then, unless ``opts.fast_motion`` is off, by the fast across-track motion
    that many scatterers measure along that track (:mod:`autosar_cli.sar.fast_motion`; ``fast``: its options).

    Where that refuses because every point it used crossed the beam alike, at a phase a radar boresight within
    ``MAX_MOUNTING_YAW_DEG`` of the stated would give (``moving_mounting_yaw_deg``), it runs once more along that
    boresight, and keeps that run where its points fit as still ones (``radar_mounting_yaw_deg``)."""
    result = _autofocus_along(drive_path, trajectory, config, focus, opts, passes, fast)
    yaw = result.moving_mounting_yaw_deg
    if result.applied or yaw is None or abs(yaw) > MAX_MOUNTING_YAW_DEG:
        return result
    boresight = config.radar.mounting.yaw_deg + yaw
    turned = _autofocus_along(drive_path, trajectory, with_mounting_yaw(config, boresight), focus, opts, passes,
                              fast)
    return replace(turned, radar_mounting_yaw_deg=boresight) if turned.applied else result


def _autofocus_along(drive_path: str | Path, trajectory: Trajectory, config: Config, focus: FocusOptions | None,
                     opts: AutofocusOptions | None, passes: PassOptions | None, fast: FastMotionOptions | None
                     ) -> ResidualMotion:
    """:func:`autofocus_residual_motion` along the radar mounting ``config`` states."""
    focus = with_stated_gains(drive_path, focus or FocusOptions.from_config(config))
    opts = opts or AutofocusOptions.from_config(config)
    passes = passes or PassOptions.from_config(config)
    fast = (fast or FastMotionOptions()) if opts.fast_motion else None
    points, scatterers, t_zero = points_and_scatterers(drive_path, trajectory, config, focus, opts, fast)
    calibration = measure_channel_gains(drive_path, trajectory, config, points, focus) if opts.channel_gains \
        else None
    if calibration is not None and calibration.applied:  # every read from here on undoes them
        focus = replace(focus, channel_gains=calibration.gains)
    result = replace(residual_motion_of_points(drive_path, trajectory, config, points, focus, opts, passes),
                     channel_calibration=calibration)
    late_s, reads = radar_clock_rereads(drive_path, trajectory, config, points, focus, passes,
                                        result.slow_motion)
    result = replace(result, radar_clock_reads=reads)
    if late_s:  # the motion along the track on the radar's clock, its points where that track puts them
        on_clock = trajectory.on_radar_clock(int(round(late_s * 1e9)))
        result = replace(residual_motion_of_points(drive_path, on_clock, config,
                                                   _moved(points, trajectory, on_clock, config), focus, opts,
                                                   passes),
                         channel_calibration=calibration, radar_clock_offset_s=late_s, radar_clock_reads=reads)
    if fast is None or not result.applied:
        return result
    if len(scatterers) == 0:
        return replace(result, fast_motion=FastMotion(None, 0, 0, 0.0, "no bright scatterer in the first image"))
    # each scatterer where the corrected track focuses it
    moved = moved_with_track(scatterers, t_zero, trajectory, result.trajectory, config)
    histories = gather_phase_histories(drive_path, result.trajectory, config, moved, focus,
                                       half_beam_deg=fast.half_beam_deg, window_bins=fast.window_bins,
                                       channels=fast.channels)
    stage = fast_motion(histories, result.trajectory, config, moved, fast)
    if not stage.applied:
        return replace(result, fast_motion=stage)
    assert stage.correction is not None
    return replace(result, trajectory=with_correction(result.trajectory, stage.correction), fast_motion=stage)


def moved_with_track(points: Array, t_zero: NDArray[np.int64], before: Trajectory, after: Trajectory,
                     config: Config) -> Array:
    """``points`` (P, 3) (ENU m, where ``before`` focuses them) moved as the radar moved from ``before`` to
    ``after`` at their closest approach ``t_zero`` (P,) (ns)."""
    lever = phase_centre_lever_arm(config)[None]
    return points + (after.body_points(t_zero, lever)[:, 0] - before.body_points(t_zero, lever)[:, 0])


def _moved(points: Array, before: Trajectory, after: Trajectory, config: Config) -> Array:
    """:func:`moved_with_track`, each point's closest approach to ``before``'s radar found here."""
    if len(points) == 0:
        return points
    track = before.body_points(before.t_ns, phase_centre_lever_arm(config)[None])[:, 0, :2]
    return moved_with_track(points, closest_approach_ns(track, before.t_ns, points), before, after, config)


def radar_clock_rereads(drive_path: str | Path, trajectory: Trajectory, config: Config, points: Array,
                        focus: FocusOptions, passes: PassOptions, slow: SlowMotion | None
                        ) -> tuple[float, tuple[tuple[float, float, bool], ...]]:
    """How late (s) the radar's frame stamps run on ``trajectory``'s clock, where the points' passes (``slow``,
    along ``trajectory``) showed it: each offset shown is added and the passes read again along the track on that
    clock, until none shows (at most ``passes.radar_clock_rereads`` times); and every read's measured offset (s),
    std (s) and whether it was applied, the first (``slow``'s) first. An offset moves a point's envelope by its
    speed times it along the line of sight, so a large one leaves the passes only the blocks near broadside, and
    the slip gains take the rest (urban 30 ms late: 10 ms on the first read). 0 where none showed."""
    late_s, reads = 0.0, []
    while slow is not None and math.isfinite(slow.radar_clock_offset_s):
        # shown after the last read allowed, it is not added
        added = slow.radar_clock_applied and len(reads) < passes.radar_clock_rereads
        reads.append((float(slow.radar_clock_offset_s), float(slow.radar_clock_offset_std_s), bool(added)))
        if not added:
            break
        late_s += slow.radar_clock_offset_s
        on_clock = trajectory.on_radar_clock(int(round(late_s * 1e9)))
        slow = estimate_slow_motion(drive_path, on_clock, config, _moved(points, trajectory, on_clock, config), focus,
                                    passes)
    return late_s, tuple(reads)


def residual_motion_of_points(drive_path: str | Path, trajectory: Trajectory, config: Config, points_enu: Array,
                              focus: FocusOptions, opts: AutofocusOptions, passes: PassOptions | None = None
                              ) -> ResidualMotion:
    """``trajectory`` corrected by what the points ``points_enu`` (P, 3) (ENU m, where ``trajectory`` focuses them)
    measure: unless ``opts.slow_motion`` is off, the slow motion their ranges give over their passes
    (:func:`~autosar_cli.sar.pass_ranges.estimate_slow_motion`) less its whole-track stretch, then
    :func:`~autosar_cli.sar.residual_motion.estimate_residual_motion` along the track so corrected, which measures
    the scale where the points agree on it; where they do not, the passes' stretch is kept. A used point whose
    channels' phase says it moves (``opts.max_channel_phase_rad``) is left out and the rest fitted again."""
    points = np.asarray(points_enu, dtype=np.float64).reshape(-1, 3)
    passes = passes or PassOptions.from_config(config)
    # one read of the radar for both: the passes' histories, their windows wide enough that the phases' fit the
    # shape correction's change of path (test2 seed 1's, 32 mm at most, moves them by ~1 bin of the 6 kept)
    histories = (pass_histories(drive_path, trajectory, config, points, focus, passes,
                                min_window_bins=opts.window_bins + 2 * NARROWING_SLACK_BINS)
                 if opts.slow_motion and len(points) and passes.channels == opts.channels
                 and passes.half_beam_deg >= opts.half_beam_deg else None)
    moving_enu, moving_phase, moving_yaw = np.zeros((0, 3)), np.zeros(0), np.zeros(0)
    for _ in range(3):  # a point left out may leave another one used
        result = _points_motion(drive_path, trajectory, config, points, focus, opts, passes, histories)
        moving, phase, yaw = _moving_used(drive_path, result, config, focus, opts, histories)
        if not moving.any():
            break
        moving_enu = np.concatenate([moving_enu, result.points_enu[moving]])
        moving_phase = np.concatenate([moving_phase, phase[moving]])
        moving_yaw = np.concatenate([moving_yaw, yaw[moving]])
        points = points[~moving]
        histories = _histories_without(histories, ~moving) if histories is not None else None
    if not len(moving_enu):
        return result
    result = replace(result, moving_points_enu=moving_enu, moving_channel_phase_rad=moving_phase,
                     moving_mounting_yaw_deg=mounting_yaw_agreed(moving_yaw))
    # where too few still points remain, the moving ones are the reason too
    return replace(result, reason=result.reason + result._moving_summary()) if result.reason else result


def _moving_used(drive_path: str | Path, result: ResidualMotion, config: Config, focus: FocusOptions,
                 opts: AutofocusOptions, histories: PhaseHistories | None
                 ) -> tuple[NDArray[np.bool_], Array, Array]:
    """Which of ``result``'s candidate points a fit used (the phases' or the slow motion's) and moves across the
    beam (``opts.max_channel_phase_rad``, ``opts.min_channel_coherence``), every point's channel phase (rad; 0
    where not measured), along the track ``result`` made: over +-``opts.half_beam_deg``, narrowed from
    ``histories`` where given, else read; and the radar boresight (deg from the stated) at which each moving one's
    channel phase would be 0 (:func:`mounting_yaw_of_phase`; NaN for the others)."""
    points = result.points_enu
    used = np.asarray(result.points_used, dtype=bool).copy()
    slow = result.slow_motion
    if slow is not None and slow.applied and len(slow.points_used) == len(points):
        used |= slow.points_used
    if opts.max_channel_phase_rad is None or not used.any() or not result.applied:
        return np.zeros(len(points), dtype=bool), np.zeros(len(points)), np.full(len(points), np.nan)
    track = result.trajectory
    if histories is not None:
        hist = narrow_histories(histories, track, config, points, focus, half_beam_deg=opts.half_beam_deg,
                                window_bins=opts.window_bins)
    else:
        hist = gather_phase_histories(drive_path, track, config, points, focus, half_beam_deg=opts.half_beam_deg,
                                      window_bins=opts.window_bins, channels=opts.channels)
    phase, coherence = channel_phase(hist, *pair_antennas(hist, track, config), points, len(points))
    moving = used & (np.abs(phase) > opts.max_channel_phase_rad) & (coherence >= opts.min_channel_coherence)
    yaw = np.full(len(points), np.nan)
    if moving.any():
        yaw[moving] = mounting_yaw_of_phase(hist, track, config, points, phase)[moving]
    return moving, phase, yaw


#: the moving points' boresights agree where their spread (a robust std, deg) is at most this
MOUNTING_YAW_AGREE_DEG = 0.5


def mounting_yaw_of_phase(hist: PhaseHistories, track: Trajectory, config: Config, points: Array, phase: Array
                          ) -> Array:
    """Per point (P,), the radar boresight (deg from ``config.radar.mounting.yaw_deg``) at which its channel phase
    (:func:`~autosar_cli.sar.phase_history.channel_phase`, ``phase`` (P,) rad along the stated mounting) would be 0:
    the virtual array's ends turn with the radar, so the phase a still point shows is linear in the boresight's
    error (0.3 rad per deg on test1-3's, 45 deg off the direction of motion); its slope is measured here by turning
    the stated mounting by 1 deg (NaN where that moves no phase)."""
    turned = with_mounting_yaw(config, config.radar.mounting.yaw_deg + 1.0)
    per_deg = np.angle(np.exp(1j * (channel_phase(hist, *pair_antennas(hist, track, turned), points, len(points))[0]
                                    - phase)))
    return np.divide(-phase, per_deg, out=np.full(len(phase), np.nan), where=np.abs(per_deg) > 1e-6)


def mounting_yaw_agreed(yaw_deg: Array) -> float | None:
    """The boresight error (deg) that the moving points' own (``yaw_deg``, :func:`mounting_yaw_of_phase`) agree on:
    their median, where at least two give one, within ``MOUNTING_YAW_AGREE_DEG`` (a robust std: 1.4826 times their
    median absolute deviation); else None. Points crossing the beam alike agree too (a whole column walking at one
    speed), at a phase a mounting error of a few degrees does not give (test_moving_scatterers: 2.7-3.0 rad, ~9 deg):
    :func:`autofocus_residual_motion` takes one for a mounting error only within ``MAX_MOUNTING_YAW_DEG``."""
    yaw = np.asarray(yaw_deg, dtype=np.float64)
    yaw = yaw[np.isfinite(yaw)]
    if len(yaw) < 2:
        return None
    median = float(np.median(yaw))
    spread = 1.4826 * float(np.median(np.abs(yaw - median)))  # a std that one point of another kind does not move
    return median if spread <= MOUNTING_YAW_AGREE_DEG else None


def _histories_without(hist: PhaseHistories, keep: NDArray[np.bool_]) -> PhaseHistories:
    """``hist`` with only the ``keep`` (P,) points' pulses, the points numbered as the kept ones are."""
    sub, _ = histories_of(hist, keep)
    return replace(sub, point=(np.cumsum(keep) - 1)[sub.point])


def _points_motion(drive_path: str | Path, trajectory: Trajectory, config: Config, points: Array,
                   focus: FocusOptions, opts: AutofocusOptions, passes: PassOptions,
                   histories: PhaseHistories | None) -> ResidualMotion:
    """:func:`residual_motion_of_points` without its moving-point test, on the passes' ``histories`` (or None)."""
    if not opts.slow_motion or len(points) == 0:
        return estimate_residual_motion(drive_path, trajectory, config, points, focus, opts)
    slow = estimate_slow_motion(drive_path, trajectory, config, points, focus, passes, histories)
    if not slow.applied:
        return replace(estimate_residual_motion(drive_path, trajectory, config, points, focus, opts,
                                                histories=histories), slow_motion=slow)
    # the passes' shape, their stretch left to the phases, so that the scale is one, the phases' where their points
    # agree on it (test2 seeds 0 / 1 / 3: the worst reflector 1.46 / 1.17 / 1.43 cm along the passes' stretch, 1.60 /
    # 0.56 / 1.60 along the phases'); where they do not, the passes' stretch too, and the points where that track
    # focuses them
    assert slow.shape_correction is not None and slow.shape_point_shift_enu is not None
    result = estimate_residual_motion(drive_path, with_correction(trajectory, slow.shape_correction), config,
                                      points - slow.shape_point_shift_enu, focus, opts,
                                      unscaled=(slow.trajectory, points - slow.point_shift_enu), histories=histories)
    if not (result.scale_note or result.reason):
        return replace(result, slow_motion=slow)
    phases = result.scale_note.removeprefix("track scale ") or f"not measured: {result.reason}"
    # the scale reported is the whole correction's, as the evaluation reads a track's (the stretch, a line weighted by
    # where the points are, missed SAR-MIN's by 0.026 % RMS on urban at 29 times its std; this by 0.013 % at 3.2)
    note = (f"track scale {slow.scale * 100:+.4f} ± {slow.scale_std * 100:.4f} % from the points' passes; by "
            f"their phases {phases}")
    return replace(result, trajectory=slow.trajectory if result.reason else result.trajectory, slow_motion=slow,
                   scale=slow.scale, scale_std=slow.scale_std, scale_note=note)
