"""Ground-truth sidecar ``<log>.truth.h5`` written next to every simulated log.

Layout (format ``autosar-truth`` version 1; every array in SI units, ENU metres at the origin attrs):

    /                      attrs: format, format_version, scenario, description, seed, autosar_version,
                                  origin_lat_deg, origin_lon_deg, origin_height_m, start_time_ns, config_toml
    /trajectory/           t_ns (N,), position_enu (N,3) CoG, rear_axle_enu (N,2), heading (N,) rad from East CCW,
                           speed (N,) rear-axle m/s, yaw_rate (N,) rad/s, accel (N,) m/s^2, curvature (N,) 1/m,
                           road_wheel_angle (N,) rad, radar_origin_enu (N,3) (without vibration)
    /radar/                frame_index (F,), t_ns (F,) PRI start, chirp_t_ns (F,T) chirp start per Tx, both as
                           the drive stamps them (the radar's clock: the true instant plus attr radar_clock_offset_s,
                           plus attr radar_clock_drift_ppm of the time since the first frame),
                           tx_position_enu (F,T,3), rx_position_enu (F,T,R,3) at each chirp start,
                           phase_centre_enu (F,T,R,3) = (tx + rx) / 2, vibration_enu (F,3)
    /dynamics/             only for the full vehicle model (attrs dynamics = "full"): t_ns (N,), attitude (N,3)
                           roll, pitch, yaw rad, body_rates (N,3) rad/s body axes, side_slip (N,) rad at the CoG,
                           lateral_offset (N,) rear axle from the path m, per wheel (fl, fr, rl, rr) (N,4):
                           wheel_load N, rolling_radius m, longitudinal_slip, wheel_rotation rad,
                           road_height_at_wheels m; road_s (S,) m along the path, road_track_heights (S,2)
                           left/right roughness + features m, road_grade_height (S,) m
    /targets/              position_enu (M,3) at the drive's start, rcs_m2 (M,), kind (M,) int8 (attrs kinds),
                           object (M,), object_names (K,), corner_reflectors (C,) indices; velocity_enu (M,3) m/s
                           where some move (at start_time_ns + t they are at position + velocity t)
    /sensors/<name>/       t_ns (n,) measurement instants, plus true values and error states
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import h5py
import numpy as np
from numpy.typing import NDArray

from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.sim.scene import KINDS, Scene

if TYPE_CHECKING:
    from autosar_cli.store.drive import Drive
from autosar_cli.sim.sensors import SensorSamples

FORMAT = "autosar-truth"
FORMAT_VERSION = 1


def truth_path_for(log_path: Path) -> Path:
    return log_path.with_name(log_path.name + ".truth.h5")


def truth_sidecar_of(log_paths: Iterable[str | Path]) -> Path | None:
    """The ``<log>.truth.h5`` beside the first of ``log_paths`` that has one (a drive's default truth), or None."""
    return next((c for p in log_paths if (c := truth_path_for(Path(p))).exists()), None)


class TruthWriter:
    """Streams the truth sidecar: whole-drive arrays once, radar arrays appended block by block."""

    def __init__(self, path: Path, attrs: dict[str, Any], n_tx: int, n_rx: int) -> None:
        self.path = path
        self.tmp = path.with_name(path.name + ".partial")
        self.f: h5py.File | None = None
        try:
            self.f = h5py.File(self.tmp, "w", track_order=False)
            self._start(attrs, n_tx, n_rx)
        except BaseException:  # Ctrl-C included: the caller has no writer to abort yet
            self.abort()
            raise

    def _start(self, attrs: dict[str, Any], n_tx: int, n_rx: int) -> None:
        for k, v in attrs.items():
            self.f.attrs[k] = v
        self.f.attrs["format"] = FORMAT
        self.f.attrs["format_version"] = FORMAT_VERSION
        r = self.f.create_group("radar")
        self._radar = {
            "frame_index": r.create_dataset("frame_index", (0,), np.int64, maxshape=(None,), chunks=(4096,),
                                            track_times=False),
            "t_ns": r.create_dataset("t_ns", (0,), np.int64, maxshape=(None,), chunks=(4096,), track_times=False),
            "chirp_t_ns": r.create_dataset("chirp_t_ns", (0, n_tx), np.int64, maxshape=(None, n_tx),
                                           chunks=(1024, n_tx), track_times=False),
            "tx_position_enu": r.create_dataset("tx_position_enu", (0, n_tx, 3), np.float64,
                                                maxshape=(None, n_tx, 3), chunks=(1024, n_tx, 3),
                                                track_times=False),
            "rx_position_enu": r.create_dataset("rx_position_enu", (0, n_tx, n_rx, 3), np.float64,
                                                maxshape=(None, n_tx, n_rx, 3), chunks=(512, n_tx, n_rx, 3),
                                                track_times=False),
            "phase_centre_enu": r.create_dataset("phase_centre_enu", (0, n_tx, n_rx, 3), np.float64,
                                                 maxshape=(None, n_tx, n_rx, 3), chunks=(512, n_tx, n_rx, 3),
                                                 track_times=False),
            "vibration_enu": r.create_dataset("vibration_enu", (0, 3), np.float64, maxshape=(None, 3),
                                              chunks=(4096, 3), track_times=False),
            "raw_crc32": r.create_dataset("raw_crc32", (0,), np.uint32, maxshape=(None,), chunks=(4096,),
                                          track_times=False),
        }

    def _put(self, group: str, name: str, data: NDArray[Any]) -> None:
        self.f.require_group(group).create_dataset(name, data=data, track_times=False)

    def write_trajectory(self, arrays: dict[str, NDArray[Any]]) -> None:
        for k, v in arrays.items():
            self._put("trajectory", k, v)

    def write_dynamics(self, arrays: dict[str, NDArray[Any]]) -> None:
        for k, v in arrays.items():
            self._put("dynamics", k, v)

    def write_targets(self, scene: Scene) -> None:
        self._put("targets", "position_enu", scene.position)
        self._put("targets", "rcs_m2", scene.rcs_m2)
        self._put("targets", "kind", scene.kind)
        self._put("targets", "object", scene.object_index)
        self._put("targets", "object_names", np.array(scene.names, dtype=h5py.string_dtype()))
        self._put("targets", "corner_reflectors", scene.corner_reflectors)
        if scene.velocity_enu is not None:
            self._put("targets", "velocity_enu", scene.velocity_enu)
        self.f["targets"].attrs["kinds"] = ",".join(KINDS)

    def write_sensor(self, samples: SensorSamples, t_ns: NDArray[np.int64], stamp_ns: NDArray[np.int64]) -> None:
        g = f"sensors/{samples.name}"
        self._put(g, "t_ns", t_ns)
        self._put(g, "stamp_ns", stamp_ns)
        for k, v in samples.truth.items():
            self._put(g, k, np.asarray(v))
        self.f[g].attrs["kind"] = samples.kind

    def append_radar(self, block: dict[str, NDArray[Any]]) -> None:
        n = len(block["t_ns"])
        for k, ds in self._radar.items():
            old = ds.shape[0]
            ds.resize(old + n, axis=0)
            ds[old:] = block[k]

    def close(self) -> None:
        self.finish()
        self.publish()

    def finish(self) -> None:
        """Close the file, whole, at its partial path."""
        self.f.close()

    def publish(self) -> None:
        """Put the finished file in its place."""
        os.replace(self.tmp, self.path)

    def abort(self) -> None:
        try:
            if self.f is not None:
                self.f.close()
        finally:
            self.tmp.unlink(missing_ok=True)


def open_truth(truth_path: str | Path) -> h5py.File:
    """``truth_path`` open for reading (a ``with`` closes it), checked to be an autosar truth sidecar: a ValueError
    naming it where it is not (missing, not HDF5, cut short, another file of autosar's), before any content is
    looked for."""
    if not os.path.exists(truth_path):
        raise ValueError(f"{truth_path}: no such truth sidecar")
    try:
        f = h5py.File(truth_path, "r")
    except OSError as exc:
        reason = str(exc).splitlines()[0].removeprefix("Unable to synchronously open file ").strip("()")
        raise ValueError(f"{truth_path}: not an autosar truth sidecar (not a readable HDF5 file: {reason})") from None
    if (fmt := f.attrs.get("format")) != FORMAT:
        f.close()
        raise ValueError(f"{truth_path}: not an autosar truth sidecar"
                         + (f" but {'an' if str(fmt)[0] in 'aeiou' else 'a'} {fmt} file" if fmt else ""))
    return f


def truth_radar_mismatch(truth_path: str | Path, drive: Drive, frames: int = 8) -> str | None:
    """Why the truth sidecar at ``truth_path`` is not the truth of the open ``drive``: it keeps each
    radar frame's CRC-32 (``radar/raw_crc32``, of its int16 samples as a drive holds them), and none of ``frames``
    of the drive's frames, spread over it, matches the truth's frame of the same index. None where one does (a
    damaged, cut or converted log of the same recording still has intact frames), or where nothing can be compared
    (an older truth, no common frame index)."""
    with open_truth(truth_path) as f:
        if "radar/raw_crc32" not in f:
            return None
        truth_index, truth_crc = f["radar/frame_index"][()], f["radar/raw_crc32"][()]
        log_file = f.attrs.get("log_file", "")
    radar = drive.radar()
    # the truth's frames of the indices of the drive's frames spread over it (the truth holds every frame)
    named = np.isin(truth_index, np.asarray(radar.frame_index)[radar.spread(frames)])
    n = radar.unmatched(truth_index[named].tolist(), truth_crc[named].tolist())
    if not n:
        return None
    return (f"{truth_path}: the truth of another recording ({log_file}): none of {n} radar frames of "
            f"{drive.path} matches it")


@dataclass(frozen=True)
class TruthTargets:
    """Scene scatterers from a truth sidecar, in the ENU frame of a given origin."""

    position_enu: NDArray[np.float64]  #: (N, 3) m
    kind: NDArray[np.int64]  #: index into KINDS
    names: list[str]  #: object name of each scatterer
    corner_reflectors: NDArray[np.int64]  #: indices of the corner reflectors
    velocity_enu: NDArray[np.float64] | None = None  #: (N, 3) m/s where some move (None: all still)

    def corner_reflector_names(self) -> list[str]:
        return [self.names[i] for i in self.corner_reflectors]


def read_targets(truth_path: str | Path, origin: GeodeticOrigin) -> TruthTargets:
    """The targets of ``truth_path`` re-expressed in ``origin``'s ENU frame (e.g. a drive's or an image's)."""
    with open_truth(truth_path) as f:
        g = f["targets"]
        pos = g["position_enu"][()]
        kind = g["kind"][()].astype(np.int64)
        obj = g["object"][()].astype(np.int64)
        names = [n.decode() if isinstance(n, bytes) else str(n) for n in g["object_names"][()]]
        crs = g["corner_reflectors"][()].astype(np.int64)
        velocity = g["velocity_enu"][()] if "velocity_enu" in g else None
        truth_origin = GeodeticOrigin(float(f.attrs["origin_lat_deg"]), float(f.attrs["origin_lon_deg"]),
                                      float(f.attrs["origin_height_m"]))
    enu = origin.to_enu(*truth_origin.to_geodetic(pos))
    if velocity is not None:  # the velocity turned into the origin's frame with the positions
        ahead = origin.to_enu(*truth_origin.to_geodetic(pos + velocity))
        velocity = ahead - enu
    return TruthTargets(enu, kind, [names[i] for i in obj], crs, velocity)
