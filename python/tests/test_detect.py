"""mochi.detect, mochi.Detector and mochi.backends against a brute-force NumPy oracle."""

import os

import numpy as np
import pytest

import mochi


def oracle(centres, radii):
    """Every pair whose spheres touch, computed the way the library does (float32)."""
    c = np.asarray(centres, dtype=np.float32)
    r = np.asarray(radii, dtype=np.float32)
    d = c[:, None, :] - c[None, :, :]
    dist2 = np.einsum("ijk,ijk->ij", d, d)
    reach = r[:, None] + r[None, :]
    i, j = np.nonzero(np.triu(dist2 <= reach * reach, k=1))
    return np.stack([i, j], axis=1).astype(np.int64).reshape(-1, 2)


def detector_backends():
    """The backends a Detector is tested on: cpu, and wgpu-compute, which takes centres straight
    into its upload (lavapipe in CI, which must find it: a missing adapter fails there)."""
    available = {e["name"]: e for e in mochi.backends()}
    gpu = available["wgpu-compute"]
    if gpu["available"]:
        return ["cpu", "wgpu-compute"]
    assert os.environ.get("CI") != "true", f"CI expects wgpu-compute: {gpu['reason']}"
    return ["cpu"]


def random_set(seed, n=400, box=20.0):
    rng = np.random.default_rng(seed)
    centres = rng.uniform(0.0, box, size=(n, 3))
    radii = rng.uniform(0.1, 1.0, size=n) ** 2 + 0.05
    return centres, radii


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_polydisperse_matches_oracle(seed):
    centres, radii = random_set(seed)
    pairs = mochi.detect(centres, radii, backend="cpu")
    assert pairs.dtype == np.int64 and pairs.shape[1] == 2
    np.testing.assert_array_equal(pairs, oracle(centres, radii))


def test_detect_again_keeps_its_backend_and_stays_exact():
    # Calls with sets of other sizes, modes and backends: the backend kept from the last call
    # (or a new one) must give every set's own pairs.
    calls = [(3, 400, "cpu", "mochi"), (4, 250, "cpu", "nns"), (5, 600, "cpu", "mochi")]
    calls += [(6, 300, b, "mochi") for b in detector_backends()] + [(7, 350, "cpu", "mochi")]
    for seed, n, backend, mode in calls:
        centres, radii = random_set(seed, n=n)
        np.testing.assert_array_equal(
            mochi.detect(centres, radii, backend=backend, mode=mode), oracle(centres, radii)
        )


def test_nns_mode_finds_the_same_pairs():
    centres, radii = random_set(3)
    np.testing.assert_array_equal(
        mochi.detect(centres, radii, backend="cpu", mode="nns"), oracle(centres, radii)
    )


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("order", ["C", "F"])
def test_dtypes_and_orders(dtype, order):
    centres, radii = random_set(4, n=200)
    c = np.asarray(centres, dtype=dtype, order=order)
    r = np.asarray(radii, dtype=dtype)
    np.testing.assert_array_equal(mochi.detect(c, r, backend="cpu"), oracle(c, r))


def test_empty_and_single():
    assert mochi.detect(np.zeros((0, 3)), np.zeros(0), backend="cpu").shape == (0, 2)
    assert mochi.detect(np.zeros((1, 3)), np.ones(1), backend="cpu").shape == (0, 2)


def test_touching_exactly_and_duplicates():
    centres = np.array([[0.0, 0, 0], [2.0, 0, 0], [2.0, 0, 0], [10.0, 0, 0]])
    radii = np.array([1.0, 1.0, 1.0, 1.0])
    pairs = mochi.detect(centres, radii, backend="cpu")
    np.testing.assert_array_equal(pairs, [[0, 1], [0, 2], [1, 2]])


@pytest.mark.parametrize(
    "centres, radii, words",
    [
        (np.zeros((3, 2)), np.ones(3), "shape"),
        (np.zeros((3, 3), dtype=np.int32), np.ones(3), "dtype"),
        (np.zeros((3, 3)), np.ones(2), "3 centres but 2 radii"),
        (np.array([[0.0, 0, 0], [np.nan, 0, 0]]), np.ones(2), "sphere 1"),
        (np.zeros((2, 3)), np.array([1.0, -1.0]), "sphere 1"),
    ],
)
def test_bad_input_is_value_error(centres, radii, words):
    with pytest.raises(ValueError, match=words):
        mochi.detect(centres, radii, backend="cpu")


def test_bad_backend_and_mode():
    with pytest.raises(ValueError):
        mochi.detect(np.zeros((1, 3)), np.ones(1), backend="nope")
    with pytest.raises(ValueError):
        mochi.detect(np.zeros((1, 3)), np.ones(1), mode="nope")


@pytest.mark.parametrize("backend", detector_backends())
def test_detector_update_loop_equals_fresh_detect(backend):
    centres, radii = random_set(5)
    rng = np.random.default_rng(6)
    detector = mochi.Detector(backend=backend)
    detector.build(centres, radii)
    # Every way in: float64, C-ordered float32 (read where it lies) and Fortran-ordered
    # float32 (converted first), each twice; moves small and large (a new grid layout).
    ways = [
        lambda c: c,
        lambda c: np.ascontiguousarray(c, dtype=np.float32),
        lambda c: np.asfortranarray(c, dtype=np.float32),
    ]
    for k in range(9):
        centres = centres + rng.normal(0.0, 0.2, size=centres.shape)
        if k == 4:
            centres = centres * 1.5
        given = ways[k % 3](centres)
        detector.update(given)
        np.testing.assert_array_equal(
            detector.pairs(), mochi.detect(given, radii, backend="cpu")
        )


@pytest.mark.parametrize("backend", detector_backends())
def test_detector_builds_from_every_layout_of_arrays(backend):
    # C-ordered float32 arrays are read where they lie, anything else converted first; a set
    # refused at build leaves the last build as it was.
    detector = mochi.Detector(backend=backend)
    for seed in range(11, 14):
        centres, radii = random_set(seed)
        xyzr = np.hstack([centres, radii[:, None]]).astype(np.float32)
        want = oracle(xyzr[:, :3], xyzr[:, 3])
        ways = [
            (centres, radii),
            (xyzr[:, :3].copy(), xyzr[:, 3].copy()),
            (np.asfortranarray(xyzr[:, :3]), xyzr[:, 3].copy()),
            (xyzr[:, :3], xyzr[:, 3]),  # strided views into one (N, 4) array
            (xyzr[::-1, :3][::-1], xyzr[::-1, 3][::-1]),  # negative strides
        ]
        for c, r in ways:
            detector.build(c, r)
            np.testing.assert_array_equal(detector.pairs(), want)
            assert len(want) > 0
        bad = xyzr.copy()
        bad[5, 3] = -1.0
        with pytest.raises(ValueError, match="sphere 5"):
            detector.build(bad[:, :3].copy(), bad[:, 3].copy())
        with pytest.raises(ValueError, match="centres but"):
            detector.build(xyzr[:-1, :3].copy(), xyzr[:, 3].copy())
        np.testing.assert_array_equal(detector.pairs(), want)


@pytest.mark.parametrize("backend", detector_backends())
def test_detector_update_refused_keeps_the_last_spheres(backend):
    centres, radii = random_set(7)
    detector = mochi.Detector(backend=backend)
    detector.build(centres, radii)
    before = detector.pairs()
    bad = centres.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match="sphere 3"):
        detector.update(bad)
    with pytest.raises(ValueError, match="sphere 3"):
        detector.update(bad.astype(np.float32))
    with pytest.raises(ValueError):
        detector.update(centres[:, :2].astype(np.float32))
    with pytest.raises(ValueError):
        detector.update(centres[:-1])
    np.testing.assert_array_equal(detector.pairs(), before)


def test_detector_before_build_is_mochi_error():
    with pytest.raises(mochi.MochiError):
        mochi.Detector(backend="cpu").pairs()
    assert issubclass(mochi.MochiError, RuntimeError)


def test_backends():
    entries = mochi.backends()
    names = [e["name"] for e in entries]
    assert names == ["optix", "wgpu-rq", "wgpu-compute", "cpu"]
    cpu = entries[-1]
    assert cpu["available"] is True and "CPU" in cpu["reason"]
    assert all(isinstance(e["reason"], str) and e["reason"] for e in entries)


# Masked arrays, byte order, and float64 beyond float32.


def test_a_masked_array_with_masked_entries_is_refused():
    centres, radii = random_set(8, n=50)
    masked = np.ma.masked_array(centres, mask=np.zeros_like(centres, dtype=bool))
    masked[4, 1] = np.ma.masked
    with pytest.raises(ValueError, match="centres is a masked array"):
        mochi.detect(masked, radii, backend="cpu")
    masked_radii = np.ma.masked_less(radii, 0.2)
    assert masked_radii.mask.any()
    with pytest.raises(ValueError, match="radii is a masked array"):
        mochi.detect(centres, masked_radii, backend="cpu")
    detector = mochi.Detector(backend="cpu")
    detector.build(centres, radii)
    with pytest.raises(ValueError, match="centres is a masked array"):
        detector.update(masked.astype(np.float32))
    # Nothing masked: the values are the spheres.
    unmasked = np.ma.masked_array(centres, mask=False)
    np.testing.assert_array_equal(
        mochi.detect(unmasked, np.ma.masked_array(radii), backend="cpu"), oracle(centres, radii)
    )


@pytest.mark.parametrize("dtype", [">f8", ">f4", "<f8", "<f4"])
def test_either_byte_order_is_read(dtype):
    centres, radii = random_set(9, n=300)
    c, r = centres.astype(dtype), radii.astype(dtype)
    np.testing.assert_array_equal(mochi.detect(c, r, backend="cpu"), oracle(centres.astype(dtype), r))
    detector = mochi.Detector(backend="cpu")
    detector.build(c, r)
    moved = (centres + 0.3).astype(dtype)
    detector.update(moved)
    np.testing.assert_array_equal(detector.pairs(), oracle(moved, r))


@pytest.mark.parametrize(
    "centres, radii, words",
    [
        ([[0.0, 0, 0], [0, 1e39, 0]], [1.0, 1.0], r"sphere 1: y = 1e39 is outside the range of float32"),
        ([[0.0, 0, 0], [0, 0, -4e38]], [1.0, 1.0], r"sphere 1: z = -4e38 is outside the range"),
        ([[0.0, 0, 0], [1, 0, 0]], [1.0, 1e39], r"sphere 1: radius 1e39 is outside the range of float32"),
        ([[0.0, 0, 0], [1, 0, 0]], [1e-50, 1.0], r"sphere 0: radius 1e-50 is outside the range"),
        (np.zeros((2, 3), dtype=np.int64), [1.0, 1.0], "dtype int64"),
        ([[0.0, 0, 0]], [1.0], "not a list"),
    ],
)
def test_values_float32_cannot_hold_are_named(centres, radii, words):
    given = centres if isinstance(centres, np.ndarray) else np.array(centres)
    if words == "not a list":
        given = centres
    with pytest.raises(ValueError, match=words):
        mochi.detect(given, np.array(radii), backend="cpu")
