"""infonav_gym.information against closed forms and peer libraries (scipy, scikit-image)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from infonav_gym.information import (
    expected_information_gain,
    gaussian_entropy,
    histogram_entropy,
    information_gain_of_information,
    information_metric,
    largest_position_std,
    log_det_spd,
    mutual_information,
)


def random_spd(rng: np.random.Generator, n: int, condition: float = 1e3) -> np.ndarray:
    """A random SPD matrix with eigenvalues spread over ``condition``."""
    q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    eigenvalues = np.exp(rng.uniform(0.0, math.log(condition), n)) * rng.uniform(1e-3, 1e2)
    matrix = q @ np.diag(eigenvalues) @ q.T
    return 0.5 * (matrix + matrix.T)


@settings(max_examples=200, deadline=None)
@given(n=st.integers(1, 12), seed=st.integers(0, 2**32 - 1))
def test_gaussian_entropy_matches_scipy(n, seed):
    P = random_spd(np.random.default_rng(seed), n)
    expected = stats.multivariate_normal(mean=np.zeros(n), cov=P).entropy()
    assert math.isclose(gaussian_entropy(P), expected, rel_tol=1e-9, abs_tol=1e-12)


def test_gaussian_entropy_closed_form_for_diagonal():
    variances = np.array([0.5, 2.0, 3.0])
    expected = 0.5 * np.sum(np.log(2 * math.pi * math.e * variances))
    assert math.isclose(gaussian_entropy(np.diag(variances)), expected, rel_tol=1e-14)
    assert information_metric(np.diag(variances)) == -gaussian_entropy(np.diag(variances))


@settings(max_examples=100, deadline=None)
@given(n=st.integers(1, 8), m=st.integers(1, 4), seed=st.integers(0, 2**32 - 1))
def test_mutual_information_of_linear_gaussian_update_equals_expected_gain(n, m, seed):
    rng = np.random.default_rng(seed)
    P, R = random_spd(rng, n, 1e2), random_spd(rng, m, 1e2)
    H = rng.standard_normal((m, n))
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    I_KH = np.eye(n) - K @ H
    P_post = I_KH @ P @ I_KH.T + K @ R @ K.T
    P_post = 0.5 * (P_post + P_post.T)
    assert math.isclose(mutual_information(P, P_post), expected_information_gain(P, H, R), rel_tol=1e-7, abs_tol=1e-10)


def test_mutual_information_is_the_paper_ic():
    prior, post = np.diag([4.0, 1.0]), np.diag([1.0, 1.0])
    assert math.isclose(mutual_information(prior, post), 0.5 * math.log(4.0), rel_tol=1e-14)
    assert math.isclose(mutual_information(prior, post), information_metric(post) - information_metric(prior))


def test_expected_gain_scalar_closed_form():
    P, H, R = np.array([[2.0]]), np.array([[1.0]]), np.array([[0.5]])
    assert math.isclose(expected_information_gain(P, H, R), 0.5 * math.log(1 + 2.0 / 0.5), rel_tol=1e-14)


def test_expected_gain_is_batched_over_candidates():
    rng = np.random.default_rng(0)
    P = random_spd(rng, 5)
    H = rng.standard_normal((3, 7, 2, 5))
    R = np.stack([random_spd(rng, 2) for _ in range(21)]).reshape(3, 7, 2, 2)
    batched = expected_information_gain(P, H, R)
    assert batched.shape == (3, 7)
    for i, j in np.ndindex(3, 7):
        assert math.isclose(batched[i, j], expected_information_gain(P, H[i, j], R[i, j]), rel_tol=1e-12)
    shared_noise = expected_information_gain(P, H[0], R[0, 0])
    assert math.isclose(shared_noise[4], expected_information_gain(P, H[0, 4], R[0, 0]), rel_tol=1e-12)


def test_unchecked_fast_path_agrees_and_rejects_non_positive_determinants():
    rng = np.random.default_rng(1)
    P = random_spd(rng, 3)
    H = rng.standard_normal((8, 2, 3))
    R = np.stack([random_spd(rng, 2) for _ in range(8)])
    np.testing.assert_allclose(
        expected_information_gain(P, H, R, check_input=False), expected_information_gain(P, H, R), rtol=1e-12
    )
    with pytest.raises(ValueError, match="not positive definite"):
        log_det_spd(np.diag([1.0, -1.0]), check_input=False)
    with pytest.raises(ValueError, match="not positive definite"):
        expected_information_gain(P, H, np.tile(np.diag([1.0, -1.0]), (8, 1, 1)), check_input=False)
    two_negative_eigenvalues = np.diag([1.0, -1.0, -1.0])
    with pytest.raises(ValueError, match="not positive definite"):
        log_det_spd(two_negative_eigenvalues)


@pytest.mark.parametrize("n", range(1, 9))
def test_unchecked_log_det_is_slogdets_for_every_size_and_stack_shape(n):
    """The compiled fast path (cofactors up to 3 x 3, an LU above) against LAPACK's ``slogdet``."""
    rng = np.random.default_rng(n)
    stack = np.stack([random_spd(rng, n) for _ in range(6)]).reshape(2, 3, n, n)
    expected = np.linalg.slogdet(stack)[1]
    np.testing.assert_allclose(log_det_spd(stack, check_input=False), expected, rtol=1e-12, atol=1e-12)
    assert log_det_spd(stack[0, 0], check_input=False) == pytest.approx(expected[0, 0], rel=1e-12, abs=1e-12)
    assert isinstance(log_det_spd(stack[0, 0], check_input=False), float)
    swapped = stack[0, 0][::-1]  # rows reversed: the LU must pivot; det changes sign with an odd permutation
    sign, magnitude = np.linalg.slogdet(swapped)
    if sign > 0:
        assert log_det_spd(swapped, check_input=False) == pytest.approx(magnitude, rel=1e-12, abs=1e-12)
    else:
        with pytest.raises(ValueError, match="not positive definite"):
            log_det_spd(swapped, check_input=False)
    one_negative = np.diag([-1.0, *np.ones(n - 1)])
    for bad in (one_negative, np.zeros((n, n)), np.full((n, n), np.nan)):
        with pytest.raises(ValueError, match=r"P is not positive definite \(determinant <= 0\)"):
            log_det_spd(np.stack([stack[0, 0], bad]), "P", check_input=False)


NOT_SQUARE = np.ones((2, 3))
NOT_SYMMETRIC = np.array([[2.0, 1.0], [0.0, 2.0]])
INDEFINITE = np.array([[1.0, 2.0], [2.0, 1.0]])
WITH_NAN = np.array([[1.0, np.nan], [np.nan, 1.0]])


@pytest.mark.parametrize(
    "matrix, problem",
    [(NOT_SQUARE, "square"), (NOT_SYMMETRIC, "symmetric"), (INDEFINITE, "positive definite"), (WITH_NAN, "NaN")],
)
def test_bad_covariances_raise_naming_the_problem(matrix, problem):
    with pytest.raises(ValueError, match=problem):
        gaussian_entropy(matrix)
    with pytest.raises(ValueError, match=problem):
        mutual_information(matrix, np.eye(2) if matrix.shape == (2, 2) else matrix)
    if matrix.shape == (2, 2):
        with pytest.raises(ValueError, match=problem):
            expected_information_gain(matrix, np.eye(2), np.eye(2))
        with pytest.raises(ValueError, match=problem):
            expected_information_gain(np.eye(2), np.eye(2), matrix)


def test_shape_mismatches_raise():
    with pytest.raises(ValueError, match="Jacobian H"):
        expected_information_gain(np.eye(3), np.ones((2, 4)), np.eye(2))
    with pytest.raises(ValueError, match="noise covariance R"):
        expected_information_gain(np.eye(3), np.ones((2, 3)), np.eye(3))
    with pytest.raises(ValueError, match="same shape"):
        mutual_information(np.eye(3), np.eye(2))
    with pytest.raises(ValueError, match="one matrix"):
        gaussian_entropy(np.stack([np.eye(2)] * 2))


def test_histogram_entropy_matches_scikit_image():
    skimage_measure = pytest.importorskip("skimage.measure")
    rng = np.random.default_rng(0)
    images = [
        rng.integers(0, 256, (32, 180), dtype=np.uint8),
        rng.binomial(255, 0.3, (120, 160)).astype(np.uint8),
        np.repeat(np.arange(0, 256, 16, dtype=np.uint8), 10).reshape(16, 10),
    ]
    for image in images:
        expected = skimage_measure.shannon_entropy(image, base=math.e)
        assert math.isclose(histogram_entropy(image), expected, rel_tol=1e-12)
        assert math.isclose(histogram_entropy(image, base=2), skimage_measure.shannon_entropy(image), rel_tol=1e-12)


def test_histogram_entropy_extremes():
    uniform = np.arange(256, dtype=np.uint8).repeat(4)
    assert math.isclose(histogram_entropy(uniform), math.log(256), rel_tol=1e-14)
    assert histogram_entropy(np.full((10, 10), 77, dtype=np.uint8)) == 0.0
    assert histogram_entropy(np.full((10, 10), 3.5)) == 0.0


def test_histogram_entropy_of_float_images_bins_the_value_range():
    image = np.repeat(np.linspace(0.0, 1.0, 4), 25)
    assert math.isclose(histogram_entropy(image, bins=4), math.log(4), rel_tol=1e-14)
    assert math.isclose(histogram_entropy(image, bins=2), math.log(2), rel_tol=1e-14)
    three_quarters_in_first_bin = -(0.75 * math.log(0.75) + 0.25 * math.log(0.25))
    assert math.isclose(histogram_entropy(image, bins=2, value_range=(0.0, 2.0)), three_quarters_in_first_bin)


@pytest.mark.parametrize(
    "kwargs, problem",
    [
        ({"image": np.zeros((0, 3), np.uint8)}, "empty"),
        ({"image": np.array([1.0, np.nan])}, "NaN"),
        ({"image": np.array(["a", "b"])}, "numbers"),
        ({"image": np.zeros(4, np.uint8), "bins": 0}, "bins"),
        ({"image": np.zeros(4, np.uint8), "base": 1.0}, "base"),
        ({"image": np.zeros(4), "value_range": (2.0, 1.0)}, "value_range"),
        ({"image": np.zeros(4), "value_range": (1.0, 2.0)}, "inside value_range"),
    ],
)
def test_histogram_entropy_bad_input(kwargs, problem):
    with pytest.raises(ValueError, match=problem):
        histogram_entropy(**kwargs)


def test_information_gain_of_information_is_the_entropy_drop_of_the_linear_gaussian_update():
    rng = np.random.default_rng(2)
    A_root = rng.standard_normal((6, 6))
    P = A_root @ A_root.T + 0.1 * np.eye(6)
    J = rng.standard_normal((20, 6))
    R = np.diag(rng.uniform(0.5, 2.0, 20))
    posterior = np.linalg.inv(np.linalg.inv(P) + J.T @ np.linalg.inv(R) @ J)
    expected = 0.5 * (np.linalg.slogdet(P)[1] - np.linalg.slogdet(posterior)[1])
    information = J.T @ np.linalg.inv(R) @ J
    assert information_gain_of_information(np.linalg.cholesky(P), information) == pytest.approx(expected, rel=1e-10)


def test_largest_position_std_is_the_root_of_the_position_blocks_largest_eigenvalue():
    rng = np.random.default_rng(0)
    roots = rng.normal(size=(20, 3, 3))
    covariances = roots @ roots.transpose(0, 2, 1) + 1e-3 * np.eye(3)
    expected = np.sqrt(np.linalg.eigvalsh(covariances[:, :2, :2])[:, -1])
    np.testing.assert_allclose(largest_position_std(covariances), expected, rtol=1e-12)


def test_the_mi_formula_is_written_once():
    """Every MI in the package, the compiled kernels' included, is ``mutual_information_from_log_dets`` (or its kernel
    twin): no other module halves a difference of log-determinants."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    copy = re.compile(r"0\.5 \* \(\s*(np\.linalg\.slogdet|log_det|[a-z_]*log_dets?\b|pose_block_log_det)")
    sources = [*(root / "infonav_gym").rglob("*.py"), *(root / "agents").rglob("*.py")]
    copies = [str(path.relative_to(root)) for path in sources if copy.search(path.read_text())]
    assert copies == ["infonav_gym/information.py"], copies
    prior, posterior = np.diag([4.0, 9.0]), np.diag([1.0, 1.0])
    assert mutual_information(prior, posterior) == pytest.approx(0.5 * math.log(36.0), rel=1e-15)
