"""Property and analytic tests of Phi_n (haptic_env.grasp_features)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from haptic_env.grasp_features import (
    DEFAULT_TOL,
    GRASP_SIZE_RANGE,
    DegenerateGraspError,
    feature_dim,
    normalize_scale,
    phi,
    phi_planar,
    surface_area,
)

SETTINGS = settings(max_examples=60, deadline=None)


def random_grasp(seed: int, n: int, batch: int = 16, normals: bool = False):
    """Grasps in general position: Gaussian contacts (ties have probability zero)."""
    rng = np.random.default_rng(seed)
    P = rng.normal(size=(batch, n, 3))
    N = rng.normal(size=(batch, n, 3)) if normals else None
    return P, N


rigid = st.tuples(
    st.integers(0, 2**32 - 1),  # rotation seed
    st.lists(st.floats(-10, 10), min_size=3, max_size=3),  # translation
)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 10), normals=st.booleans(), motion=rigid)
def test_rigid_motion_invariance(seed, n, normals, motion):
    """Theorem 1: q is invariant to rotation + translation of the grasp (normals rotate along)."""
    P, N = random_grasp(seed, n, normals=normals)
    Rm = Rotation.random(random_state=motion[0]).as_matrix()
    t = np.array(motion[1])
    f = phi(P, N)
    g = phi(P @ Rm.T + t, None if N is None else N @ Rm.T)
    assert f.q.shape == (len(P), feature_dim(n, normals))
    assert f.valid.all() and g.valid.all()
    np.testing.assert_allclose(f.q, g.q, atol=1e-8)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 10), normals=st.booleans(), data=st.data())
def test_finger_permutation_invariance(seed, n, normals, data):
    """The chain orders the contacts, never the input order."""
    P, N = random_grasp(seed, n, normals=normals)
    perm = np.array(data.draw(st.permutations(range(n))))
    f = phi(P, N)
    g = phi(P[:, perm], None if N is None else N[:, perm])
    np.testing.assert_allclose(f.q, g.q, atol=1e-9)
    if n >= 3 or normals:  # (two contacts without normals are symmetric: no canonical order)
        # the returned order names the same physical contacts
        np.testing.assert_array_equal(perm[g.order], f.order)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 10), normals=st.booleans(),
       scale=st.floats(1e-2, 1e2))
def test_scale_invariance_after_normalisation(seed, n, normals, scale):
    """Theorem 2: after dividing by sqrt(surface area), uniform scaling leaves q unchanged."""
    P, N = random_grasp(seed, n, normals=normals)
    a, sa = normalize_scale(P)
    b, sb = normalize_scale(P * scale)
    np.testing.assert_allclose(sb, sa * scale, rtol=1e-9)
    np.testing.assert_allclose(phi(a, N).q, phi(b, N).q, atol=1e-8)
    np.testing.assert_allclose(surface_area(a), 1.0, rtol=1e-9)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(3, 8))
def test_interior_contacts_are_attached_invariantly(seed, n):
    """Contacts inside the hull (concave objects) still get a rigid- and permutation-invariant code."""
    rng = np.random.default_rng(seed)
    P = rng.normal(size=(8, n, 3))
    P[:, -1] = P[:, :-1].mean(axis=1) + 0.01 * rng.normal(size=(8, 3))  # inside the hull
    Rm = Rotation.random(random_state=seed).as_matrix()
    perm = rng.permutation(n)
    f = phi(P)
    g = phi((P @ Rm.T)[:, perm])
    assert f.valid.all()
    np.testing.assert_allclose(f.q, g.q, atol=1e-8)


@pytest.mark.parametrize("n", [2, 3, 4, 5, 7])
@pytest.mark.parametrize("normals", [False, True])
def test_distinct_grasps_give_distinct_vectors(n, normals):
    """Non-congruent random grasps map to distinct vectors (no collisions in 2,000)."""
    P, N = random_grasp(123, n, batch=2000, normals=normals)
    q = phi(P, N).q
    d = np.linalg.norm(q[:, None] - q[None], axis=-1)
    d[np.diag_indices_from(d)] = np.inf
    assert d.min() > 1e-10  # float noise of congruent grasps is ~1e-15 (see the invariance tests)


def test_regular_tetrahedron():
    tet = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1.0]])
    f = phi(tet, strict=True)
    edge = 2 * np.sqrt(2)
    expected = [edge, np.pi / 3, np.pi / 3, np.pi / 3, np.pi / 3, np.arccos(1 / 3)]
    np.testing.assert_allclose(np.abs(f.q), expected, atol=1e-12)
    # surface area: 4 equilateral triangles of side 2 sqrt 2
    np.testing.assert_allclose(surface_area(tet), 4 * np.sqrt(3) / 4 * edge**2)


def test_unit_box_corner_grasp_with_normals():
    """Contacts on a unit box corner: t1 is the equilateral face, t2 a right isosceles face."""
    P = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    N = np.array([[1, 1, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1.0]])  # inward face normals
    f = phi(P, N, strict=True)
    q = f.q
    np.testing.assert_allclose(q[0], np.sqrt(2))  # longest edge of t1
    np.testing.assert_allclose(q[1:3], [np.pi / 3, np.pi / 3])  # t1 equilateral
    np.testing.assert_allclose(q[3:5], [np.pi / 4, np.pi / 4])  # t2 right isosceles at the hypotenuse
    np.testing.assert_allclose(abs(q[5]), np.arccos(1 / np.sqrt(3)))  # dihedral equilateral/right face
    assert q.shape == (feature_dim(4, True),) == (14,)
    # the corner contact (origin) has its normal along t1's normal (the (1,1,1) diagonal): angle 0 or pi
    corner = int(np.flatnonzero(f.order == 0)[0])
    a1 = q[6 + 2 * corner]
    assert min(a1, np.pi - a1) < 1e-12
    np.testing.assert_allclose(surface_area(P), 3 * 0.5 + np.sqrt(3) / 4 * 2)


def test_triangle_with_normals_uses_longest_edge():
    P = np.array([[0, 0, 0], [3, 0, 0], [0, 4, 0.0]])  # 3-4-5 triangle
    N = np.array([[0, 0, 1], [0, 0, 1], [1, 0, 0.0]])
    f = phi(P, N, strict=True)
    np.testing.assert_allclose(f.q[0], 5.0)
    angles = sorted(f.q[1:3])
    np.testing.assert_allclose(angles, sorted([np.arctan2(3, 4), np.arctan2(4, 3)]))
    assert f.q.shape == (9,)


def test_two_fingers():
    P = np.array([[0, 0, 0], [0, 0, 2.0]])
    assert phi(P).q.tolist() == [2.0]
    N = np.array([[0, 0, 1], [0, 1, -1.0]])
    f = phi(P, N)
    np.testing.assert_allclose(f.q[:3], [2.0, np.pi / 4, 0.0])
    g = phi(P[::-1], N[::-1])
    np.testing.assert_allclose(f.q, g.q)


@pytest.mark.parametrize(
    "contacts, reason",
    [
        ([[0, 0, 0], [0, 0, 0], [1, 0, 0], [0, 1, 0]], "coincident"),
        ([[0, 0, 0], [1, 1, 1], [2, 2, 2]], "collinear"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], "coplanar"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.3, 0.7, 0]], "coplanar"),
        ([[1, 2, 3]] * 2, "coincident"),
    ],
)
def test_degenerate_grasps_flagged_never_nan(contacts, reason):
    good, _ = random_grasp(0, len(contacts), batch=3)
    batch = np.concatenate([good, np.array(contacts, float)[None]], axis=0)
    f = phi(batch)
    assert np.isfinite(f.q).all()
    assert f.valid.tolist() == [True, True, True, False]
    assert not f.q[-1].any()
    np.testing.assert_allclose(f.q[:3], phi(good).q)  # good rows unaffected by the bad one
    with pytest.raises(DegenerateGraspError, match=f"grasp 3 is degenerate \\({reason}"):
        phi(batch, strict=True)


def test_bad_input_raises_clear_errors():
    P = np.random.default_rng(0).normal(size=(4, 4, 3))
    P[2, 1, 0] = np.nan
    with pytest.raises(ValueError, match="grasp 2 are not finite"):
        phi(P)
    with pytest.raises(ValueError, match=r"shape \(B, n, 3\)"):
        phi(np.zeros((4, 4, 2)))
    with pytest.raises(ValueError, match="at least 2 contacts"):
        phi(np.zeros((3, 1, 3)))
    with pytest.raises(ValueError, match="normal 1 of grasp 0 is zero"):
        phi(np.eye(3), np.array([[1, 0, 0], [0, 0, 0], [0, 0, 1.0]]))


def test_box_face_coplanar_subset_is_deterministic():
    """Four contacts on one box face plus one off it: a valid grasp whose hull comes from Qhull.

    The coplanar face has two triangulations, so (as for any tie) which one Qhull picks may depend
    on the frame; the result is valid, finite, repeatable and its area exact.
    """
    P = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.5, 0.5, 1.0]])
    f = phi(P, strict=True)
    assert f.valid and np.isfinite(f.q).all()
    np.testing.assert_array_equal(phi(P).q, f.q)
    np.testing.assert_allclose(surface_area(P), 1 + 4 * 0.5 * np.sqrt(1.25))


# ------------------------------------------------------------------------------------- planar
@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 9), normals=st.booleans(),
       angle=st.floats(-np.pi, np.pi), data=st.data())
def test_planar_invariances(seed, n, normals, angle, data):
    rng = np.random.default_rng(seed)
    P = rng.normal(size=(8, n, 2))
    N = rng.normal(size=(8, n, 2)) if normals else None
    c, s = np.cos(angle), np.sin(angle)
    Rm = np.array([[c, -s], [s, c]])
    perm = np.array(data.draw(st.permutations(range(n))))
    f = phi_planar(P, N)
    g = phi_planar((P @ Rm.T + 3.0)[:, perm], None if N is None else (N @ Rm.T)[:, perm])
    assert f.q.shape == (8, feature_dim(n, normals, dim=2))
    np.testing.assert_allclose(f.q, g.q, atol=1e-8)


def test_planar_square_and_degenerate():
    sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    q = phi_planar(sq, strict=True).q
    np.testing.assert_allclose(q, [1, np.pi / 2, 1, np.pi / 2, 1])
    assert not phi_planar(np.array([[0, 0], [1, 1], [2, 2.0]])).valid
    with pytest.raises(DegenerateGraspError, match="collinear"):
        phi_planar(np.array([[0, 0], [1, 1], [2, 2.0]]), strict=True)


def test_planar_hull_face_is_triangulated_canonically():
    """Regression: four contacts on one box face (n=5) gave an order-dependent chain via Qhull."""
    P = np.array([[0.035, 0.0108, -0.1168], [0.035, -0.0584, 0.0719], [-0.035, 0.0798, 0.0915],
                  [0.035, 0.0283, -0.0921], [0.035, 0.0655, -0.0012]])
    f = phi(P, strict=True)
    for perm in ([4, 2, 0, 1, 3], [1, 0, 3, 4, 2], [2, 3, 4, 0, 1]):
        Rm = Rotation.random(random_state=perm[0]).as_matrix()
        np.testing.assert_allclose(phi(P[perm] @ Rm.T).q, f.q, atol=1e-9)


def test_planar_face_grouping_does_not_depend_on_scale_or_position():
    """Regression (found by Hypothesis): a grasp with a near-planar hull face took the canonical path, whose facet
    grouping compared unit normals with a tolerance that grew with the grasp's size, so at some sizes it fanned two
    distinct facets as one face and its area was off by 6e-5. The area is now Qhull's at every size and place."""
    from scipy.spatial import ConvexHull

    P = random_grasp(1447, 8)[0][5]
    area = ConvexHull(P).area
    for s in (1e-3, 1e-2, 1.0, 1e2, 1e3):
        for t in (0.0, 1e3 * s):
            np.testing.assert_allclose(surface_area(P * s + t) / s**2, area, rtol=1e-9)
    np.testing.assert_allclose(surface_area(normalize_scale(P)[0]), 1.0, rtol=1e-9)


@pytest.mark.parametrize("n", [5, 6])
def test_box_surface_grasps_are_order_and_frame_invariant(n):
    """Grasps sampled on a box often put >= 4 contacts on one face; all must stay canonical."""
    from haptic_env.dataset import sample_grasps
    from haptic_env.objects import load_object_set

    rng = np.random.default_rng(n)
    C, N = sample_grasps(load_object_set("default")["box"], 3000, n, rng)
    perm = rng.permutation(n)
    Rm = Rotation.random(random_state=n).as_matrix()
    f, g = phi(C, N), phi((C @ Rm.T)[:, perm], (N @ Rm.T)[:, perm])
    assert f.valid.mean() > 0.98
    np.testing.assert_array_equal(f.valid, g.valid)
    np.testing.assert_allclose(f.q, g.q, atol=1e-7)


# ------------------------------------------------------------- compiled path vs the NumPy oracle
@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(3, 9), normals=st.booleans(), batch=st.sampled_from([12, 200]))
def test_compiled_path_matches_the_numpy_oracle(seed, n, normals, batch):
    """phi and surface_area (the numba kernels at every batch size) give the q, order, validity and area of the
    vectorised NumPy implementation (tests/phi_numpy.py), on random, degenerate and planar-faced grasps."""
    from tests.phi_numpy import phi_numpy, surface_area_numpy

    P, N = random_grasp(seed, n, batch=batch, normals=normals)
    P[0, :, 2] = 0.0  # coplanar (n >= 4) or a flat-lying triangle (n = 3: still valid)
    P[1, 1] = P[1, 0]  # coincident
    P[2] = np.linspace(0, 1, n)[:, None] * [1.0, 2.0, 3.0]  # collinear
    if n >= 4:  # a square of 4 contacts (n = 4: coplanar; n >= 5: a planar hull face, the Qhull triangulation)
        P[3, :4] = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
        P[3, 4:, 2] = np.abs(P[3, 4:, 2]) + 0.5
    q, valid, order, reason = phi_numpy(P, N)
    f = phi(P, N)
    np.testing.assert_array_equal(f.valid, valid)
    np.testing.assert_array_equal(f.reason, reason)
    np.testing.assert_array_equal(f.order, order)
    np.testing.assert_allclose(f.q, q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(surface_area(P), surface_area_numpy(P), rtol=1e-12, atol=1e-15)
    for i in (0, 3, 4):  # single grasps take the same path
        g = phi(P[i], None if N is None else N[i])
        np.testing.assert_allclose(g.q, q[i], rtol=0, atol=1e-12)
        assert g.valid == valid[i]
        np.testing.assert_allclose(surface_area(P[i]), surface_area_numpy(P[i]), rtol=1e-12, atol=1e-15)


def test_compiled_path_raises_the_same_errors():
    P = np.random.default_rng(0).normal(size=(2, 4, 3))
    P[1, 2, 1] = np.inf
    with pytest.raises(ValueError, match="grasp 1 are not finite"):
        phi(P)
    with pytest.raises(ValueError, match="grasp 1 are not finite"):
        surface_area(P)
    N = np.ones((2, 4, 3))
    N[0, 3] = np.nan
    with pytest.raises(ValueError, match="normal 3 of grasp 0 is zero, shorter than 1e-12, .* or not finite"):
        phi(P[:1].repeat(2, 0), N)


def _bitwise_equal(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and bool(np.all((a == b) | (np.isnan(a) & np.isnan(b)))
                                       and np.all(np.signbit(a) == np.signbit(b)))


@pytest.mark.parametrize("normals", [False, True])
def test_two_finger_kernel_equals_the_numpy_oracle_bit_for_bit(normals):
    """Phi_2 (two compiled passes around NumPy's arctan2) gives the NumPy code's bits (tests/phi_numpy.py):
    random grasps over scales, coincident contacts, normals along the line and opposite, signed zeros, axis-aligned
    values; batches and single grasps."""
    from tests.phi_numpy import phi_numpy

    rng = np.random.default_rng(7)
    M = 20_000
    P = rng.normal(size=(M, 2, 3)) * rng.choice([1e-4, 1.0, 1e3], (M, 1, 1))
    N = rng.normal(size=(M, 2, 3)) * rng.choice([1e-6, 1.0, 7.0], (M, 1, 1))
    P[:50, 1] = P[:50, 0]  # coincident
    v = P[50:100, 1] - P[50:100, 0]
    N[50:100] = np.stack([v, -v], axis=1)  # normals along the line (zero twist projections)
    N[100:150] = np.stack([v, v], axis=1)
    grid = np.array([0.0, -0.0, 1.0, -1.0, 0.5])
    P[150:2150] = rng.choice(grid, (2000, 2, 3))
    N[150:2150] = rng.choice(grid, (2000, 2, 3))
    zero = (np.einsum("...k,...k->...", N, N) == 0).any(axis=1)
    N[zero] = 1.0
    N_arg = N if normals else None
    q, valid, order, reason = phi_numpy(P, N_arg)
    f = phi(P, N_arg)
    assert _bitwise_equal(f.q, q)
    np.testing.assert_array_equal(f.valid, valid)
    np.testing.assert_array_equal(f.order, order)
    np.testing.assert_array_equal(f.reason, reason)
    assert not valid[:50].any() and valid[50:].any()
    for i in (0, 60, 120, 200, 5000):
        g = phi(P[i], None if N_arg is None else N[i])
        assert _bitwise_equal(g.q, q[i]) and g.valid == valid[i]


def test_two_finger_kernel_raises_the_same_errors():
    P = np.random.default_rng(0).normal(size=(3, 2, 3))
    P[2, 1, 0] = np.nan
    with pytest.raises(ValueError, match="grasp 2 are not finite"):
        phi(P)
    N = np.ones((2, 2, 3))
    N[1, 0] = 0.0
    with pytest.raises(ValueError, match="normal 0 of grasp 1 is zero, shorter than 1e-12, .* or not finite"):
        phi(P[:2] * 0 + 1.0 + np.arange(2)[:, None, None] * [[0, 0, 0], [1, 0, 0]], N)


@pytest.mark.parametrize("n,normals", [(2, False), (3, True), (4, False), (5, True)])
def test_heights_append_the_contact_heights_in_chain_order(n, normals):
    """phi(heights=True) = [Phi_n, z of the contacts in chain order]: invariant to turns about the vertical and to
    horizontal moves, not to vertical ones; degenerate rows stay all zero."""
    P, N = random_grasp(5, n, batch=32, normals=normals)
    f = phi(P, N)
    fh = phi(P, N, heights=True)
    d = feature_dim(n, normals)
    assert fh.q.shape == (32, feature_dim(n, normals, heights=True)) == (32, d + n)
    np.testing.assert_array_equal(fh.q[:, :d], f.q)
    np.testing.assert_array_equal(fh.q[:, d:], np.take_along_axis(P[:, :, 2], fh.order, axis=1))
    if n > 2 or normals:  # two contacts without normals have no chain order: the heights' own, the lower first
        np.testing.assert_array_equal(fh.order, f.order)
    R = Rotation.from_euler("z", 1.234).as_matrix()
    shift = np.array([0.3, -2.0, 0.0])
    moved = phi(P @ R.T + shift, None if N is None else N @ R.T, heights=True)
    np.testing.assert_allclose(moved.q, fh.q, atol=1e-9)
    swapped = phi(P[:, ::-1], None if N is None else N[:, ::-1], heights=True)  # the fingers in another order
    np.testing.assert_allclose(swapped.q, fh.q, atol=1e-9)
    lifted = phi(P + [0.0, 0.0, 0.5], N, heights=True)
    np.testing.assert_allclose(lifted.q[:, d:], fh.q[:, d:] + 0.5, atol=1e-12)
    flat = np.zeros((1, max(n, 3), 3))  # coincident contacts: no polyhedron
    assert not phi(flat[:, :n], heights=True).q.any()


def test_a_nearly_flat_hull_face_is_grouped_alike_in_every_pose_and_finger_order():
    """Four contacts flat to about 1e-5 of the grasp's size: the planar-face grouping of the ambiguous path compared
    unit normals per axis (a turn about z split the face) and grouped in Qhull's facet order (the fingers' order);
    now every turn and order gives the same vector and area (the facets linked by a pose-free test)."""
    from itertools import permutations

    from scipy.spatial.transform import Rotation

    P = np.array([[1.2565096553428839e-01, 7.7448920908867513e-02, 1.0006409423733347e-05],
                  [2.6196862488829153e-01, -3.1228040870757375e-02, -8.7685184581013863e-06],
                  [-2.3681708051255725e+00, 3.0344607141912495e-02, 9.0717773465503850e-06],
                  [-7.5968597300239382e-01, 2.2993934633839939e-02, -1.0674565894923128e-06],
                  [1.6045130164280344e-02, -8.4880404088263278e-02, 1.2918433900417066e+00]])
    ref, area = phi(P).q, surface_area(P)
    for deg in range(0, 360, 5):
        R = Rotation.from_euler("z", deg, degrees=True).as_matrix()
        np.testing.assert_allclose(phi(P @ R.T).q, ref, atol=1e-9, err_msg=f"turned {deg} deg")
        np.testing.assert_allclose(surface_area(P @ R.T), area, rtol=1e-12)
    for perm in permutations(range(5)):
        np.testing.assert_allclose(phi(P[list(perm)]).q, ref, atol=1e-9, err_msg=f"fingers {perm}")


def test_two_contacts_heights_are_finger_order_invariant_where_the_normals_tie():
    """A pinch across two parallel faces (antiparallel normals: equal angles to the line) has no Phi_2 order: its
    heights came in finger order; now the lower contact's first, with and without normals."""
    P = np.array([[0.035, 0.0, 0.05], [-0.035, 0.0, 0.12]])
    N = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    for normals in (None, N):
        a = phi(P, normals, heights=True)
        b = phi(P[::-1], None if normals is None else normals[::-1], heights=True)
        np.testing.assert_array_equal(a.q, b.q)
        np.testing.assert_array_equal(a.q[-2:], [0.05, 0.12])


def test_feature_dim_with_heights():
    assert feature_dim(4, True, heights=True) == 18 and feature_dim(3, False, heights=True) == 6
    assert feature_dim(2, False, heights=True) == 3
    with pytest.raises(ValueError, match="3-d contacts"):
        feature_dim(4, False, dim=2, heights=True)


# ----------------------------------------------------------------- normal_axis="ab" (each normal in t1's frame)
def _angles_in_t1_frame(P, N, order):
    """Reference: each unit normal's angles (chain order) to t1's normal (b - a) x (c - a) and to the edge b - a."""
    Po = np.take_along_axis(P, order[..., None], 1)
    No = np.take_along_axis(N / np.linalg.norm(N, axis=-1, keepdims=True), order[..., None], 1)
    x = Po[:, 1] - Po[:, 0]
    z = np.cross(Po[:, 1] - Po[:, 0], Po[:, 2] - Po[:, 0])
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    to_z = np.arccos(np.clip(np.einsum("gnk,gk->gn", No, z), -1, 1))
    to_x = np.arccos(np.clip(np.einsum("gnk,gk->gn", No, x), -1, 1))
    return np.stack([to_z, to_x], -1).reshape(len(P), -1)


@pytest.mark.parametrize("n", [3, 4, 5, 7])
def test_normal_axis_ab_reads_every_normal_in_t1s_frame(n):
    """The contact part and the order are the paper's; each normal's angles are to t1's normal and to ab (the
    paper's n = 3 rule at every n), so at n = 3 both settings agree and at n >= 4 only the normal part differs."""
    P, N = random_grasp(n, n, batch=300, normals=True)
    f, g = phi(P, N), phi(P, N, normal_axis="ab")
    assert g.q.shape == f.q.shape == (300, feature_dim(n, True)) and g.valid.all()
    np.testing.assert_array_equal(g.order, f.order)
    np.testing.assert_array_equal(g.q[:, : 3 * n - 6], f.q[:, : 3 * n - 6])
    np.testing.assert_allclose(g.q[:, 3 * n - 6:], _angles_in_t1_frame(P, N, g.order), atol=1e-7)
    if n == 3:
        np.testing.assert_array_equal(g.q, f.q)
    else:
        assert not np.allclose(g.q, f.q)
    # without normals the setting changes nothing
    np.testing.assert_array_equal(phi(P, normal_axis="ab").q, phi(P).q)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(3, 9), motion=rigid, data=st.data(),
       axis=st.sampled_from(["ab", "frame"]))
def test_normal_axis_ab_and_frame_are_invariant_to_rigid_motion_and_finger_order(seed, n, motion, data, axis):
    P, N = random_grasp(seed, n, normals=True)
    Rm = Rotation.random(random_state=motion[0]).as_matrix()
    perm = np.array(data.draw(st.permutations(range(n))))
    f = phi(P, N, normal_axis=axis)
    g = phi((P @ Rm.T + np.array(motion[1]))[:, perm], (N @ Rm.T)[:, perm], normal_axis=axis)
    np.testing.assert_allclose(f.q, g.q, atol=1e-8)


@pytest.mark.parametrize("n", [2, 3, 4, 5, 7])
def test_normal_axis_frame_reads_each_normal_on_all_three_axes_of_t1(n):
    """"frame": the contact part and the order are "ab"'s; each normal has three angles, to t1's normal, to ab and
    to the in-plane direction towards the third contact (6n - 6 values; n = 2 is unchanged). Mirroring every normal
    in the plane of ab and t1's normal leaves "ab"'s vector as it is and changes "frame"'s third angles to pi - x."""
    P, N = random_grasp(n, n, batch=300, normals=True)
    g, h = phi(P, N, normal_axis="ab"), phi(P, N, normal_axis="frame")
    if n == 2:
        np.testing.assert_array_equal(h.q, g.q)
        return
    assert h.q.shape == (300, feature_dim(n, True, normal_axis="frame")) == (300, 6 * n - 6) and h.valid.all()
    np.testing.assert_array_equal(h.order, g.order)
    np.testing.assert_array_equal(h.q[:, : 3 * n - 6], g.q[:, : 3 * n - 6])
    A = h.q[:, 3 * n - 6:].reshape(300, n, 3)
    np.testing.assert_allclose(A[..., :2].reshape(300, -1), g.q[:, 3 * n - 6:], atol=1e-12)
    np.testing.assert_allclose((np.cos(A) ** 2).sum(-1), 1.0, atol=1e-9)  # the three angles of one unit vector
    Po = np.take_along_axis(P, h.order[..., None], 1)
    x = Po[:, 1] - Po[:, 0]
    z = np.cross(x, Po[:, 2] - Po[:, 0])
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    y = np.cross(z, x)
    Nu = N / np.linalg.norm(N, axis=-1, keepdims=True)
    No = np.take_along_axis(Nu, h.order[..., None], 1)
    np.testing.assert_allclose(A[..., 2], np.arccos(np.clip(np.einsum("gnk,gk->gn", No, y), -1, 1)), atol=1e-7)
    # the mirrored normals (y -> -y in t1's frame; the contacts stay)
    M = np.eye(3)[None] - 2 * y[:, :, None] * y[:, None, :]
    Nm = np.einsum("gij,gnj->gni", M, Nu)
    np.testing.assert_allclose(phi(P, Nm, normal_axis="ab").q, g.q, atol=1e-7)
    hm = phi(P, Nm, normal_axis="frame").q[:, 3 * n - 6:].reshape(300, n, 3)
    np.testing.assert_allclose(hm[..., 2], np.pi - A[..., 2], atol=1e-7)
    # without normals the setting changes nothing
    np.testing.assert_array_equal(phi(P, normal_axis="frame").q, phi(P).q)
    assert feature_dim(n, False, normal_axis="frame") == 3 * n - 6


def test_normal_axis_ab_on_coplanar_box_faces_and_bad_values():
    """Planar hull faces of >= 4 contacts (the Qhull path) take the setting too; a bad value is named."""
    from haptic_env.dataset import DatasetConfig, sample_grasps
    from haptic_env.objects import load_object_set

    rng = np.random.default_rng(5)
    C, N = sample_grasps(load_object_set("default")["box"], 2000, 5, rng)
    g = phi(C, N, normal_axis="ab")
    Rm = Rotation.random(random_state=5).as_matrix()
    np.testing.assert_allclose(phi(C @ Rm.T, N @ Rm.T, normal_axis="ab").q, g.q, atol=1e-7)
    v = g.valid
    np.testing.assert_allclose(g.q[v, 9:], _angles_in_t1_frame(C[v], N[v], g.order[v]), atol=1e-7)
    h = phi(C, N, normal_axis="frame")
    np.testing.assert_allclose(phi(C @ Rm.T, N @ Rm.T, normal_axis="frame").q, h.q, atol=1e-7)
    np.testing.assert_allclose(h.q[v, 9:].reshape(-1, 5, 3)[..., :2].reshape(v.sum(), -1), g.q[v, 9:], atol=1e-12)
    with pytest.raises(ValueError, match="normal_axis must be one of .*'t3'"):
        phi(C, N, normal_axis="t3")
    with pytest.raises(ValueError, match="normal_axis must be one of .*'AB'"):
        DatasetConfig(normal_axis="AB")


# ------------------------------------------------------------------- argument checks (the input-validation audit)
COLLINEAR4 = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]


@pytest.mark.parametrize("tol", [-1, -1e-7, 0, 0.0, np.nan, np.inf, -np.inf, "x", None, True, np.array([1e-7]),
                                 np.float64(np.nan), [1e-7]])
def test_tol_must_be_a_finite_number_above_zero(tol):
    """tol=-1 made collinear and coplanar grasps valid (q=[2, 0, 0, 0, pi, 0] for four contacts on a line), nan made
    every n >= 4 grasp coplanar, 'x' / None / an array reached numba (TypingError, 'Cannot unify'); 0 would make the
    degeneracy tests exact comparisons that rounding decides. Every public function taking tol refuses it by name."""
    square = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
    match = "tol must be a finite number > 0, got"
    for call in (lambda: phi(COLLINEAR4, tol=tol), lambda: phi(COLLINEAR4[:3], tol=tol), lambda: phi(square, tol=tol),
                 lambda: phi([[0, 0, 0]] * 3 + [[1, 0, 0]], tol=tol), lambda: phi(COLLINEAR4[:2], tol=tol),
                 lambda: surface_area(COLLINEAR4, tol=tol), lambda: surface_area(COLLINEAR4[:2], tol=tol),
                 lambda: normalize_scale(COLLINEAR4, tol=tol),
                 lambda: phi_planar([[0, 0], [1, 0], [2, 0]], tol=tol)):
        with pytest.raises(ValueError, match=match):
            call()


def test_tol_takes_numpy_scalars_with_the_float_results():
    P, N = random_grasp(3, 5, batch=40, normals=True)
    P[0, :, 2] = 0.0  # coplanar
    for tol in (np.float64(DEFAULT_TOL), np.float32(1e-5), np.int64(1), 1):
        ref = phi(P, N, tol=float(tol))
        f = phi(P, N, tol=tol)
        for a, b in zip(f, ref):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(surface_area(P, tol=tol), surface_area(P, tol=float(tol)))
        np.testing.assert_array_equal(phi_planar(P[..., :2], tol=tol).q, phi_planar(P[..., :2], tol=float(tol)).q)
    assert not phi(COLLINEAR4, tol=np.float64(1e-7)).valid


@pytest.mark.parametrize("n", [2, 3, 4, 5, 6])
@pytest.mark.parametrize("normals", [False, True])
def test_ordinary_grasps_are_unchanged_by_the_checks(n, normals):
    """The checks add no change to a valid call: random grasps at ordinary scales (mm to m), a numpy-scalar tol,
    give the default call's bits and the NumPy oracle's q (bit for bit at n = 2), order, reason and areas."""
    from tests.phi_numpy import phi_numpy, surface_area_numpy

    rng = np.random.default_rng(100 + n)
    P = rng.normal(size=(500, n, 3)) * rng.choice([1e-3, 1.0, 1e3], (500, 1, 1))
    N = rng.normal(size=(500, n, 3)) if normals else None
    f = phi(P, N)
    g = phi(P, N, tol=np.float64(DEFAULT_TOL))
    for a, b in zip(f, g):
        assert _bitwise_equal(a, b)
    q, valid, order, reason = phi_numpy(P, N)
    assert valid.all() and f.valid.all()
    np.testing.assert_array_equal(f.order, order)
    np.testing.assert_array_equal(f.reason, reason)
    if n == 2:
        assert _bitwise_equal(f.q, q)
    else:
        np.testing.assert_allclose(f.q, q, rtol=0, atol=1e-12 * 1e3)
    a = surface_area(P, tol=np.float64(DEFAULT_TOL))
    np.testing.assert_allclose(a, surface_area_numpy(P), rtol=1e-12)
    assert (a > 0).all()
    scaled, s = normalize_scale(P)
    np.testing.assert_array_equal(s, np.sqrt(a))
    np.testing.assert_array_equal(scaled, P / s[:, None, None])


@pytest.mark.parametrize("n", [3, 4, 5])
def test_surface_area_and_normalize_scale_agree_with_phis_verdict(n):
    """At n = 3 surface_area zeroed only collinear triangles: near-coincident contacts (phi's reason 1) kept their
    area (5e-09) and normalize_scale scaled them by 1/7.07e-5 though both promise 0 and factor 1 for degenerate
    grasps. Now both follow phi's verdict at every n, and so does the NumPy oracle."""
    from tests.phi_numpy import surface_area_numpy

    P = np.array([[0, 0, 0], [1e-8, 0, 0], [0, 1, 0]], float)
    assert phi(P).reason == 1
    assert surface_area(P) == 0.0 and surface_area_numpy(P) == 0.0
    scaled, s = normalize_scale(P)
    assert s == 1.0
    np.testing.assert_array_equal(scaled, P)
    B = random_grasp(n, n, batch=8)[0]
    B[0, 1] = B[0, 0] + 1e-9  # near-coincident
    B[1, :, 2] = 0.0  # coplanar (n >= 4)
    B[2] = np.linspace(0, 1, n)[:, None] * [1.0, 2.0, 3.0]  # collinear
    B[3] *= 1e60  # out of range
    f = phi(B)
    a = surface_area(B)
    np.testing.assert_array_equal(a > 0, f.valid)
    np.testing.assert_array_equal(surface_area_numpy(B) > 0, f.valid)
    scaled, s = normalize_scale(B)
    np.testing.assert_array_equal(s[~f.valid], 1.0)
    np.testing.assert_array_equal(scaled[~f.valid], B[~f.valid])


@pytest.mark.parametrize("n", [3.5, 3.0, np.float64(4), "3", None, 1, 0, -2, True, np.int64(1)])
def test_feature_dim_refuses_a_bad_n(n):
    """feature_dim(3.5) gave 4.5, (3.0) 3.0, ('3') a TypeError; n is a whole number >= 2, phi's minimum."""
    with pytest.raises(ValueError, match="a grasp needs at least 2 contacts"):
        feature_dim(n)


def test_feature_dim_checks_dim_and_normal_axis_always():
    """A bad normal_axis passed at n = 2 or without normals (feature_dim(4, False, normal_axis='bogus') gave 6)."""
    for args in ((4, False), (2, True), (2, False), (3, True), (5, True, 2)):
        with pytest.raises(ValueError, match="normal_axis must be one of .*'bogus'"):
            feature_dim(*args, normal_axis="bogus")
    for dim in (3.0, "3", 1, None):
        with pytest.raises(ValueError, match="dim must be 2 or 3"):
            feature_dim(4, dim=dim)
    assert feature_dim(np.int64(4), True) == 14 and type(feature_dim(np.int64(4))) is int
    assert feature_dim(4, False, dim=np.int64(2)) == 5 and feature_dim(2, normal_axis="frame") == 1


def test_grasp_sizes_out_of_range_are_flagged():
    """Two contacts 1e155 apart gave q=[inf] as valid; a right triangle with legs 1e80 got angles of pi/2 as valid,
    legs 1e155 were 'coincident', 1e-160 'collinear'; normalize_scale made legs of 1e200 all-zero contacts with
    factor inf. A diameter outside GRASP_SIZE_RANGE is now reason 4 (zero row, zero area, factor 1)."""
    from haptic_env import _phi_kernels
    from tests.phi_numpy import phi_numpy, surface_area_numpy

    T = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    T4 = np.vstack([T, [0.2, 0.3, 1.0]])
    for s in (1e-160, 1e-60, 1e60, 1e80, 1e155, 1e200):
        for P in (T * s, T4 * s, T[:2] * s, T4[[0, 3]] * s):
            for N in (None, np.ones_like(P)):
                f = phi(P, N)
                assert not f.valid and f.reason == 4 and not f.q.any(), (s, P)
                with np.errstate(all="ignore"):  # the oracle's NumPy overflows out there
                    assert f.reason == phi_numpy(P, N)[3]
            with np.errstate(all="ignore"):
                assert surface_area(P) == 0.0 and surface_area_numpy(P) == 0.0
            scaled, factor = normalize_scale(P)
            assert factor == 1.0 and np.array_equal(scaled, P)
            with pytest.raises(DegenerateGraspError, match="grasp size out of range"):
                phi(P, strict=True)
        assert phi_planar(T[:, :2] * s).reason == 4 and phi_planar(T[:2, :2] * s).reason == 4
    for s in (1e-49, 1e-3, 1e3, 1e49):  # inside: the unit triangle's values, scaled lengths
        for P in (T, T4, T[:2]):
            f, g = phi(P * s), phi(P)
            assert f.valid
            np.testing.assert_allclose(f.q / np.r_[s, np.ones(len(f.q) - 1)], g.q, rtol=1e-12)
            np.testing.assert_allclose(surface_area(P * s) / s**2, surface_area(P), rtol=1e-12)
    assert phi(np.zeros((3, 3))).reason == 1 and phi(np.zeros((2, 3))).reason == 1  # coincident stays coincident
    assert GRASP_SIZE_RANGE == (_phi_kernels.SIZE_MIN, _phi_kernels.SIZE_MAX)


def test_complex_contacts_and_normals_are_refused():
    """Complex input was cast with only a ComplexWarning (the imaginary part dropped)."""
    P, N = random_grasp(0, 4, batch=3, normals=True)
    for call in (lambda: phi(P + 1j), lambda: phi(P[0].astype(np.complex64)), lambda: phi(P[:, :2] + 0j),
                 lambda: surface_area(P + 0j), lambda: surface_area(P[:, :2] + 0j), lambda: normalize_scale(P + 0j),
                 lambda: phi_planar(P[..., :2] + 0j), lambda: phi([[1j, 0, 0], [1, 0, 0], [0, 1, 0]]),
                 lambda: phi([np.complex128(1), 0, 0])):
        with pytest.raises(ValueError, match="contacts must be real numbers, got an array of dtype complex"):
            call()
    for call in (lambda: phi(P, N + 0j), lambda: phi(P[:, :2], N[:, :2] + 0j), lambda: phi_planar(P[..., :2],
                                                                                                N[..., :2] + 0j)):
        with pytest.raises(ValueError, match="normals must be real numbers, got an array of dtype complex"):
            call()
    # an object array of complex numbers (a float() TypeError), and complex input to force closure (its real part
    # taken with a ComplexWarning)
    from haptic_env.force_closure import force_closure

    with pytest.raises(ValueError, match="contacts must be real numbers"):
        phi(np.array([[1j, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=object))
    for call, what in ((lambda: force_closure(P + 5j, N), "contacts"), (lambda: force_closure(P, N + 0j), "normals")):
        with pytest.raises(ValueError, match=f"{what} must be real numbers, got an array of dtype complex"):
            call()
    # a single grasp with a batch of normals: the shapes as given (both were reported with the batch axis)
    for call in (lambda: phi(P[0], N[:1]), lambda: force_closure(P[0], N[:1])):
        with pytest.raises(ValueError, match=r"normals must have the shape of contacts \(4, 3\), got \(1, 4, 3\)"):
            call()
    # yes / no settings are flags, not truthy values ("no" gave the vector with heights, 14 values for normals)
    for call, name in ((lambda: phi(P, heights="no"), "heights"), (lambda: phi(P, strict="no"), "strict"),
                       (lambda: feature_dim(4, normals="no"), "normals"),
                       (lambda: feature_dim(4, heights=1), "heights")):
        with pytest.raises(ValueError, match=f"{name} must be a bool"):
            call()
    # real input of any real dtype (and lists) is taken as before
    P32, N32 = P.astype(np.float32), N.astype(np.float32)
    np.testing.assert_array_equal(phi(P32, N32).q, phi(P32.astype(float), N32.astype(float)).q)
    T = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    np.testing.assert_array_equal(phi(T).q, phi(np.array(T, float)).q)
    np.testing.assert_array_equal(surface_area(T), surface_area(np.array(T, float)))


def test_topology_tables_are_read_only():
    """The index tables are cached and shared by every caller: writing to one must fail, not corrupt Phi_n."""
    from haptic_env.grasp_features import _topology

    for a in _topology(5)[:3]:
        with pytest.raises(ValueError, match="read-only"):
            a[...] = 0
