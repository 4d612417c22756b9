"""Road surface under the simulated car: grade, cross-fall, ISO 8608 roughness and discrete features.

Heights are in metres, up, as a function of the arc length s along the scenario's path (m) and of the
lateral offset w from the path (m, left positive). The two wheel tracks (left, right) carry independent
roughness with a coherence that falls with spatial frequency, as measured on real roads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

from autosar_cli.config import VehicleDynamicsConfig

# ISO 8608:2016 Table 1: displacement PSD Gd(n0) at n0 = 0.1 cycles/m (geometric mean of each class), m^3.
ISO8608_GD_N0 = {"A": 16e-6, "B": 64e-6, "C": 256e-6, "D": 1024e-6}
ISO8608_N0 = 0.1  # cycles/m
ISO8608_WAVINESS = 2.0
ROAD_GRID_M = 0.02  # height samples along each track


@dataclass(frozen=True)
class RoadLayout:
    """Discrete features of a scenario's road, by arc length s (m) along its path."""

    bumps: tuple[tuple[float, float, float], ...] = ()  #: (start s, length, height) m, both tracks
    kerb_ramps: tuple[tuple[float, float, float], ...] = ()  #: (start s, length, height) m, right track only
    rough_sections: tuple[tuple[float, float, str], ...] = ()  #: (s0, s1, ISO class) replacing the base class


def iso8608_psd(n: NDArray[np.float64], road_class: str) -> NDArray[np.float64]:
    """One-sided displacement PSD Gd(n) (m^3) of an ISO 8608 class at spatial frequencies n (cycles/m)."""
    return ISO8608_GD_N0[road_class] * (np.asarray(n) / ISO8608_N0) ** (-ISO8608_WAVINESS)


def rough_tracks(length_m: float, road_class: str, track_m: float, coherence_decay: float,
                 max_frequency_cpm: float, rng: np.random.Generator,
                 spacing_m: float = ROAD_GRID_M) -> NDArray[np.float64]:
    """Left and right roughness profiles (2, N) m on a grid of spacing_m, ISO 8608 class, zero mean.

    Spectral synthesis: complex Gaussian amplitudes with the class PSD; the right track shares a part
    gamma(n) = exp(-decay n B) of the left's amplitudes (coherence gamma^2), the rest is independent.
    """
    n_pts = int(np.ceil(length_m / spacing_m)) + 1
    n_fft = 1 << int(np.ceil(np.log2(max(n_pts, 16))))
    n = np.fft.rfftfreq(n_fft, spacing_m)
    dn = n[1]
    psd = np.zeros_like(n)
    band = (n > 0) & (n <= max_frequency_cpm)
    psd[band] = iso8608_psd(n[band], road_class)
    # one-sided PSD -> E|X_k|^2 of the rfft so that irfft has the same variance per band: N^2 Gd dn / 2
    amp = np.sqrt(psd * dn / 2.0) * n_fft
    z1 = (rng.standard_normal(n.size) + 1j * rng.standard_normal(n.size)) / np.sqrt(2.0)
    z2 = (rng.standard_normal(n.size) + 1j * rng.standard_normal(n.size)) / np.sqrt(2.0)
    gamma = np.exp(-coherence_decay * n * track_m)
    left = np.fft.irfft(amp * z1, n_fft)[:n_pts]
    right = np.fft.irfft(amp * (gamma * z1 + np.sqrt(1.0 - gamma**2) * z2), n_fft)[:n_pts]
    return np.stack([left, right])


def _raised_cosine_step(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """0 for x <= 0, 1 for x >= 1, a smooth (C1) half cosine between."""
    return 0.5 - 0.5 * np.cos(np.pi * np.clip(x, 0.0, 1.0))


class RoadProfile:
    """Heights of the road under each wheel track along a path from s_min_m to s_max_m.

    Args:
        s_min_m, s_max_m: arc-length span to cover (m).
        layout: the scenario's discrete features and rough sections.
        dyn: road class, coherence, grade and cross-fall parameters.
        track_m: distance between the wheel tracks (m).
        rng: the scenario's road generator (the road is part of the scene, fixed per scenario).
    """

    def __init__(self, s_min_m: float, s_max_m: float, layout: RoadLayout, dyn: VehicleDynamicsConfig,
                 track_m: float, rng: np.random.Generator) -> None:
        self.s = np.arange(s_min_m, s_max_m + ROAD_GRID_M, ROAD_GRID_M)
        span = self.s[-1] - self.s[0]
        tracks = rough_tracks(span, dyn.road_class, track_m, dyn.road_coherence_decay, dyn.road_max_frequency_cpm,
                              rng)[:, : self.s.size]
        for s0, s1, cls in layout.rough_sections:
            other = rough_tracks(span, cls, track_m, dyn.road_coherence_decay, dyn.road_max_frequency_cpm,
                                 rng)[:, : self.s.size]
            # 1 m raised-cosine transitions in and out of the section
            w = _raised_cosine_step(self.s - s0 + 0.5) * (1.0 - _raised_cosine_step(self.s - s1 + 0.5))
            tracks = tracks * (1.0 - w) + other * w
        self.roughness = tracks
        features = np.zeros_like(tracks)
        for s0, length, height in layout.bumps:
            x = (self.s - s0) / length
            features += np.where((x > 0) & (x < 1), height * np.sin(np.pi * np.clip(x, 0, 1)) ** 2, 0.0)
        for s0, length, height in layout.kerb_ramps:
            ramp = 0.4  # m up and down
            up = _raised_cosine_step((self.s - s0) / ramp)
            down = _raised_cosine_step((self.s - s0 - length + ramp) / ramp)
            features[1] += height * (up - down)
        self.features = features
        self.grade_amplitude_m = dyn.road_grade_percent / 100.0 * dyn.road_grade_wavelength_m / (2 * np.pi)
        self.grade_k = 2 * np.pi / dyn.road_grade_wavelength_m
        self.cross_fall = dyn.road_cross_fall_percent / 100.0
        self.track_m = track_m
        self._tracks = CubicSpline(self.s, (tracks + features).T, axis=0)

    def grade_height(self, s: NDArray[np.float64]) -> NDArray[np.float64]:
        """Height (m) of the road's centre line: a sinusoidal grade of the configured amplitude."""
        return self.grade_amplitude_m * np.sin(self.grade_k * np.asarray(s))

    def height(self, s: NDArray[np.float64], w: NDArray[np.float64], side: int) -> NDArray[np.float64]:
        """Road height (m) at arc length s, lateral offset w (m, left +) on wheel track side (0 left, 1 right)."""
        s = np.asarray(s, dtype=np.float64)
        return self.grade_height(s) + self.cross_fall * np.asarray(w) + self._tracks(s)[..., side]
