"""Back-projection kernel, stripmap windows and grids against straightforward float64 references."""

from __future__ import annotations

import math

import numpy as np
import pytest
import reference

from autosar_cli.sar.backprojection import PulseBlock, backproject, backproject_block
from autosar_cli.sar.grid import GridError, box_grid, track_grid
from autosar_cli.sar.stripmap import block_context, look_angle_margin_m, processed_half_width, stripmap_windows

C = 299_792_458.0
F_CENTRE = 78.5e9
CYCLES_PER_M = F_CENTRE / C
BIN_M = 0.0125  # bistatic path per bin: 8x upsampled ScanBrick profiles
N_BINS = 4400  # up to 55 m of bistatic path
HALF_WIDTH = processed_half_width(C / F_CENTRE, 0.04)


def _antennas(track: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """10 antenna positions per pulse as the default 8 channels use the ScanBrick (3 Tx x 4 Rx): Tx0 and Tx2, 2 lambda
    apart, and the 4 Rx at each of their chirps (ENU m).

    The radar looks right, 45 deg forward; antennas spread along its horizontal row by lambda/2, and the
    Rx of the second chirp are displaced by the motion during 120 us (about 0.6 mm).
    """
    lam = C / 77e9
    row = np.array([math.cos(-math.pi / 4 + math.pi / 2), math.sin(-math.pi / 4 + math.pi / 2)])
    fwd = np.stack([np.cos(heading), np.sin(heading)], axis=1)
    lever = np.array([2.2, -0.75])
    base = track + fwd * lever[0] + np.stack([-fwd[:, 1], fwd[:, 0]], axis=1) * lever[1]
    step = np.gradient(track, axis=0)  # per pulse (~1 ms)
    out = []
    for y_tx, chirp in ((0.0, 0), (2 * lam, 2)):
        out.append(base + np.outer(np.ones(len(track)), row) * y_tx + step * chirp * 0.06)
    for chirp in (0, 2):
        for r in range(4):
            out.append(base + np.outer(np.ones(len(track)), row) * r * lam / 2 + step * chirp * 0.06)
    ant = np.stack(out)
    return np.concatenate([ant, np.full(ant.shape[:2] + (1,), 0.5)], axis=2)


CHANNELS = np.array([[t, 2 + 4 * t + r] for t in (0, 1) for r in range(4)])


def _case(track: np.ndarray, heading: np.ndarray, n_pix: int, rng: np.random.Generator, *,
          window: bool = True) -> tuple[np.ndarray, ...]:
    ant = _antennas(track, heading)
    # random profiles, uniform in float32, which the kernel reads anyway (normal draws took most of the test's time)
    shape = (len(CHANNELS), N_BINS, len(track))
    prof = np.empty(shape, np.complex64)
    prof.real = rng.random(shape, dtype=np.float32) - 0.5
    prof.imag = rng.random(shape, dtype=np.float32) - 0.5
    # pixels on the right of the track, 0.5-27 m ground range, along the middle of the track
    k = rng.integers(len(track) // 4, 3 * len(track) // 4, n_pix)
    rng_m = rng.uniform(0.5, 27.0, n_pix)
    right = np.stack([np.sin(heading[k]), -np.cos(heading[k])], axis=1)
    pix = np.concatenate([track[k] + right * rng_m[:, None], np.full((n_pix, 1), 0.5)], axis=1)
    vel = np.concatenate([np.gradient(ant[0, :, :2], axis=0), np.zeros((len(track), 1))], axis=1)
    if window:
        win = stripmap_windows(pix, ant[0], vel, HALF_WIDTH)
    else:  # a wide, squinted aperture: up to +-60 deg of squint
        win = np.stack([np.maximum(k - 1500, 0), np.minimum(k + 1500, len(track))], axis=1)
    return prof, ant, pix, win


def _relative_error_db(got: np.ndarray, ref: np.ndarray) -> float:
    return 10 * math.log10(np.sum(np.abs(got - ref) ** 2) / np.sum(np.abs(ref) ** 2))


def _check(prof, ant, pix, win) -> float:
    kw = dict(range0_m=0.0, bin_m=BIN_M, cycles_per_m=CYCLES_PER_M)
    got = backproject(prof, ant, CHANNELS, pix, win, **kw)
    ref = reference.tdbp(prof, ant, CHANNELS, pix, win, **kw)
    assert np.all(win[:, 1] > win[:, 0])
    return _relative_error_db(got, ref)


def test_kernel_equals_float64_reference_straight_track() -> None:
    rng = np.random.default_rng(1)
    n = 3000  # 12 m at 4 mm per pulse
    track = np.stack([np.arange(n) * 0.004, np.zeros(n)], axis=1)
    err = _check(*_case(track, np.zeros(n), 120, rng))
    assert err < -50.0, err


def test_kernel_equals_float64_reference_curved_track() -> None:
    # test3-like zig-zag: +-1.5 m lateral swing over 20 m, heading up to ~25 deg off the mean
    rng = np.random.default_rng(2)
    n = 4000
    s = np.arange(n) * 0.005
    y = 1.5 * np.sin(2 * np.pi * s / 20.0)
    track = np.stack([s, y], axis=1)
    heading = np.arctan(1.5 * 2 * np.pi / 20.0 * np.cos(2 * np.pi * s / 20.0))
    err = _check(*_case(track, heading, 120, rng))
    assert err < -50.0, err


def test_kernel_equals_reference_with_large_range_migration() -> None:
    """Windows far wider than the stripmap beam: chunks split and the exact path takes over."""
    rng = np.random.default_rng(3)
    n = 3200
    track = np.stack([np.arange(n) * 0.004, np.zeros(n)], axis=1)
    prof, ant, pix, win = _case(track, np.zeros(n), 40, rng, window=False)
    err = _check(prof, ant, pix, win)
    assert err < -50.0, err



@pytest.mark.parametrize("seed", [5, 6])
def test_kernel_equals_reference_with_every_pulse_and_coarse_bins(seed: int) -> None:
    """The benchmark's fixed case in small: one channel, every pulse for every pixel at up to 70 deg of squint,
    10 cm bins, so range migration (up to 20 bins) cuts six-row chunks short and the per-vector rows take over;
    antennas jittered by 0.3 mm (vibration), 600 pulses (a partial last vector), pixels across the profile's
    far end. The same with eight channels (chunks cut instead)."""
    rng = np.random.default_rng(seed)
    n = 600
    track = np.stack([np.arange(n) * 0.004, np.zeros(n)], axis=1)
    ant = _antennas(track, np.zeros(n)) + rng.normal(0.0, 0.3e-3, (10, n, 3))
    n_bins = 220  # 22 m of bistatic path: pixels beyond ~10 m ground range fall off the end
    prof = (rng.standard_normal((len(CHANNELS), n_bins, n))
            + 1j * rng.standard_normal((len(CHANNELS), n_bins, n))).astype(np.complex64)
    pix = np.stack([rng.uniform(-4.0, 6.4, 150), -rng.uniform(1.0, 12.0, 150), np.full(150, 0.5)], axis=1)
    win = np.tile([0, n], (len(pix), 1))
    kw = dict(range0_m=0.0, bin_m=0.1, cycles_per_m=CYCLES_PER_M)
    for chans, profs in ((CHANNELS[:1], prof[:1]), (CHANNELS, prof)):
        got = backproject(profs, ant, chans, pix, win, **kw)
        ref = reference.tdbp(profs, ant, chans, pix, win, **kw)
        assert np.sum(ref == 0) < 10  # most pixels see part of the profiles
        assert _relative_error_db(got, ref) < -50.0, len(chans)

def test_kernel_equals_reference_at_the_end_of_the_profiles() -> None:
    """Profiles that stop at 30 m of bistatic path while pixels reach 27 m of ground range (54 m of path):
    pixels beyond the last bin get exactly nothing, those across it what the reference gives."""
    rng = np.random.default_rng(4)
    n = 3000
    track = np.stack([np.arange(n) * 0.004, np.zeros(n)], axis=1)
    prof, ant, pix, win = _case(track, np.zeros(n), 300, rng)
    prof = np.ascontiguousarray(prof[:, :2400])  # 30 m of bistatic path
    kw = dict(range0_m=0.0, bin_m=BIN_M, cycles_per_m=CYCLES_PER_M)
    got = backproject(prof, ant, CHANNELS, pix, win, **kw)
    ref = reference.tdbp(prof, ant, CHANNELS, pix, win, **kw)
    # the track runs along y = 0, pixels at y = -ground range, the antennas 0.75 m right of the track
    beyond = -pix[:, 1] > 15.8  # every channel's path > 30.1 m
    assert beyond.sum() > 50 and (~beyond).sum() > 50
    assert np.all(ref[beyond] == 0) and np.all(got[beyond] == 0)
    assert _relative_error_db(got[~beyond], ref[~beyond]) < -50.0

def test_point_target_focuses_at_its_position() -> None:
    """Noise-free profiles of one point (sinc in range, exact carrier phase) focus on it, to the millimetre."""
    n = 600
    track = np.stack([np.arange(n) * 0.004, np.zeros(n)], axis=1)
    ant = _antennas(track, np.zeros(n))
    target = np.array([1.2 + 2.2, -8.0, 0.5])
    path = (np.linalg.norm(ant[CHANNELS[:, 0]] - target, axis=2) + np.linalg.norm(ant[CHANNELS[:, 1]] - target,
                                                                                      axis=2))  # (C, P)
    b = np.arange(N_BINS)[None, :, None] * BIN_M
    prof = (np.sinc((b - path[:, None, :]) / 0.1) * np.exp(2j * np.pi * CYCLES_PER_M * path[:, None, :]))
    g = box_grid(target[0] - 0.2, target[1] - 0.2, target[0] + 0.2, target[1] + 0.2, pixel_m=0.005, height_m=0.5)
    pix = g.positions().reshape(-1, 3)
    vel = np.tile([1.0, 0.0, 0.0], (n, 1))
    win = stripmap_windows(pix, ant[0], vel, HALF_WIDTH)
    img = np.abs(backproject(prof.astype(np.complex64), ant, CHANNELS, pix, win, range0_m=0.0, bin_m=BIN_M,
                             cycles_per_m=CYCLES_PER_M)).reshape(g.shape)
    r, c = np.unravel_index(np.argmax(img), img.shape)
    # the argmax alone is good to half a 5 mm pixel; the main lobe (10 cm in range, 4 cm across) spans many pixels,
    # so near its top the intensity is a parabola in each axis, whose vertex through the 3 samples around the
    # argmax places the peak to a small fraction of a pixel
    i = img.astype(np.float64) ** 2
    dr = 0.5 * (i[r - 1, c] - i[r + 1, c]) / (i[r - 1, c] - 2 * i[r, c] + i[r + 1, c])
    dc = 0.5 * (i[r, c - 1] - i[r, c + 1]) / (i[r, c - 1] - 2 * i[r, c] + i[r, c + 1])
    peak = g.pixel_enu(r + dr, c + dc)
    assert np.hypot(*(peak[:2] - target[:2])) <= 0.0005  # measured 0.002 mm; the argmax alone 3.5 mm
    # coherent gain: every pulse and channel adds in phase at the peak
    assert img[r, c] == pytest.approx(np.sum(win[r * g.n_along + c, 1] - win[r * g.n_along + c, 0]) * 8, rel=0.02)


def test_empty_windows_and_accumulation() -> None:
    rng = np.random.default_rng(4)
    n = 200
    track = np.stack([np.arange(n) * 0.004, np.zeros(n)], axis=1)
    prof, ant, pix, win = _case(track, np.zeros(n), 10, rng)
    block = PulseBlock.from_profiles(prof, ant, CHANNELS, range0_m=0.0, bin_m=BIN_M, cycles_per_m=CYCLES_PER_M)
    empty = win.copy()
    empty[:, 1] = empty[:, 0]
    assert not np.any(backproject_block(block, pix, empty))
    once = backproject_block(block, pix, win)
    twice = backproject_block(block, pix, win, out=once.copy())
    np.testing.assert_allclose(twice, 2 * once, rtol=1e-6)


def _brute_force_window(pix: np.ndarray, track: np.ndarray, vel: np.ndarray) -> tuple[int, int]:
    """Pulses inside the processed beam (|sin psi| <= sin psi_max) whose line of sight is within psi_max of the
    line of sight at zero Doppler (the first pulse with sin psi <= 0, or the beam's last if psi jumps past zero
    after it or the drive ends before), every pulse tested; (0, 0) if none."""
    v = vel / np.linalg.norm(vel, axis=1, keepdims=True)
    d = pix - track
    sin_psi = np.sum(d * v, axis=1) / np.linalg.norm(d, axis=1)
    inside = np.flatnonzero(np.abs(sin_psi) <= math.sin(HALF_WIDTH))
    if inside.size == 0:
        return (0, 0)
    assert inside.size == inside[-1] + 1 - inside[0]  # one contiguous interval
    past = inside[sin_psi[inside] <= 0.0]
    m0 = past[0] if past.size else inside[-1]
    los = -d[inside] / np.linalg.norm(d[inside], axis=1, keepdims=True)
    sin_angle = np.linalg.norm(np.cross(los, los[inside == m0][0]), axis=1)
    keep = inside[sin_angle <= math.sin(HALF_WIDTH)]
    assert keep.size == keep[-1] + 1 - keep[0]
    return (int(keep[0]), int(keep[-1]) + 1)


@pytest.mark.parametrize("parallel", [True, False])
def test_stripmap_windows_equal_brute_force(parallel: bool) -> None:
    # a weaving track (0.3 m, 19 m period: a 30 m turn radius at its crests), pixels out to 27 m, so some lie
    # near a centre of curvature and the look-angle cut applies
    rng = np.random.default_rng(5)
    n = 2000
    s = np.arange(n) * 0.004
    track = np.stack([s, 0.3 * np.sin(s / 3.0), np.full(n, 0.5)], axis=1)
    vel = np.gradient(track, axis=0)
    pix = np.stack([rng.uniform(1, 7, 300), rng.uniform(-27, -0.5, 300), np.full(300, 0.5)], axis=1)
    win = stripmap_windows(pix, track, vel, HALF_WIDTH, parallel=parallel)
    cut = 0
    for k in range(len(pix)):
        want = _brute_force_window(pix[k], track, vel)
        if want == (0, 0):
            assert win[k, 1] <= win[k, 0]
            continue
        assert (win[k, 0], win[k, 1]) == want
        v = vel / np.linalg.norm(vel, axis=1, keepdims=True)
        d = pix[k] - track
        beam = np.abs(np.sum(d * v, axis=1) / np.linalg.norm(d, axis=1)) <= math.sin(HALF_WIDTH)
        cut += int(want[1] - want[0] < beam.sum())
    assert cut > 20  # the curve matters for a good share of these pixels


@pytest.mark.parametrize("block_pulses", [97, 512])
def test_stripmap_windows_do_not_depend_on_the_block(block_pulses: int) -> None:
    """Block by block, each with the context block_context gives, the windows are the whole drive's cut to the
    block: a pixel whose aperture straddles a block's end gets the same look-angle cut on both sides. test3-like
    zig-zag (+-0.8 m, 25 m period: a 20 m turn radius at its crests), 1.5 mm per pulse (1.5 m/s), pixels out to
    27.5 m on the right."""
    rng = np.random.default_rng(8)
    n = 6000
    s = np.arange(n) * 0.0015
    track = np.stack([s, 0.8 * np.sin(2 * np.pi * s / 25.0), np.full(n, 0.5)], axis=1)
    vel = np.gradient(track, axis=0)
    pix = np.stack([rng.uniform(0, 9, 2000), rng.uniform(-27.5, -0.5, 2000), np.full(2000, 0.5)], axis=1)
    whole = stripmap_windows(pix, track, vel, HALF_WIDTH, side=-1.0)
    # beyond a crest's centre of curvature (y < -19 m), and where the track swings over a pixel, sin psi is not
    # monotone, and bisections in the whole drive and in a block's context may find different crossings (the
    # processed beam assumes one pass): compare where sin psi decreases along the whole drive
    d = pix[:, None, :] - track[None]
    sin_psi = np.sum(d * (vel / np.linalg.norm(vel, axis=1, keepdims=True))[None], axis=2) / np.linalg.norm(d, axis=2)
    once = np.all(np.diff(sin_psi, axis=1) <= 0.0, axis=1)
    assert once.sum() > 1200
    travel = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(track, axis=0), axis=1))])
    margin = look_angle_margin_m(27.5, HALF_WIDTH)
    got = np.zeros(len(pix), np.int64)
    for b0 in range(0, n, block_pulses):
        b1 = min(n, b0 + block_pulses)
        win = stripmap_windows(pix, track, vel, HALF_WIDTH, side=-1.0, block=(b0, b1),
                               context=block_context(travel, b0, b1, margin))
        lo = np.maximum(whole[:, 0], b0) - b0
        hi = np.maximum(np.minimum(whole[:, 1], b1) - b0, lo)
        part = (hi > lo) & once
        np.testing.assert_array_equal(win[part], np.stack([lo, hi], axis=1)[part])
        assert np.all(win[~part & once, 1] <= win[~part & once, 0])
        got += np.maximum(win[:, 1] - win[:, 0], 0)
    np.testing.assert_array_equal(got[once], np.maximum(whole[:, 1] - whole[:, 0], 0)[once])
    assert np.count_nonzero(whole[once, 1] > whole[once, 0]) > 900


def test_cross_range_resolution_stays_nominal_in_a_curve() -> None:
    """A point 1 m from the centre of a 10 m turn towards it: the beam holds it for +-0.12 rad of look angle,
    which would focus it to ~4 mm across; cut to +-psi_max of look angle it has the nominal 0.886 rho."""
    turn_radius, offset = 10.0, 1.0
    theta = np.arange(-0.3, 0.3, 0.0004)  # 4 mm per pulse along the arc
    track = np.stack([turn_radius * np.sin(theta), turn_radius * (1 - np.cos(theta)), np.full(theta.size, 0.5)], 1)
    vel = np.stack([np.cos(theta), np.sin(theta), np.zeros(theta.size)], axis=1)
    target = np.array([0.0, turn_radius - offset, 0.5])  # 9 m from the track, left of it
    xs = np.arange(-0.1, 0.1, 0.001)
    pix = target + np.outer(xs, [1.0, 0.0, 0.0])  # across the line of sight at zero Doppler (theta = 0)
    path = 2 * np.linalg.norm(track - target, axis=1)
    bins = np.arange(N_BINS) * BIN_M
    res_path = 2 * 0.0375  # 4 GHz: 3.75 cm in range, twice that in two-way path
    prof = (np.sinc((bins[:, None] - path[None, :]) / res_path)
            * np.exp(2j * np.pi * CYCLES_PER_M * path)[None, :])[None].astype(np.complex64)
    ant = track[None]
    kw = dict(range0_m=0.0, bin_m=BIN_M, cycles_per_m=CYCLES_PER_M)
    win = stripmap_windows(pix, track, vel, HALF_WIDTH)
    img = backproject(prof, ant, np.array([[0, 0]]), pix, win, **kw)
    width = reference.minus3db_width(xs, np.abs(img))
    assert width == pytest.approx(0.8859 * 0.04, rel=0.1), width
    assert abs(xs[np.argmax(np.abs(img))]) <= 0.002
    # the beam alone: every pulse with |sin psi| <= sin psi_max
    v_sin = np.sum((target - track) * vel, axis=1) / np.linalg.norm(target - track, axis=1)
    beam = np.flatnonzero(np.abs(v_sin) <= math.sin(HALF_WIDTH))
    wide = np.tile([beam[0], beam[-1] + 1], (len(pix), 1))
    sharp = reference.minus3db_width(xs, np.abs(backproject(prof, ant, np.array([[0, 0]]), pix, wide, **kw)))
    print(f"cross-range -3 dB width: {width * 1e3:.1f} mm cut, {sharp * 1e3:.1f} mm the beam alone")
    assert sharp < 0.3 * width, sharp


def test_aperture_grows_with_range() -> None:
    n = 4000
    s = np.arange(n) * 0.004
    track = np.stack([s, np.zeros(n), np.full(n, 0.5)], axis=1)
    vel = np.tile([1.0, 0.0, 0.0], (n, 1))
    pix = np.array([[8.0, -r, 0.5] for r in (2.0, 8.0, 20.0)])
    win = stripmap_windows(pix, track, vel, HALF_WIDTH)
    length = (win[:, 1] - win[:, 0]) * 0.004
    np.testing.assert_allclose(length, 2 * np.hypot([2.0, 8.0, 20.0], 0) * math.tan(HALF_WIDTH), rtol=0.02,
                               atol=0.008)


def test_grids() -> None:
    s = np.linspace(0, 50, 200)
    track = np.stack([-s, 0.5 * (s / 50) ** 2], axis=1)  # westwards, drifting north
    g = track_grid(track, side=-1.0, pixel_m=0.04, height_m=0.5, antenna_height_m=0.5, max_range_m=27.0)
    assert g.along[0] < -0.99  # columns follow the drive
    assert g.along[0] * g.across[1] - g.along[1] * g.across[0] < 0  # rows run to the right of it
    rows, cols = g.enu_to_pixel(g.pixel_enu([3.0, 100.0], [7.0, 900.0]))
    np.testing.assert_allclose(rows, [3.0, 100.0], atol=1e-9)
    np.testing.assert_allclose(cols, [7.0, 900.0], atol=1e-9)
    assert g.n_along * 0.04 == pytest.approx(50.0, abs=0.1)
    # ranges 0.5..27 m from every track point: 26.5 m plus the track's weave about its mean line (< 0.5 m)
    assert 26.5 < g.n_across * 0.04 < 27.0 + 0.04
    b = box_grid(0.0, 0.0, 2.0, 1.0, pixel_m=0.5, height_m=0.0)
    assert b.shape == (2, 4)
    np.testing.assert_allclose(b.pixel_enu(0, 0), [0.25, 0.75, 0.0])
    with pytest.raises(GridError):
        box_grid(1.0, 0.0, 0.0, 1.0, pixel_m=0.5, height_m=0.0)
    # `focus --pixel 4` meant as 4 cm, on a 2.4 m drive: said as 'shorter than one pixel', no length, no unit
    short = np.column_stack([np.linspace(0.0, 2.4, 50), np.zeros(50)])
    with pytest.raises(GridError, match=r"^the trajectory runs 2\.40 m from its first point to its last, shorter "
                                        r"than one 4 m pixel \(--pixel and processing\.pixel_m are metres: 0\.04 "
                                        r"is 4 cm\): nothing to focus along$"):
        track_grid(short, side=-1.0, pixel_m=4.0, height_m=0.5, antenna_height_m=0.5)
    with pytest.raises(GridError, match=r"^the trajectory runs 0\.02 m .* one 0\.04 m pixel: nothing"):
        track_grid(short[:1] + [[0.0, 0.0], [0.02, 0.0]], side=-1.0, pixel_m=0.04, height_m=0.5,
                   antenna_height_m=0.5)


def test_windows_only_on_the_radar_side() -> None:
    n = 1000
    track = np.stack([np.arange(n) * 0.004, np.zeros(n), np.full(n, 0.5)], axis=1)
    vel = np.tile([1.0, 0.0, 0.0], (n, 1))
    pix = np.array([[2.0, -5.0, 0.5], [2.0, 5.0, 0.5]])  # right, left of an eastward drive
    both = stripmap_windows(pix, track, vel, HALF_WIDTH)
    right = stripmap_windows(pix, track, vel, HALF_WIDTH, side=-1.0)
    left = stripmap_windows(pix, track, vel, HALF_WIDTH, side=1.0)
    assert np.all(both[:, 1] > both[:, 0])
    assert right[0, 1] > right[0, 0] and right[1, 1] == right[1, 0]
    assert left[1, 1] > left[1, 0] and left[0, 1] == left[0, 0]
