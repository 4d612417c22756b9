"""Focus in tiles: the image grid split along the track into column tiles, each focused on its own.

A pixel's value does not depend on which grid it is in (:func:`~autosar_cli.sar.focus.focus_images` sums
each pixel's own stripmap window, pulse block by pulse block, independently of its neighbours), so tiles
focused separately reassemble into the one-piece image. To make that hold bit for bit, a tile
(:class:`GridTile`) computes its pixels' ENU positions from the *parent* grid's origin and the parent's
column index -- exactly the floating-point operations of the one-piece grid -- instead of from an origin
shifted to its first pixel (which would move every pixel by a rounding error, ~1e-14 m, and the image by
float32 rounding).

Memory: a tile's task holds its own image (and one block of pulses), never the whole image; the tiles
can run one after the other in-process (``client=None``) or as Dask tasks on a dask.distributed cluster.
The caller writes each tile's columns into the products as the tile arrives
(:class:`~autosar_cli.store.image.ImageWriter`), so it never holds the whole image either.

Cost: a tile's task reads and range-compresses only the pulse blocks whose beam reaches it (focus_images
skips the others), so tiles along the track split the reading, range compression and back-projection of
a long drive; blocks that straddle a tile boundary are compressed once per tile they reach.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from autosar_cli.config import Config
from autosar_cli.nav.trajectory import Trajectory
from autosar_cli.sar.focus import (
    DAMAGED_FRAMES,
    FocusError,
    FocusOptions,
    FocusReport,
    _usable_frames,
    brightest_pixel,
    channels_incoherent_warning,
    check_request,
    check_same_recording,
    check_some_backprojection,
    damaged_frames_warning,
    drive_radar_config,
    focus_images,
    grid_enu_box,
    make_grid,
    open_radar,
    unfocused_radars,
)
from autosar_cli.sar.grid import FocusGrid
from autosar_cli.store.drive import Drive
from autosar_cli.store.image import ImageWriter
from autosar_cli.store.trajectory import read_trajectory


@dataclass(frozen=True)
class GridTile(FocusGrid):
    """Columns [col0, col0 + n_along) of a parent grid.

    ``origin`` is the tile's first pixel (as for any grid), but pixel positions are computed from the
    parent's origin and column index so that they equal the parent's bit for bit.
    """

    col0: int = 0  #: first column of the tile in the parent grid
    parent_origin: tuple[float, float] = (0.0, 0.0)  #: the parent grid's origin

    def _parent(self) -> FocusGrid:
        return FocusGrid(self.parent_origin, self.along, self.across, self.pixel_m, self.col0 + self.n_along,
                         self.n_across, self.height_m)

    def pixel_enu(self, rows: ArrayLike, cols: ArrayLike) -> NDArray[np.float64]:
        return self._parent().pixel_enu(rows, np.asarray(cols, dtype=np.float64) + self.col0)

    def enu_to_pixel(self, xy: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        rows, cols = self._parent().enu_to_pixel(xy)
        return rows, cols - self.col0


def split_grid(grid: FocusGrid, tiles: int) -> list[GridTile]:
    """``tiles`` column tiles of ``grid`` (along the track), as equal as possible; at most one per column."""
    if tiles < 1:
        raise FocusError(f"--tiles {tiles}: must be at least 1")
    n = min(int(tiles), grid.n_along)
    bounds = [round(k * grid.n_along / n) for k in range(n + 1)]
    out = []
    for c0, c1 in zip(bounds[:-1], bounds[1:], strict=True):
        first = grid.pixel_enu(0, c0)
        out.append(GridTile((float(first[0]), float(first[1])), grid.along, grid.across, grid.pixel_m, c1 - c0,
                            grid.n_across, grid.height_m, col0=c0, parent_origin=grid.origin))
    return out


def _read_trajectory(trajectory: str | Path | Trajectory) -> tuple[Trajectory, str]:
    if isinstance(trajectory, Trajectory):
        return trajectory, f"<{trajectory.method} trajectory>"
    name = str(trajectory)
    try:
        return read_trajectory(trajectory, covariance=False), name
    except (OSError, ValueError) as exc:
        msg = str(exc)
        raise FocusError(msg if name in msg else f"{name}: {msg}") from None


def plan_grid(drive_path: str | Path, trajectory: str | Path | Trajectory, config: Config,
              options: FocusOptions, trajectory_name: str | None = None) -> FocusGrid:
    """The grid :func:`~autosar_cli.sar.focus.focus_images` would focus onto (``options.grid``), without focusing.

    Reads only the radar frame times of the drive and the trajectory (``trajectory_name``: how errors name a
    :class:`Trajectory` given, e.g. the file it was read from).
    """
    traj, traj_name = _read_trajectory(trajectory)
    traj_name = trajectory_name or traj_name
    with Drive(drive_path) as drive:
        radar = open_radar(drive, options)
        check_same_recording(drive, radar, traj, traj_name)
        geometry = _usable_frames(radar, traj, config, options.min_speed_mps)
    if geometry.frames.size < 2:
        raise FocusError(f"{drive_path}: no radar frame lies inside the trajectory {traj_name} while moving")
    return make_grid(options, geometry, config)


@dataclass
class TileResult:
    """What one tile's task sends back: its image and what it took (no grid products, nothing written)."""

    col0: int
    image: NDArray[np.complex64]  #: (rows, tile columns)
    frames_used: int
    frames_skipped: dict[str, int]
    backprojections: int
    timings_s: dict[str, float]
    drive_s: float
    params: dict[str, Any] = field(default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict)
    wall_s: float = 0.0
    damaged_frame_index: list[int] = field(default_factory=list)  #: frames of a damaged drive the tile left out
    #: what focus_images warned of beside those frames (the drive's damaged attributes or tables): the image's too
    warnings: list[str] = field(default_factory=list)
    #: the tile's brightest pixel: its magnitude, row and column in the parent grid (the channels' check's point)
    brightest: tuple[float, int, int] = (0.0, 0, 0)


def focus_tile(drive_path: str | Path, trajectory: str | Path | Trajectory, config: Config, options: FocusOptions,
               tile: FocusGrid, *, progress: Callable[[int, int], None] | None = None,
               command: str = "") -> TileResult:
    """Focus one tile (top-level and picklable: the Dask task of :func:`focus_tiled`)."""
    t0 = time.perf_counter()
    res = focus_images(drive_path, trajectory, config, options, [tile], progress=progress, command=command)
    img = res.images[0]
    # the damaged frames' warning is the whole image's, counted over every tile's frames by focus_tiled
    damaged = damaged_frames_warning(drive_path, str(img.params["radar"]), res.damaged_frame_index) \
        if res.damaged_frame_index else None
    others = [w for w in res.warnings if w != damaged]
    col0 = getattr(tile, "col0", 0)
    r, c = brightest_pixel(img.image)
    return TileResult(col0, img.image, res.frames_used, res.frames_skipped, res.backprojections,
                      res.timings_s, res.drive_s, img.params, img.provenance, time.perf_counter() - t0,
                      res.damaged_frame_index, list(others), (float(np.abs(img.image[r, c])), r, col0 + c))


def focus_tiled(drive_path: str | Path, trajectory_path: str | Path, output: str | Path, config: Config,
                options: FocusOptions, *, tiles: int, client: Any = None, overwrite: bool = False,
                progress: Callable[[int, int], None] | None = None, command: str = "") -> FocusReport:
    """:func:`~autosar_cli.sar.focus.focus` in ``tiles`` column tiles; writes OUT.tif/.h5/.png, the same image.

    ``client``: a ``dask.distributed.Client`` to run the tiles as tasks on its cluster (the drive and the
    trajectory must be readable at the same paths on the workers); ``None`` runs them one after the other
    in this process. ``progress(done, total)`` counts pulse blocks over all tiles in-process, tiles with a
    client. Timings in the report are summed over the tiles (processing time, not wall time).
    """
    check_request(options, output, overwrite, [drive_path, trajectory_path])
    config = drive_radar_config(config, drive_path, options.radar)
    t_plan = time.perf_counter()
    traj, traj_name = _read_trajectory(trajectory_path)
    grid = plan_grid(drive_path, traj, config, options, traj_name)
    parts = split_grid(grid, tiles)
    timings: Counter[str] = Counter()
    timings["geometry"] += time.perf_counter() - t_plan
    results: list[TileResult] = []

    with ImageWriter(Path(output), grid, traj.origin, overwrite=overwrite) as writer:
        def place(r: TileResult) -> None:
            t0 = time.perf_counter()
            writer.write_columns(r.col0, r.image)  # straight to the products: the whole image is never held
            timings["write"] += time.perf_counter() - t0
            timings.update(r.timings_s)
            results.append(replace(r, image=np.zeros((0, 0), np.complex64)))

        if client is None:
            for k, tile in enumerate(parts):
                def tile_progress(done: int, total: int, k: int = k) -> None:
                    if progress is not None:
                        progress(k * total + done, len(parts) * total)

                place(focus_tile(drive_path, trajectory_path, config, options, tile, progress=tile_progress,
                                 command=command))
        else:
            from distributed import as_completed

            futures = [client.submit(focus_tile, str(drive_path), str(trajectory_path), config, options, tile,
                                     command=command, key=f"focus-tile-{Path(output).name}-{k}-{_token()}",
                                     pure=False)
                       for k, tile in enumerate(parts)]
            for n, fut in enumerate(as_completed(futures), 1):
                place(fut.result())
                fut.release()
                if progress is not None:
                    progress(n, len(parts))

        first = min(results, key=lambda r: r.col0)
        n_bp = sum(r.backprojections for r in results)
        check_some_backprojection(n_bp, drive_path, options, float(first.params["half_width_rad"]), trajectory_path,
                                  config)
        # each tile reads the frames its columns need: the frames left out are those any tile found damaged
        damaged = sorted({i for r in results for i in r.damaged_frame_index})
        frames_used = first.frames_used + len(first.damaged_frame_index) - len(damaged)
        skipped = {k: v for k, v in first.frames_skipped.items() if k != DAMAGED_FRAMES}
        if damaged:
            skipped[DAMAGED_FRAMES] = len(damaged)
        warnings = [damaged_frames_warning(drive_path, str(first.params["radar"]), damaged)] if damaged else []
        warnings += list(dict.fromkeys(w for r in sorted(results, key=lambda r: r.col0) for w in r.warnings))
        warnings += unfocused_radars(drive_path, options)
        # the whole image's brightest pixel (of equals, the first row-major, as np.argmax over one piece), then the
        # check that its channels add coherently, as focus makes it on one piece: two patch focuses
        t0 = time.perf_counter()
        _, row, col = max((r.brightest for r in results), key=lambda b: (b[0], -b[1], -b[2]))
        incoherent = channels_incoherent_warning(drive_path, trajectory_path, config, options, grid, (row, col),
                                                 len(first.params["channel_pairs"]))
        warnings += [incoherent] if incoherent else []
        timings["channel_check"] += time.perf_counter() - t0
        writer.set_metadata({**first.params, "backprojections": n_bp, "frames_used": frames_used,
                             "frames_damaged": len(damaged)},
                            {**first.provenance, "tiles": len(parts), "warnings": warnings})
        t0 = time.perf_counter()
    timings["write"] += time.perf_counter() - t0  # closing: tags, quicklook, flush, rename
    return FocusReport({k: str(v) for k, v in writer.paths.items()}, grid.shape, frames_used, skipped, n_bp,
                       dict(timings), first.drive_s, warnings, grid_enu_box(grid))


def _token() -> str:
    import uuid

    return uuid.uuid4().hex[:8]


__all__ = ["GridTile", "TileResult", "focus_tile", "focus_tiled", "plan_grid", "split_grid"]
