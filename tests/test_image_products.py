"""Focused-image products: GeoTIFF georeferencing (UTM), image.h5 round trip, PNG quicklook, atomic writes."""

from __future__ import annotations

import json
import math
import os
import struct
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
import rasterio
from numpy.typing import NDArray
from pyproj import Proj, Transformer
from typer.testing import CliRunner

from autosar_cli import __version__
from autosar_cli.cli import app
from autosar_cli.nav.geodesy import GeodeticOrigin
from autosar_cli.sar.grid import FocusGrid
from autosar_cli.store import image as image_mod
from autosar_cli.store.atomic import atomic_output
from autosar_cli.store.image import (
    FocusedImage,
    ImageFormatError,
    ImageWriter,
    read_image,
    utm_geotransform,
    write_image,
)

runner = CliRunner()
ORIGIN = GeodeticOrigin(45.06, 7.66, 240.0)  # Turin: UTM zone 32N, 1.34 deg west of the central meridian
PIXEL = 0.04
C30, S30 = math.cos(math.radians(30.0)), math.sin(math.radians(30.0))
BRIGHT = {(17, 33): 1000.0 * np.exp(0.7j), (120, 250): 400.0 * np.exp(-2.1j), (199, 5): 150.0 + 0j}
ZERO = (60, 60)
PARAMS = {"method": "backprojection", "pixel_m": PIXEL, "upsample": 8, "autofocus": False,
          "band_hz": [76.0e9, 80.0e9], "window": {"range": "hann", "azimuth": None}, "seed": None}


def rotated_grid() -> FocusGrid:
    """250 x 400 px at 4 cm, columns at 30 deg north of east, rows on the right-hand side of travel."""
    return FocusGrid((7.5, -3.25), (C30, S30), (S30, -C30), PIXEL, 400, 250, -1.5)


def make_image(grid: FocusGrid, seed: int = 3) -> NDArray[np.complex64]:
    """Complex noise (|z| ~ 0.5), the BRIGHT pixels and one exact zero where they fit in the grid."""
    rng = np.random.default_rng(seed)
    z = (0.5 * (rng.normal(size=grid.shape) + 1j * rng.normal(size=grid.shape))).astype(np.complex64)
    for (r, c), v in [*BRIGHT.items(), (ZERO, 0)]:
        if r < grid.n_across and c < grid.n_along:
            z[r, c] = v
    return z


def utm_of(grid: FocusGrid, row: float, col: float, epsg: int) -> np.ndarray:
    """Independent reference: ENU -> geodetic (pymap3d) -> UTM (pyproj), pixel centre (row, col)."""
    lat, lon, _ = ORIGIN.to_geodetic(grid.pixel_enu(row, col))
    e, n = Transformer.from_crs("EPSG:4326", f"EPSG:{epsg}", always_xy=True).transform(lon, lat)
    return np.array([e, n])


@pytest.fixture(scope="module")
def rotated_products(tmp_path_factory: pytest.TempPathFactory) -> tuple[FocusedImage, dict[str, Path]]:
    grid = rotated_grid()
    img = FocusedImage(make_image(grid), grid, ORIGIN, PARAMS, {"inputs": ["drive.h5"], "command": "autosar focus"})
    out = tmp_path_factory.mktemp("img") / "scene"
    return img, write_image(out, img)


def test_products_are_written_next_to_base(rotated_products: tuple[FocusedImage, dict[str, Path]]) -> None:
    _, paths = rotated_products
    assert {k: p.name for k, p in paths.items()} == {"tif": "scene.tif", "h5": "scene.h5", "png": "scene.png"}
    assert all(p.is_file() for p in paths.values())
    assert not list(paths["tif"].parent.glob("*partial*"))
    assert not list(paths["tif"].parent.glob("*.aux.xml"))  # everything is inside the GeoTIFF


def test_geotiff_lands_on_the_utm_positions_of_the_pixels(
        rotated_products: tuple[FocusedImage, dict[str, Path]]) -> None:
    img, paths = rotated_products
    assert ORIGIN.utm_epsg() == 32632
    with rasterio.open(paths["tif"]) as ds:
        assert ds.crs.to_epsg() == 32632
        assert (ds.height, ds.width) == img.grid.shape == (250, 400)
        assert ds.dtypes == ("float32",)
        band = ds.read(1)
        t = ds.transform
        for (row, col), z in BRIGHT.items():
            got = np.array(t @ (col + 0.5, row + 0.5))
            assert np.hypot(*(got - utm_of(img.grid, row, col, 32632))) < 0.01
            assert band[row, col] == pytest.approx(20 * np.log10(abs(z)), abs=1e-4)
        # the pixel (0, 0) outer corner is half a pixel before pixel (0, 0)'s centre on both grid axes
        assert np.hypot(*(np.array(t @ (0, 0)) - utm_of(img.grid, -0.5, -0.5, 32632))) < 0.01
        # the transform is rotated: the column axis follows the grid's 30 deg (plus ~ -1 deg grid convergence)
        assert math.degrees(math.atan2(t.d, t.a)) == pytest.approx(30.0, abs=1.5)
        assert math.hypot(t.a, t.d) == pytest.approx(PIXEL, rel=1e-3)
        assert np.unravel_index(np.nanargmax(band), band.shape) == (17, 33)


def test_geotiff_nodata_tags_and_layout(rotated_products: tuple[FocusedImage, dict[str, Path]]) -> None:
    img, paths = rotated_products
    with rasterio.open(paths["tif"]) as ds:
        band = ds.read(1)
        assert math.isnan(ds.nodata)
        assert np.isnan(band[ZERO])
        assert np.isnan(band).sum() == 1  # only the zero pixel
        assert ds.read_masks(1)[ZERO] == 0 and ds.read_masks(1)[0, 0] == 255
        noise = np.delete(band.ravel(), np.ravel_multi_index(ZERO, band.shape))
        ref = 20 * np.log10(np.abs(np.delete(img.image.ravel(), np.ravel_multi_index(ZERO, band.shape))))
        np.testing.assert_allclose(noise, ref, atol=1e-4)
        tags = ds.tags()
        assert tags["units"] == "dB, 20 log10 |complex image|"
        assert tags["autosar_version"] == __version__
        assert json.loads(tags["param_band_hz"]) == PARAMS["band_hz"]
        assert json.loads(tags["param_method"]) == "backprojection"
        assert json.loads(tags["provenance"])["command"] == "autosar focus"
        assert ds.profile["tiled"] and ds.compression.name.lower() == "deflate"


@pytest.mark.filterwarnings("ignore:Use `@` matmul:PendingDeprecationWarning")  # rasterio bounds
def test_north_up_grid_has_only_convergence_rotation(tmp_path: Path) -> None:
    # pixel (0, 0)'s centre at the ENU origin itself: its UTM position inverts to the origin's lat/lon
    grid = FocusGrid((0.0, 0.0), (1.0, 0.0), (0.0, -1.0), PIXEL, 300, 200, 0.0)
    t, epsg, residual = utm_geotransform(grid, ORIGIN)
    assert epsg == 32632 and residual < 1e-4
    assert abs(t.b) < 0.02 * PIXEL and abs(t.d) < 0.02 * PIXEL
    assert t.a == pytest.approx(PIXEL, rel=1e-3) and t.e == pytest.approx(-PIXEL, rel=1e-3)
    # the small rotation is the meridian convergence (~ -0.95 deg here), not noise
    conv = Proj("EPSG:32632").get_factors(ORIGIN.lon_deg, ORIGIN.lat_deg).meridian_convergence
    assert abs(conv) > 0.5
    assert abs(math.degrees(math.atan2(t.d, t.a))) == pytest.approx(abs(conv), abs=0.01)
    e, n = t @ (0.5, 0.5)
    lon, lat = Transformer.from_crs("EPSG:32632", "EPSG:4326", always_xy=True).transform(e, n)
    assert lat == pytest.approx(ORIGIN.lat_deg, abs=1e-8) and lon == pytest.approx(ORIGIN.lon_deg, abs=1e-8)

    img = FocusedImage(make_image(grid), grid, ORIGIN, {})
    paths = write_image(tmp_path / "north", img)
    with rasterio.open(paths["tif"]) as ds:
        assert ds.transform.almost_equals(t, precision=1e-9)
        corners = np.array([utm_of(grid, r, c, 32632) for r in (-0.5, 199.5) for c in (-0.5, 299.5)])
        np.testing.assert_allclose(ds.bounds, [*corners.min(axis=0), *corners.max(axis=0)], atol=0.01)


def test_affine_residual_is_sub_millimetre_over_300_m() -> None:
    grid = FocusGrid((-150.0, 40.0), (C30, S30), (S30, -C30), 1.0, 300, 300, 0.0)
    t, _, residual = utm_geotransform(grid, ORIGIN)
    assert residual < 1e-3
    # the fit holds between its lattice points too
    for row, col in [(37.0, 211.0), (150.0, 150.0), (299.0, 0.0), (263.5, 88.25)]:
        assert np.hypot(*(np.array(t @ (col + 0.5, row + 0.5)) - utm_of(grid, row, col, 32632))) < 1e-3


def test_h5_round_trip(rotated_products: tuple[FocusedImage, dict[str, Path]]) -> None:
    img, paths = rotated_products
    back = read_image(paths["h5"])
    assert back.image.dtype == np.complex64
    np.testing.assert_array_equal(back.image, img.image)
    assert back.grid == img.grid
    assert back.origin == img.origin
    assert back.params == PARAMS
    assert back.provenance == img.provenance
    with h5py.File(paths["h5"], "r") as f:
        assert f.attrs["format"] == "autosar-image" and int(f.attrs["format_version"]) == 1
        assert f.attrs["autosar_version"] == __version__
        assert int(f.attrs["utm_epsg"]) == 32632
        with rasterio.open(paths["tif"]) as ds:
            np.testing.assert_allclose(f.attrs["geotransform"], ds.transform.to_gdal(), rtol=0, atol=1e-9)
            assert rasterio.crs.CRS.from_wkt(f.attrs["crs_wkt"]) == ds.crs
        along, across = f["along_m"][()], f["across_m"][()]
        assert along.shape == (400,) and across.shape == (250,)
        row, col = 120, 250
        enu = np.asarray(img.grid.origin) + along[col] * np.asarray(img.grid.along) + across[row] * np.asarray(
            img.grid.across)
        np.testing.assert_allclose(enu, img.grid.pixel_enu(row, col)[:2], atol=1e-12)
        ds = f["image"]
        assert ds.chunks is not None and ds.chunks[0] <= 256 and ds.chunks[1] <= 256  # partial reads stay cheap
        assert ds.id.get_storage_size() <= 1.02 * ds.nbytes  # chunks tile the image: little padding stored


def test_png_quicklook(rotated_products: tuple[FocusedImage, dict[str, Path]]) -> None:
    _, paths = rotated_products
    head = paths["png"].read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", head[16:24])
    assert 600 <= width <= 3000 and 300 <= height <= 2000


def test_failed_tif_write_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def boom(*args: object, **kwargs: object) -> dict[str, str]:
        assert (tmp_path / f"scene.partial-{os.getpid()}.tif").exists()  # the failure happens half-written
        raise RuntimeError("disk full")

    monkeypatch.setattr(image_mod, "_tif_tags", boom)
    grid = rotated_grid()
    with pytest.raises(RuntimeError, match="disk full"):
        write_image(tmp_path / "scene", FocusedImage(make_image(grid), grid, ORIGIN, PARAMS))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("damage", "said"), [("cut", "(it does not open)"), ("zeroed", "(columns 256-511 differ)"),
                                              ("end zeroed", "(columns 512-599 differ)")])
def test_a_geotiff_cut_as_it_closed_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                   damage: str, said: str) -> None:
    """libtiff's writes refused as the GeoTIFF closes (a disk that fills then) raise nothing through rasterio: the
    cut file came into place beside a whole image.h5 and PNG, a product that looked complete. Now the GeoTIFF is
    read back against its columns' checksums before anything comes into place: an error naming it, nothing left.
    Here the file, the moment it is closed, is cut to 97 % of its bytes (its directory, written last, lost), or
    holds zeros where 4 kB of its tiles were (blocks the disk did not take)."""
    import contextlib

    real_open = image_mod._open_geotiff

    @contextlib.contextmanager
    def damaged_as_it_closes(path: Path, *args: object):  # noqa: ANN202
        with real_open(path, *args) as ds:
            yield ds
        size = path.stat().st_size
        if damage == "cut":
            os.truncate(path, int(size * 0.97))
            return
        with open(path, "r+b") as f:  # the header and directories are at the start and the end
            f.seek(size // 2 if damage == "zeroed" else size * 3 // 4)
            f.write(bytes(4096))

    monkeypatch.setattr(image_mod, "_open_geotiff", damaged_as_it_closes)
    grid = FocusGrid((0.0, 0.0), (1.0, 0.0), (0.0, -1.0), PIXEL, 600, 300, 0.0)
    with pytest.raises(OSError, match=r"scene.tif: the GeoTIFF did not read back as written \(") as failed:
        write_image(tmp_path / "scene", FocusedImage(make_image(grid), grid, ORIGIN, PARAMS))
    assert said in str(failed.value) and not str(failed.value).startswith("[Errno"), str(failed.value)
    assert list(tmp_path.iterdir()) == []


def test_existing_outputs_need_overwrite(tmp_path: Path) -> None:
    grid = FocusGrid((0.0, 0.0), (1.0, 0.0), (0.0, -1.0), PIXEL, 40, 30, 0.0)
    first = FocusedImage(make_image(grid, seed=1), grid, ORIGIN, {"run": 1})
    paths = write_image(tmp_path / "out", first)
    (tmp_path / "other.png").write_bytes(b"x")
    with pytest.raises(FileExistsError, match="--overwrite") as exc:
        write_image(tmp_path / "other", first)
    assert "other.png" in str(exc.value)
    assert not (tmp_path / "other.tif").exists()  # refused before writing anything
    second = FocusedImage(make_image(grid, seed=2), grid, ORIGIN, {"run": 2})
    with pytest.raises(FileExistsError, match="--overwrite"):
        write_image(tmp_path / "out", second)
    assert read_image(paths["h5"]).params == {"run": 1}
    write_image(tmp_path / "out", second, overwrite=True)
    back = read_image(paths["h5"])
    assert back.params == {"run": 2}
    np.testing.assert_array_equal(back.image, second.image)
    with rasterio.open(paths["tif"]) as ds:
        assert ds.read(1)[20, 3] == pytest.approx(20 * np.log10(abs(second.image[20, 3])), abs=1e-4)


def test_atomic_output_keeps_the_old_file_on_failure(tmp_path: Path) -> None:
    target = tmp_path / "a.txt"
    target.write_text("old")
    with pytest.raises(ValueError, match="half"), atomic_output(target, overwrite=True) as tmp:
        assert tmp.name == f"a.partial-{os.getpid()}.txt"
        tmp.write_text("half")
        raise ValueError("half")
    assert target.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]
    with atomic_output(target, overwrite=True) as tmp:
        tmp.write_text("new")
        assert target.read_text() == "old"  # not visible until complete
    assert target.read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]


def test_read_image_rejects_other_files(tmp_path: Path, rotated_products: tuple[FocusedImage, dict[str, Path]]
                                        ) -> None:
    other = tmp_path / "trajectory.h5"
    with h5py.File(other, "w") as f:
        f.attrs["format"] = "autosar-trajectory"
        f["t_ns"] = np.arange(3)
    with pytest.raises(ImageFormatError, match="trajectory.h5") as exc:
        read_image(other)
    assert "not an image.h5 (it is a trajectory.h5 autosar wrote)" in str(exc.value)

    text = tmp_path / "notes.h5"
    text.write_text("not hdf5")
    with pytest.raises(ImageFormatError, match="notes.h5.*not an HDF5"):
        read_image(text)

    newer = tmp_path / "newer.h5"
    newer.write_bytes(rotated_products[1]["h5"].read_bytes())
    with h5py.File(newer, "r+") as f:
        f.attrs["format_version"] = 2
    with pytest.raises(ImageFormatError, match="newer.h5.*version 2"):
        read_image(newer)


def test_image_must_match_the_grid() -> None:
    grid = rotated_grid()
    with pytest.raises(ValueError, match="grid shape"):
        FocusedImage(np.zeros((400, 250), np.complex64), grid, ORIGIN, {})


def test_strip_writer_equals_one_piece(tmp_path: Path) -> None:
    """Column strips in any order (boundaries off the GeoTIFF blocks and the quicklook's 3-pixel pools) give
    the products of the whole image at once: same GeoTIFF, same image.h5, same quicklook PNG."""
    grid = FocusGrid((0.0, 0.0), (1.0, 0.0), (0.0, -1.0), PIXEL, 3000, 64, 0.0)  # quicklook pools 3 x 3 px
    img = FocusedImage(make_image(grid), grid, ORIGIN, PARAMS, {"tiles": 5})
    whole = write_image(tmp_path / "whole", img)
    bounds = [0, 700, 1301, 1302, 2048, 3000]
    with ImageWriter(tmp_path / "strips", grid, ORIGIN) as w:
        for k in (3, 0, 4, 2, 1):  # as tiles come back from a cluster
            c0, c1 = bounds[k], bounds[k + 1]
            w.write_columns(c0, img.image[:, c0:c1])
        w.set_metadata(PARAMS, {"tiles": 5})
    strips = w.paths
    back = read_image(strips["h5"])
    np.testing.assert_array_equal(back.image, img.image)
    assert back.params == read_image(whole["h5"]).params and back.provenance == {"tiles": 5}
    with rasterio.open(whole["tif"]) as a, rasterio.open(strips["tif"]) as b:
        assert a.transform == b.transform and a.crs == b.crs and a.tags() == b.tags()
        np.testing.assert_array_equal(a.read(1), b.read(1))
        assert np.isnan(b.read(1)[ZERO])  # the exact zero is nodata
    assert strips["png"].read_bytes() == whole["png"].read_bytes()


def test_strip_writer_leaves_nothing_when_incomplete_or_failing(tmp_path: Path) -> None:
    grid = FocusGrid((0.0, 0.0), (1.0, 0.0), (0.0, -1.0), PIXEL, 64, 32, 0.0)
    img = make_image(grid)
    with pytest.raises(ValueError, match="image incomplete, 14 columns never written"):
        with ImageWriter(tmp_path / "a", grid, ORIGIN) as w:
            w.write_columns(0, img[:, :50])
            w.set_metadata(PARAMS)
    with pytest.raises(ValueError, match="some were written already"):
        with ImageWriter(tmp_path / "b", grid, ORIGIN) as w:
            w.write_columns(0, img[:, :50])
            w.write_columns(40, img[:, 40:])
    with pytest.raises(ValueError, match="does not fit the grid"):
        with ImageWriter(tmp_path / "c", grid, ORIGIN) as w:
            w.write_columns(60, img[:, :10])
    with pytest.raises(RuntimeError, match="worker lost"):
        with ImageWriter(tmp_path / "d", grid, ORIGIN) as w:
            w.write_columns(0, img)
            raise RuntimeError("worker lost")
    assert list(tmp_path.iterdir()) == []


def _tile(tif: Path, row: int, col: int) -> tuple[int, int, Any]:
    """(byte offset, bytes, window) of tile (row, col) of band 1 of ``tif``."""
    with rasterio.open(tif) as src:
        return (int(src.get_tag_item(f"BLOCK_OFFSET_{col}_{row}", "TIFF", bidx=1)),
                int(src.get_tag_item(f"BLOCK_SIZE_{col}_{row}", "TIFF", bidx=1)), src.block_window(1, row, col))


def test_the_geotiff_carries_checksums_that_name_what_is_damaged(
        tmp_path: Path, rotated_products: tuple[FocusedImage, dict[str, Path]]) -> None:
    """TIFF has no checksum of its tags, and its deflate tiles do not always fail where damaged: a byte flipped in
    the middle of a tile's stream read as other pixels without an error from GDAL. The GeoTIFF carries the CRC-32
    of each column and of its georeference (tif_checksum); ``verify_geotiff`` names a tile that does not decode,
    the columns whose pixels differ from those written, a moved georeference and a damaged checksum tag."""
    from autosar_cli.store.tif_checksum import COLUMNS_TAG, verify_geotiff

    img, paths = rotated_products
    tif = paths["tif"]
    found = verify_geotiff(tif)
    assert found.intact and found.columns == img.grid.shape[1] == 400 and found.tiles == 2 * 2
    at, size, window = _tile(tif, 0, 1)
    assert (window.col_off, window.row_off, window.width, window.height) == (256, 0, 144, 240)

    def damaged(name: str, change: Any) -> Path:
        copy = tmp_path / name
        copy.write_bytes(tif.read_bytes())
        change(copy)
        return copy

    def flip(offset: int) -> Any:
        def at_byte(copy: Path) -> None:
            data = bytearray(copy.read_bytes())
            data[offset] ^= 0x5A
            copy.write_bytes(bytes(data))
        return at_byte

    outcomes = [verify_geotiff(damaged(f"tile_{k}.tif", flip(at + size * k // 8))) for k in range(1, 8)]
    for f in outcomes:
        assert not f.intact and f.georeference_intact and f.tags_intact
        gdal_says = f"{Path(f.path).name}, band 1: IReadBlock failed at X offset 1, Y offset 0: TIFFReadEncodedTile()"
        assert f.unreadable in ([], [f"rows 0-239, columns 256-399: {gdal_says} failed."])
        assert all(256 <= a < b <= 400 for a, b in f.damaged_columns) and bool(f.unreadable) != bool(f.damaged_columns)
    assert any(f.damaged_columns for f in outcomes)  # decoded without an error: other pixels, told by their CRCs

    def one_pixel(copy: Path) -> None:
        with rasterio.open(copy, "r+") as dst:
            dst.write(np.array([[12.5]], np.float32), 1, window=rasterio.windows.Window(123, 45, 1, 1))
    assert verify_geotiff(damaged("pixel.tif", one_pixel)).damaged_columns == [(123, 124)]

    def moved(copy: Path) -> None:
        with rasterio.open(copy, "r+") as dst:
            dst.transform = dst.transform @ dst.transform.translation(0.0, 25.0)  # a flipped bit: one metre off
    found = verify_geotiff(damaged("moved.tif", moved))
    assert not found.georeference_intact and not found.damaged_columns and not found.intact

    def tag(copy: Path) -> None:
        with rasterio.open(copy, "r+") as dst:
            text = dst.tags()[COLUMNS_TAG]
            dst.update_tags(**{COLUMNS_TAG: text[:40] + ("B" if text[40] != "B" else "C") + text[41:]})
    found = verify_geotiff(damaged("tag.tif", tag))
    assert not found.tags_intact and found.georeference_intact and not found.intact

    r = runner.invoke(app, ["info", str(tmp_path / "pixel.tif"), "--verify"])
    assert r.exit_code == 1 and "columns 123-123 differ from those written" in r.stderr
    r = runner.invoke(app, ["info", str(tif), "--verify", "--json"])
    assert r.exit_code == 0 and json.loads(r.stdout)["intact"]


def test_a_geotiff_without_autosars_checksums_is_not_called_intact(tmp_path: Path) -> None:
    tif = tmp_path / "other.tif"
    with rasterio.open(tif, "w", driver="GTiff", width=20, height=10, count=1, dtype="float32", crs="EPSG:32632",
                       transform=rasterio.Affine(0.04, 0, 400000, 0, -0.04, 5000000)) as dst:
        dst.write(np.ones((1, 10, 20), np.float32))
    r = runner.invoke(app, ["info", str(tif), "--verify"])
    assert r.exit_code == 1 and "carries no autosar checksum" in r.stderr


def pyproj_utm(origin: GeodeticOrigin, enu: NDArray[np.float64], epsg: int) -> NDArray[np.float64]:
    """UTM easting, northing (..., 2) of ENU points (..., 3) about ``origin`` through pyproj alone (not the package's
    pymap3d geodesy): the origin to ECEF (EPSG:4979 -> 4978), the tangent-plane rotation, ECEF -> WGS-84 geodetic,
    geodetic -> ``EPSG:<epsg>``."""
    x0 = np.array(Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True).transform(
        origin.lon_deg, origin.lat_deg, origin.height_m))
    la, lo = math.radians(origin.lat_deg), math.radians(origin.lon_deg)
    rot = np.array([[-math.sin(lo), math.cos(lo), 0.0],
                    [-math.sin(la) * math.cos(lo), -math.sin(la) * math.sin(lo), math.cos(la)],
                    [math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)]])
    ecef = x0 + np.asarray(enu, np.float64) @ rot
    lon, lat, _ = Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True).transform(*ecef.T)
    return np.stack(Transformer.from_crs("EPSG:4326", f"EPSG:{epsg}", always_xy=True).transform(lon, lat), axis=-1)


@pytest.mark.parametrize(("lat", "lon", "epsg"), [
    (-33.45, -72.0001, 32718),  # Chile, 9 m west of the zone 18/19 boundary: the image lies across it
    (-16.8, 180.0, 32760),  # Fiji, on the antimeridian: zone 60S (zone "61" would be EPSG:32761, UPS South)
    (16.8, 180.0, 32660),  # and north of the equator: zone 60N (not EPSG:32661, UPS North)
    (-16.8, -180.0, 32701),
    (0.0, 3.0, 32631),
])
def test_geotiff_is_in_the_utm_zone_of_the_origin_anywhere(tmp_path: Path, lat: float, lon: float, epsg: int) -> None:
    """South of the equator, west of Greenwich, across a zone boundary and on the antimeridian: the GeoTIFF states
    the UTM zone pyproj's database gives the origin, and each pixel lands where pyproj alone puts its ENU position.
    The georeference is read twice, through GDAL (rasterio) and from the TIFF's own tags (Pillow): the
    ModelTransformationTag, the ProjectedCSTypeGeoKey and GTRasterTypeGeoKey = 1 (PixelIsArea, so the transform's
    (0, 0) is the outer corner of pixel (0, 0): PixelIsPoint would move every pixel by half of one, 2 cm)."""
    from PIL import Image
    from pyproj import CRS
    from pyproj.aoi import AreaOfInterest
    from pyproj.database import query_utm_crs_info

    origin = GeodeticOrigin(lat, lon, 35.0)
    zones = {int(z.code) for z in query_utm_crs_info(datum_name="WGS 84", area_of_interest=AreaOfInterest(
        lon, lat, lon, lat))}
    assert epsg in zones
    grid = rotated_grid()
    paths = write_image(tmp_path / "scene", FocusedImage(make_image(grid), grid, origin, PARAMS))
    with rasterio.open(paths["tif"]) as ds:
        assert ds.crs.to_epsg() == epsg
        assert f"UTM zone {epsg % 100}{'N' if epsg < 32700 else 'S'}" in CRS.from_wkt(ds.crs.to_wkt()).name
        t = ds.transform
    with Image.open(paths["tif"]) as tif:
        tags = tif.tag_v2
        model = np.array(tags[34264]).reshape(4, 4)  # ModelTransformationTag: raster (col, row, 0, 1) -> (E, N, 0, 1)
        keys = np.array(tags[34735][4:]).reshape(-1, 4)  # GeoKeyDirectoryTag: (key, location, count, value) rows
    geokeys = {int(k): int(v) for k, loc, _, v in keys if loc == 0}
    assert geokeys[1025] == 1 and geokeys[3072] == epsg  # GTRasterTypeGeoKey: PixelIsArea; ProjectedCSTypeGeoKey
    np.testing.assert_allclose(model[:2, [0, 1, 3]], [[t.a, t.b, t.c], [t.d, t.e, t.f]], rtol=0, atol=1e-9)
    rows, cols = np.meshgrid([0, 17, 120, 249], [0, 33, 250, 399], indexing="ij")
    truth = pyproj_utm(origin, grid.pixel_enu(rows.ravel(), cols.ravel()), epsg)
    for (row, col), want in zip(zip(rows.ravel(), cols.ravel(), strict=True), truth, strict=True):
        got = model[:2] @ [col + 0.5, row + 0.5, 0.0, 1.0]  # the pixel's centre, as the TIFF's tags alone place it
        assert np.hypot(*(got - want)) < 1e-3, (row, col, got - want)
    with h5py.File(paths["h5"], "r") as f:
        assert int(f.attrs["utm_epsg"]) == epsg
