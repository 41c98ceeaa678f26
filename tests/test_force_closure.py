"""Tests of haptic_env.force_closure: the force-closure test of frictional point contacts."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

from haptic_env.dataset import sample_grasps
from haptic_env.force_closure import FRAMES, check_friction, epsilon_quality, force_closure, primitive_wrenches

force_closure_ = force_closure
from haptic_env.objects import load_object_set


def _equator(k: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """``k`` contacts evenly round a unit sphere's equator, normals pointing to its centre."""
    a = 2 * np.pi * np.arange(k) / k
    C = np.stack([np.cos(a), np.sin(a), np.zeros(k)], axis=1)
    return C, -C


@pytest.mark.parametrize("method", ["auto", "search", "qhull"])
def test_textbook_grasps(method):
    force_closure = partial(force_closure_, method=method)
    C, N = _equator(3)
    assert force_closure(C, N, mu=0.5) is True  # three fingers round a ball hold it with friction
    assert force_closure(C, N, mu=0.0) is False  # frictionless: 3 normals cannot span 6 wrench directions
    assert force_closure(C, N, mu=0.05) is True  # any friction: squeezing harder makes up for it
    assert force_closure(C, np.tile([0.0, 0.0, 1.0], (3, 1)), mu=0.5) is False  # all pushing the same way
    tip = np.vstack([C, [[0.0, 0.0, 1.0]]])
    assert force_closure(tip, np.vstack([N, [[0.0, 0.0, -1.0]]]), mu=0.5) is True
    # invariant to moving and scaling the grasp, and to the contacts' order
    R = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))[0]
    assert force_closure(3.0 * C @ R.T + [1.0, -2.0, 0.5], N @ R.T, mu=0.5) is True
    assert force_closure(C[::-1], N[::-1], mu=0.5) is True


@pytest.mark.parametrize("method", ["auto", "search", "qhull"])
def test_degenerate_grasps_are_not_in_closure(method):
    force_closure = partial(force_closure_, method=method)
    C, N = _equator(3)
    assert force_closure(C[:2], N[:2], mu=1.0) is False  # two point contacts never are
    assert force_closure(np.zeros((3, 3)), N, mu=0.5) is False  # coincident contacts
    assert force_closure(C, np.zeros((3, 3)), mu=0.5) is False  # zero normals
    line = np.stack([np.linspace(-1, 1, 3), np.zeros(3), np.zeros(3)], axis=1)
    assert force_closure(line, np.tile([0.0, 1.0, 0.0], (3, 1)), mu=0.5) is False  # collinear
    assert force_closure(np.zeros((0, 3, 3)), np.zeros((0, 3, 3)), mu=0.5).shape == (0,)


def test_fast_methods_give_qhulls_answers_on_random_grasps():
    obj = load_object_set("default")["mug"]
    rng = np.random.default_rng(1)
    for n in (3, 4):
        C, N = sample_grasps(obj, 600, n, rng)
        exact = force_closure(C, N, 0.5, method="qhull")
        np.testing.assert_array_equal(force_closure(C, N, 0.5, method="search"), exact)
        np.testing.assert_array_equal(force_closure(C, N, 0.5), exact)
        assert 0 < exact.sum() < len(exact)  # both kinds occur, so the comparison means something
    # more friction holds more grasps, and every grasp held at mu holds at 2 mu
    lo, hi = force_closure(C, N, 0.3), force_closure(C, N, 0.6)
    assert lo.sum() < hi.sum() and not (lo & ~hi).any()


@pytest.mark.parametrize("mu,edges", [(0.2, 3), (0.5, 4), (1.0, 4), (0.5, 8)])
def test_plane_reduction_gives_qhulls_answers_at_three_contacts(mu, edges):
    """The planar reduction (three contacts) on grasps of every kind: most out of closure, enough in it."""
    rng = np.random.default_rng(2)
    objects = load_object_set("default")
    C, N = (np.concatenate(a) for a in zip(*(sample_grasps(o, 300, 3, rng) for o in objects)))
    exact = force_closure(C, N, mu, edges, method="qhull")
    np.testing.assert_array_equal(force_closure(C, N, mu, edges, method="plane"), exact)
    assert exact.sum() >= 10 and (~exact).sum() >= 10


def test_a_pyramid_that_only_touches_the_contact_plane_is_not_cut_by_it():
    """Three contacts on the equator, contact 0's normal 45 degrees out of their plane at mu = 1: one edge of its
    pyramid lies in the plane (z = -1e-16 after rounding), the others above, so its out-of-plane force has one sign
    and the grasp is not in closure. The planar reduction said True (its sector shrank to that edge), every other
    method and epsilon_quality False."""
    a = 2 * np.pi * np.arange(3) / 3
    C = np.stack([np.cos(a), np.sin(a), np.zeros(3)], axis=1)
    N = -C.copy()
    N[0] = [-np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4)]
    for frame in FRAMES:
        answers = {m: bool(force_closure(C, N, 1.0, 4, frame=frame, method=m)) for m in ("plane", "search", "qhull")}
        assert answers == {"plane": False, "search": False, "qhull": False}, (frame, answers)
        assert epsilon_quality(C, N, 1.0, 4, frame=frame) == 0.0


def test_plane_reduction_refuses_other_finger_counts_and_bad_methods():
    C, N = _equator(4)
    with pytest.raises(ValueError, match="three-contact grasps only, got 4"):
        force_closure(C, N, method="plane")
    with pytest.raises(ValueError, match="method must be one of .* got 'lp'"):
        force_closure(C, N, method="lp")


def test_epsilon_quality_is_positive_exactly_in_closure_and_bounded_by_the_support_function():
    obj = load_object_set("default")["mug"]
    C, N = sample_grasps(obj, 300, 4, np.random.default_rng(2))
    eps = epsilon_quality(C, N, 0.5)
    held = force_closure(C, N, 0.5)
    assert eps.shape == (300,) and 0 < held.sum() < 300
    np.testing.assert_array_equal(eps > 0, held)
    # the largest origin-centred ball in the hull is no wider than the hull's support in any direction
    W = primitive_wrenches(C[held], N[held], 0.5)
    d = np.random.default_rng(3).normal(size=(4000, 6))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    support = np.einsum("bmk,dk->bdm", W, d).max(axis=2).min(axis=1)
    assert np.all(eps[held] <= support + 1e-12)
    # and, checked by linear programs (is p a convex combination of the wrenches?) on a few grasps: the ball of
    # radius eps lies in the hull in random directions, and just beyond eps the hull ends in the nearest facet's
    from scipy.optimize import linprog
    from scipy.spatial import ConvexHull

    def inside(w, p):
        return linprog(np.zeros(len(w)), A_eq=np.vstack([w.T, np.ones(len(w))]), b_eq=np.append(p, 1.0),
                       bounds=(0, None), method="highs").status == 0

    for w, e in list(zip(W, eps[held]))[:4]:
        assert all(inside(w, 0.999 * e * u) for u in d[:20])
        eq = ConvexHull(w).equations
        nearest = eq[np.argmax(eq[:, -1]), :-1]
        assert inside(w, 0.999 * e * nearest) and not inside(w, 1.001 * e * nearest)


def test_epsilon_quality_of_textbook_grasps():
    C, N = _equator(3)
    q = epsilon_quality(C, N, 0.5)
    assert isinstance(q, float) and q > 0
    assert epsilon_quality(C, N, 0.2) < q  # less friction, a weaker grasp
    assert epsilon_quality(C, N, 0.0) == 0.0 and epsilon_quality(C[:2], N[:2], 0.5) == 0.0
    assert epsilon_quality(3.0 * C + [1.0, -2.0, 0.5], N, 0.5) == pytest.approx(q)  # size and place do not matter
    # a rotation turns the pyramids about their normals (their edges follow the frame); many edges approach the cone
    R = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))[0]
    assert epsilon_quality(C @ R.T, N @ R.T, 0.5, edges=64) == pytest.approx(epsilon_quality(C, N, 0.5, edges=64),
                                                                             rel=0.01)
    with pytest.raises(ValueError, match="mu"):
        epsilon_quality(C, N, -1.0)


def test_wrenches_shape_and_units():
    C, N = _equator(3)
    W = primitive_wrenches(C, N, mu=0.5, edges=6)
    assert W.shape == (18, 6)
    np.testing.assert_allclose(W[:, :3].reshape(3, 6, 3).mean(axis=1), N, atol=1e-12)  # the edges surround the normal
    Wb = primitive_wrenches(100.0 * C[None], 7.0 * N[None], mu=0.5, edges=6)  # neither length unit nor |normal| counts
    np.testing.assert_allclose(Wb[0], W, atol=1e-12)


@pytest.mark.parametrize("kwargs,match", [
    ({"mu": -0.1}, "mu"), ({"mu": float("nan")}, "mu"), ({"edges": 2}, "edges"), ({"edges": 3.5}, "edges"),
    ({"frame": "object"}, "frame"),
])
def test_bad_arguments_are_named(kwargs, match):
    C, N = _equator(3)
    with pytest.raises(ValueError, match=match):
        force_closure(C, N, **kwargs)


def test_bad_shapes_are_named():
    C, N = _equator(3)
    with pytest.raises(ValueError, match="contacts must have shape"):
        force_closure(C[:, :2], N[:, :2])
    with pytest.raises(ValueError, match="normals must have the shape"):
        force_closure(C, N[:2])


def test_check_friction_names_the_setting_and_value():
    assert check_friction(1) == 1.0 and isinstance(check_friction(np.float32(0.5)), float)
    for bad in (0, -0.5, float("inf"), float("nan"), True, "0.5", None):
        with pytest.raises(ValueError, match=r"mu_filter \(a friction coefficient\) must be a finite number > 0"):
            check_friction(bad, "mu_filter")


@pytest.mark.parametrize("n", [3, 4])
def test_grasp_frame_follows_the_grasp_alone(n):
    """``frame="grasp"``: the answers and qualities of random mug grasps do not change under a rotation and move of
    the grasp or a new contact order, where the axes' pyramids change many answers (the module docstring's
    figures); every method agrees with Qhull; each pyramid's first edge leans towards the centroid."""
    mug = load_object_set("default")["mug"]
    rng = np.random.default_rng(n)
    C, N = sample_grasps(mug, 3000 if n == 3 else 1000, n, rng)
    R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    R *= np.sign(np.linalg.det(R))
    moved, perm = (C @ R.T + [0.2, -0.1, 0.3], N @ R.T), rng.permutation(n)
    base = force_closure(C, N, 0.5, frame="grasp")
    assert 0 < base.sum() < len(base)
    assert np.array_equal(force_closure(*moved, 0.5, frame="grasp"), base)
    assert np.array_equal(force_closure(C[:, perm], N[:, perm], 0.5, frame="grasp"), base)
    assert np.array_equal(force_closure(C, N, 0.5, method="qhull", frame="grasp"), base)
    assert not np.array_equal(force_closure(*moved, 0.5), force_closure(C, N, 0.5))  # the axes' frame: not so
    held = np.flatnonzero(base)[:20]
    np.testing.assert_allclose(epsilon_quality(moved[0][held], moved[1][held], 0.5, frame="grasp"),
                               epsilon_quality(C[held], N[held], 0.5, frame="grasp"), rtol=1e-7)
    W = primitive_wrenches(C[:1], N[:1], 0.5, edges=4, frame="grasp")[0]
    first = W.reshape(n, 4, 6)[:, 0, :3] - N[0]  # each pyramid's first edge minus its normal: mu t1
    towards = C[0].mean(axis=0) - C[0]
    towards -= (towards * N[0]).sum(axis=1, keepdims=True) * N[0]
    np.testing.assert_allclose(first, 0.5 * towards / np.linalg.norm(towards, axis=1, keepdims=True), atol=1e-12)
    assert FRAMES[0] == "axes"  # the default, which the committed force-closure results used


def test_grasp_frame_falls_back_where_the_centroid_is_along_the_normal():
    """Contacts round a ball whose normals point straight at the contacts' centroid have no tangential direction
    to it: the axes' basis, the same wrenches, finite, still in closure."""
    C, N = _equator(3)
    ball = np.vstack([C, [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]])
    W = primitive_wrenches(ball, -ball, 0.5, frame="grasp")
    assert np.isfinite(W).all() and force_closure(ball, -ball, 0.5, frame="grasp") is True
    np.testing.assert_allclose(W, primitive_wrenches(ball, -ball, 0.5, frame="axes"), atol=1e-12)


# a regular tetrahedron's corners on the unit sphere, normals to the centre: in force closure at mu = 0.5
_C4 = np.array([[1.0, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]]) / np.sqrt(3)
_N4 = -_C4


@pytest.mark.parametrize("bad", [[np.nan, np.nan, np.nan], [np.nan, 0.0, 1.0], [np.inf, 0.0, 0.0]])
def test_non_finite_normals_are_refused_not_read_as_no_contact(bad):
    """A NaN normal used to count as a zero normal (no contact): the tetrahedron plus a NaN-normal fifth contact came
    out in closure (epsilon 0.27) with zero wrenches for that contact."""
    C, N = np.vstack([_C4, [[0.0, 0.0, 1.0]]]), np.vstack([_N4, [bad]])
    calls = [lambda: primitive_wrenches(C, N, 0.5), lambda: epsilon_quality(C, N),
             *(partial(force_closure, C, N, method=m) for m in ("auto", "search", "qhull"))]
    for call in calls:
        with pytest.raises(ValueError, match=r"normals must be finite, got normals\[4\] = \[(nan|inf)"):
            call()
    with pytest.raises(ValueError, match=r"normals must be finite, got normals\[1, 4\]"):
        force_closure(np.stack([C, C]), np.stack([np.vstack([_N4, [[0.0, 0.0, -1.0]]]), N]))


@pytest.mark.parametrize("bad", [np.inf, -np.inf, np.nan])
def test_non_finite_contacts_are_refused(bad):
    """An infinite contact used to scale every torque to 0 (finite wrenches, answer False); NaN gave False."""
    C = _C4.copy()
    C[0, 0] = bad
    calls = [lambda: primitive_wrenches(C, _N4, 0.5), lambda: force_closure(C, _N4), lambda: epsilon_quality(C, _N4),
             lambda: force_closure(C[:3], _N4[:3], method="plane")]
    for call in calls:
        with pytest.raises(ValueError, match=r"contacts must be finite, got contacts\[0\] = \[(nan|-?inf)"):
            call()


def test_a_grasp_without_contacts_is_not_in_closure():
    """No contacts resist nothing (documented): not in closure, epsilon 0, no wrenches; an empty batch is empty."""
    for method in ("auto", "search", "qhull"):
        assert force_closure(np.zeros((0, 3)), np.zeros((0, 3)), method=method) is False
        np.testing.assert_array_equal(force_closure(np.zeros((2, 0, 3)), np.zeros((2, 0, 3)), method=method),
                                      [False, False])
        assert force_closure(np.zeros((0, 0, 3)), np.zeros((0, 0, 3)), method=method).shape == (0,)
    assert epsilon_quality(np.zeros((0, 3)), np.zeros((0, 3))) == 0.0
    np.testing.assert_array_equal(epsilon_quality(np.zeros((2, 0, 3)), np.zeros((2, 0, 3)), frame="grasp"), [0.0, 0.0])
    assert epsilon_quality(np.zeros((0, 0, 3)), np.zeros((0, 0, 3))).shape == (0,)
    assert epsilon_quality(np.zeros((0, 4, 3)), np.zeros((0, 4, 3))).shape == (0,)
    assert primitive_wrenches(np.zeros((0, 3)), np.zeros((0, 3)), 0.5).shape == (0, 6)
    assert primitive_wrenches(np.zeros((2, 0, 3)), np.zeros((2, 0, 3)), 0.5, 5).shape == (2, 0, 6)
    with pytest.raises(ValueError, match="three-contact grasps only, got 0"):
        force_closure(np.zeros((0, 3)), np.zeros((0, 3)), method="plane")


def test_valid_grasps_keep_their_answers():
    """The checks change no valid answer: the tetrahedron's epsilon and its wrenches from the formula."""
    assert force_closure(_C4, _N4) is True
    W = primitive_wrenches(_C4, _N4, 0.5)
    r = _C4 / np.linalg.norm(_C4, axis=1).max()  # centroid 0, unit size
    np.testing.assert_allclose(W[:, 3:], np.cross(np.repeat(r, 4, axis=0), W[:, :3]), rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.einsum("ij,ij->i", W[:, :3], np.repeat(_N4, 4, axis=0)), 1.0, rtol=0, atol=1e-15)
    eps = epsilon_quality(_C4, _N4)
    assert eps > 0 and eps == epsilon_quality(np.stack([_C4, _C4]), np.stack([_N4, _N4]))[1]
    assert eps == pytest.approx(0.3150057631523782, rel=1e-6)  # pinned: a check that moved the answer fails here
