r"""One grasp to its KDE log-likelihoods in one compiled call: :math:`\log p(\Phi_n(P, N) \mid c)`.

An environment step scores one complete grasp. Through the general path (``Recognizer.features`` ->
``phi`` -> ``KDELikelihood.log_likelihood``) that is about ten Python calls and a dozen small NumPy
arrays around two compiled kernels; :class:`GraspScorer` runs :math:`\Phi_n`, the standardisation and
the pooled KDE search in one numba call instead (same kernels, same results: tested equal to the
general path). It applies to a recogniser whose KDE uses ``method="pooled"`` and that does not
scale-normalise grasps; :meth:`haptic_env.recognizers.Recognizer.grasp_scorer` returns None otherwise.
With gradient boosting in the KDE's place (``RecognizerConfig.likelihood="hgb"``) it runs :math:`\Phi_n` compiled and
hands the vector to :meth:`~haptic_env.recognizers.boosted.BoostedLikelihood.log_likelihood` (its own compiled walk).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from haptic_env import _phi_kernels as phik
from haptic_env.grasp_features import DEFAULT_TOL, _topology, feature_dim, normals_code, phi
from haptic_env.numbers import whole_number
from haptic_env.recognizers.boosted import BoostedLikelihood
from haptic_env.recognizers.knn import log_density_row, workspace

__all__ = ["GraspScorer"]


class GraspScorer:
    """``scorer(contacts (n, 3), normals (n, 3) | None) -> (q (d,), log_lik (1, K) | None)``.

    ``log_lik`` is None for a degenerate grasp (then ``q`` is all zeros, as :func:`phi` reports it).
    ``post``, if given, maps the log-likelihoods ``(B, K) -> (B, K)`` (the KDE's calibration,
    :meth:`~.kde.KDELikelihood.calibrate_scores`). ``kde``: a KDE evaluated ``"pooled"`` (searched in the same
    compiled call as Phi) or a :class:`~haptic_env.recognizers.boosted.BoostedLikelihood` (Phi compiled, then its
    walk).
    """

    def __init__(self, n_fingers: int, normals: bool, kde, post=None, heights: bool = False, normal_axis: str = "t2"):
        if (whole_number(n_fingers) or 0) < 3:  # n = 2 (a distance) has no facets: the kernel failed to compile
            raise ValueError(f"GraspScorer needs n_fingers >= 3 (two contacts are scored by the KDE directly), "
                             f"got {n_fingers!r}")
        if post is not None and not callable(post):
            raise TypeError(f"post must be a callable (B, K) -> (B, K) or None, got {type(post).__name__}")
        self.post = post
        if not self.handles(kde):
            raise ValueError("GraspScorer needs a KDE evaluated with method='pooled' or a BoostedLikelihood, got "
                             f"{type(kde).__name__}" + (" without a pooled index" if hasattr(kde, "pooled") else ""))
        d = feature_dim(n_fingers, normals, heights=heights, normal_axis=normal_axis)
        if kde.n_features != d:
            raise ValueError(f"the likelihood has {kde.n_features} features, {n_fingers} fingers (normals={normals}, "
                             f"heights={heights}) give {d}")
        self.n_fingers, self.normals, self.kde, self.heights = int(n_fingers), bool(normals), kde, bool(heights)
        self.normal_axis = normal_axis
        self._normals_code = normals_code(self.normals, normal_axis)  # the kernels' has_normals (0-3)
        tri, tri_edges, _, n_edges = _topology(self.n_fingers)
        self._phi_args = (tri, tri_edges, n_edges, DEFAULT_TOL, feature_dim(n_fingers, normals, normal_axis=normal_axis),
                          self.heights)
        self._kde_args = None  # gradient boosting: Phi compiled here, the scores by the model's own walk
        if not isinstance(kde, BoostedLikelihood):  # a pooled KDE: searched in the same compiled call as Phi
            cfg = kde.config
            self._kde_args = (kde.scaler.mean, kde.scaler.std, *kde.pooled.arrays(), kde.pooled_labels,
                              min(cfg.k, kde.pooled.n), float(cfg.eps), kde._norms(), 0.5 / kde.bandwidth**2,
                              cfg.cutoff * kde.bandwidth)
            self._work = workspace(kde.pooled.nodes, d, min(cfg.k, kde.pooled.n), kde.n_classes)
        self._d, self._K = d, kde.n_classes

    @staticmethod
    def handles(model) -> bool:
        """Whether ``model`` (a recogniser's likelihood slot) is one this scorer runs: a KDE evaluated ``"pooled"``
        or a :class:`~haptic_env.recognizers.boosted.BoostedLikelihood`."""
        return getattr(model, "pooled", None) is not None or isinstance(model, BoostedLikelihood)

    def __call__(self, contacts, normals=None) -> tuple[np.ndarray, np.ndarray | None]:
        P = np.ascontiguousarray(contacts, dtype=np.float64)
        N = None if normals is None else np.ascontiguousarray(normals, dtype=np.float64)
        if P.shape != (self.n_fingers, 3) or (N is None) == self.normals or (N is not None and N.shape != P.shape):
            raise ValueError(f"GraspScorer takes contacts (and normals={self.normals}) of shape ({self.n_fingers}, 3), "
                             f"got {P.shape}" + ("" if N is None else f" and {N.shape}"))
        q = np.zeros(self._d)
        order = np.empty(self.n_fingers, np.int64)
        if self._kde_args is None:
            status = _phi_row(P, P if N is None else N, self._normals_code, *self._phi_args, q, order)
            if status == 0:
                return q, self._finish(self.kde.log_likelihood(q))
        else:
            out = np.empty((1, self._K))
            status = _score(P, P if N is None else N, self._normals_code, *self._phi_args, *self._kde_args, self._work,
                            q, order, out[0])
            if status == 0:
                return q, self._finish(out)
        if status > 0:  # degenerate: no information
            return np.zeros(self._d), None
        # a planar hull face (Qhull's canonical triangulation) or bad input (raises): the general path
        f = phi(P, N, heights=self.heights, normal_axis=self.normal_axis)
        return (f.q, self._finish(self.kde.log_likelihood(f.q))) if f.valid else (f.q, None)

    def _finish(self, ll: np.ndarray) -> np.ndarray:
        return self.post(ll) if self.post is not None else ll


    def batch(self, contacts, normals=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`__call__` of ``B`` complete grasps ``(B, n, 3)`` in one compiled call (a vector env's step):
        ``(q (B, d), log_lik (B, K), scored (B,) bool)``; rows of unscored (degenerate) grasps have ``q = 0`` and
        undefined ``log_lik``. Row ``b`` equals ``self(contacts[b], normals[b])`` bit for bit."""
        P = np.ascontiguousarray(contacts, dtype=np.float64)
        N = None if normals is None else np.ascontiguousarray(normals, dtype=np.float64)
        B = P.shape[0] if P.ndim == 3 else -1
        if P.shape != (B, self.n_fingers, 3) or (N is None) == self.normals or (N is not None and N.shape != P.shape):
            raise ValueError(f"GraspScorer.batch takes contacts (and normals={self.normals}) of shape "
                             f"(B, {self.n_fingers}, 3), got {P.shape}" + ("" if N is None else f" and {N.shape}"))
        q = np.zeros((B, self._d))
        out = np.empty((B, self._K))
        status = np.empty(B, np.int64)
        if self._kde_args is None:
            _phi_batch(P, P if N is None else N, self._normals_code, *self._phi_args, q, status)
            scored = status == 0
            if scored.any():
                out[scored] = self._finish(self.kde.log_likelihood(q[scored]))
        else:
            _score_batch(P, P if N is None else N, self._normals_code, *self._phi_args, *self._kde_args, self._work, q,
                         out, status)
            scored = status == 0
            out[scored] = self._finish(out[scored])
        for b in np.flatnonzero(status < 0):  # a planar hull face or bad input: the general path, as __call__
            f = phi(P[b], None if N is None else N[b], heights=self.heights, normal_axis=self.normal_axis)
            q[b] = f.q
            if f.valid:
                out[b] = self._finish(self.kde.log_likelihood(f.q))[0]
                scored[b] = True
        q[status > 0] = 0.0
        return q, out, scored


@njit(cache=True)
def _score_batch(P, N, has_normals, tri, tri_edges, n_edges, tol, d_phi, has_heights, mean, std, data, nodes, split,
                 labels, k, eps, log_norms, inv, radius, work, q, out, status):
    """:func:`_score` of ``B`` grasps (the same kernels, one row at a time)."""
    order = np.empty(P.shape[1], np.int64)
    for b in range(P.shape[0]):
        status[b] = _score(P[b], N[b], has_normals, tri, tri_edges, n_edges, tol, d_phi, has_heights, mean, std, data,
                           nodes, split, labels, k, eps, log_norms, inv, radius, work, q[b], order, out[b])


@njit(cache=True)
def _phi_row(P, N, has_normals, tri, tri_edges, n_edges, tol, d_phi, has_heights, q, order):
    """Phi of one grasp into ``q[:d_phi]`` (and with ``has_heights`` the contacts' heights in chain order into the
    rest), as :func:`_score` computes it; returns the Phi status."""
    status = phik.phi_checked(P, N, has_normals, tri, tri_edges, n_edges, tol, q[:d_phi], order,
                              np.empty((P.shape[0], 3)))
    if status == 0 and has_heights:
        for i in range(P.shape[0]):
            q[d_phi + i] = P[order[i], 2]
    return status


@njit(cache=True)
def _phi_batch(P, N, has_normals, tri, tri_edges, n_edges, tol, d_phi, has_heights, q, status):
    """:func:`_phi_row` of ``B`` grasps."""
    order = np.empty(P.shape[1], np.int64)
    for b in range(P.shape[0]):
        status[b] = _phi_row(P[b], N[b], has_normals, tri, tri_edges, n_edges, tol, d_phi, has_heights, q[b], order)


@njit(cache=True)
def _score(P, N, has_normals, tri, tri_edges, n_edges, tol, d_phi, has_heights, mean, std, data, nodes, split, labels,
           k, eps, log_norms, inv, radius, work, q, order, out):
    """Phi of one grasp into ``q[:d_phi]`` (and with ``has_heights`` the contacts' heights in chain order into the
    rest), then its pooled-KDE log densities into ``out``; returns the Phi status."""
    status = _phi_row(P, N, has_normals, tri, tri_edges, n_edges, tol, d_phi, has_heights, q, order)
    if status != 0:
        return status
    z = (q - mean) / std
    log_density_row(data, nodes, split, labels, z, k, eps, log_norms, inv, radius, work, out)
    return 0
