"""Trajectory figure for ``autosar navigate --plot``: track, speed, heading, estimated biases and the
across-track deviation from the straight line through the track's ends (paper Fig. 11)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from autosar_cli.nav.trajectory import Trajectory
from autosar_cli.store.quicklook import PanelGrid, save_png

Array = NDArray[np.float64]


def across_track_deviation(xy: Array) -> tuple[Array, Array]:
    """(along, across) coordinates (m) of a track relative to the straight line from its first to its last point;
    across is positive to the left of the direction of travel."""
    a, b = xy[0], xy[-1]
    u = (b - a) / max(float(np.linalg.norm(b - a)), 1e-9)
    d = xy - a
    return d @ u, u[0] * d[:, 1] - u[1] * d[:, 0]


def plot_trajectory(traj: Trajectory, path: str | Path, others: list[Trajectory] | None = None) -> Path:
    """Write a PNG summary of ``traj`` (and, in the track and across-track panels, ``others``)."""
    path = Path(path)
    t = traj.t
    has_bias = traj.state is not None and any(n.startswith("bias.") for n in traj.state_names)
    fig, axes = PanelGrid(2, 3, (4.0, 2.9), top_in=0.75, gap_y_in=0.9).figure()
    ax = axes[0, 0]
    for tr in [traj, *(others or [])]:
        ax.plot(tr.rear_axle_enu[:, 0], tr.rear_axle_enu[:, 1], label=tr.method, lw=1)
    ax.set(xlabel="East (m)", ylabel="North (m)", title="track (rear-axle centre)")
    ax.axis("equal")
    ax.legend()
    ax = axes[0, 1]
    for tr in [traj, *(others or [])]:
        along, across = across_track_deviation(tr.rear_axle_enu)
        ax.plot(along, across * 100, label=tr.method, lw=1)
    ax.set(xlabel="along track (m)", ylabel="across track (cm)", title="deviation from the straight line")
    ax.legend()
    axes[0, 2].plot(t, traj.speed * 3.6)
    axes[0, 2].set(xlabel="time (s)", ylabel="speed (km/h)", title="speed")
    axes[1, 0].plot(t, np.rad2deg(traj.heading))
    axes[1, 0].set(xlabel="time (s)", ylabel="heading (deg, ENU)", title="heading")
    axes[1, 1].plot(t, np.rad2deg(traj.yaw_rate))
    axes[1, 1].set(xlabel="time (s)", ylabel="yaw rate (deg/s)", title="yaw rate")
    ax = axes[1, 2]
    if has_bias:
        for i, name in enumerate(traj.state_names):
            if name.startswith("bias.") and name != "bias.steering":
                ax.plot(t, np.rad2deg(traj.state[:, i]), label=name[5:])  # type: ignore[index]
        ax.set(xlabel="time (s)", ylabel="gyro bias (deg/s)", title="estimated gyro biases")
        ax.legend()
    else:
        ax.axis("off")
    fig.suptitle(f"{traj.method}: {traj.info.get('drive', '')}")
    return save_png(fig, path)
