"""The radar's channel gains: the complex gain each virtual channel's front end puts on its echoes.

A MIMO radar's Tx and Rx paths each add their own phase and gain (TI's mmWave devices leave them to a calibration
against a corner reflector). Back-projection sums the channels coherently, so an uncalibrated front end costs the
image its peak and blurs its far swath, and makes every still point look like a mover to the autofocus (its
channels' phases differ). :class:`ChannelGains` holds them per (Tx, Rx), as measured
(:mod:`autosar_cli.sar.channel_calibration`) or as a TI capture's calibration states them; focus divides each
channel's range profiles by its gain (:meth:`ChannelGains.correction`). Phases are relative to the channels' mean,
gains to their geometric mean: a common phase or gain changes no image.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class ChannelGains:
    """Per (Tx, Rx): the phase (deg) and gain (dB) the channel's front end adds, ``[tx][rx]``."""

    phase_deg: tuple[tuple[float, ...], ...]
    gain_db: tuple[tuple[float, ...], ...]

    @classmethod
    def from_complex(cls, gains: NDArray[np.complexfloating], measured: NDArray[np.bool_] | None = None
                     ) -> ChannelGains:
        """From complex gains (T, R), normalised over the ``measured`` ones (default all): their sum's phase 0,
        their magnitudes' geometric mean 1; the others 1 (0 deg, 0 dB)."""
        g = np.asarray(gains, dtype=np.complex128)
        m = np.ones(g.shape, bool) if measured is None else np.asarray(measured, bool)
        g = g.copy()
        g[m], g[~m] = normalised(g[m]), 1.0
        return cls(tuple(tuple(round(float(v), 3) for v in row) for row in np.degrees(np.angle(g))),
                   tuple(tuple(round(float(v), 4) for v in row) for row in 20 * np.log10(np.abs(g))))

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ChannelGains:
        return cls(tuple(tuple(float(v) for v in row) for row in d["phase_deg"]),
                   tuple(tuple(float(v) for v in row) for row in d["gain_db"]))

    def to_dict(self) -> dict[str, Any]:
        return {"phase_deg": [list(r) for r in self.phase_deg], "gain_db": [list(r) for r in self.gain_db]}

    def complex(self) -> NDArray[np.complex128]:
        """The complex gains (T, R)."""
        return 10 ** (np.asarray(self.gain_db) / 20) * np.exp(1j * np.radians(np.asarray(self.phase_deg)))

    def correction(self, pairs: list[tuple[int, int]]) -> NDArray[np.complex64]:
        """What each of ``pairs`` (Tx, Rx) is multiplied by to undo its gain (C,), normalised over those pairs (so
        an image's level does not depend on the channels it leaves out)."""
        g = self.complex()
        return (1.0 / normalised(np.array([g[t, r] for t, r in pairs]))).astype(np.complex64)


def normalised(gains: NDArray[np.complexfloating]) -> NDArray[np.complex128]:
    """Complex gains (any shape) with their sum's phase 0 and their magnitudes' geometric mean 1: a common phase or
    gain changes no image."""
    g = np.asarray(gains, dtype=np.complex128)
    g = g / np.exp(1j * np.angle(g.sum()))
    return g / np.exp(np.mean(np.log(np.maximum(np.abs(g), 1e-300))))


def stated_channel_gains(radar_attrs: Any) -> ChannelGains | None:
    """The channel gains a drive's radar stream states (``channel_phase_deg``, ``channel_gain_db``: a TI capture's
    calibration, ``compRangeBiasAndRxChanPhase``), else None."""
    if "channel_phase_deg" not in radar_attrs:
        return None
    gain = np.asarray(radar_attrs.get("channel_gain_db", 0.0), dtype=np.float64)
    phase = np.asarray(radar_attrs["channel_phase_deg"], dtype=np.float64)
    return ChannelGains.from_complex(10 ** (gain / 20) * np.exp(1j * np.radians(phase)))


def trajectory_channel_gains(info: dict[str, Any]) -> ChannelGains | None:
    """The channel gains a trajectory's ``info`` carries (``channel_gains``: those its autofocus measured and
    applied, or the truth's), else None."""
    d = info.get("channel_gains")
    return ChannelGains.from_dict(d) if d else None
