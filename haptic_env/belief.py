r"""The belief over the ``K`` objects: grasp :math:`\to q = \Phi_n \to` likelihood :math:`\to` posterior.

:class:`Belief` is the one owner of that chain. The env, the greedy agent and the experiments use only its
public API:

=================================  ===================================================================
``reset(prior, *, support_z)``     forget all grasps (returns the prior); the episode's table height
``update(contacts, normals, t)``   one real grasp -> ``(q, usable)``; the posterior moves if usable
``update_rows(Q)``                 one grasp given as its score rows ``(m, d)`` (precomputed vectors)
``rows(contacts, normals, t)``     the grasp vector and score rows of one grasp (no state change)
``rows_batch(C, N, T)``            the same for ``B`` grasps ``(B, n, 3)``: vectorised for complete grasps
``predict(rows)``                  the posteriors after one more grasp for ``G`` candidates (no change)
``predict_grasps(C, N, T)``        ``rows_batch`` + ``predict``: what ``B`` simulated grasps would do
``touch_rows(T)``                  the weighted touch-pattern log-likelihoods of ``B`` grasps (``touch_weight``)
``scores(Q)``                      the models' ``(log_lik, proba)`` of score rows
``subset_scores(C, N, z, k, rng)`` batched z-subset scoring of ``G`` grasps (paper, Algorithms 3 and 4)
``probs`` / ``certainty`` /        the posterior ``(K,)``, its certainty, whether it decided, the grasps
``decided`` / ``n_grasps``         that updated it
=================================  ===================================================================

Which grasps update the belief: a grasp with all ``n`` fingers touching, scored by the ``n``-finger model; with
``z_fingers`` also an incomplete grasp of ``t >= z`` touching fingers, by the ``t``-finger model; with
``score_subsets`` every grasp of ``t >= z`` touching fingers through its ``z``-subsets by the ``z``-finger model,
and with ``min_fingers = m`` also one of ``m <= t < z``, by the ``t``-finger model.
The ``C(t, z)`` subsets of one grasp share its contacts, so a Bayesian belief counts them as at most ``subset_k`` (the
paper's Algorithm 4 scores ``k = 4`` random subsets): their summed log-likelihood is multiplied by
``min(1, subset_k / m)``, ``m`` the subsets scored (``C(t, z)`` unless some are degenerate), the expected sum of
``subset_k`` random ones, without the draw (``None``: the plain product over all of them, Algorithm 3). With ``z = 3``
this changes nothing for 4 fingers (``C(4, 3) = 4``).
A recogniser whose grasp vectors carry the contacts' heights above the table (``DatasetConfig.heights``) reads
the contacts in the support frame: the belief holds the episode's table height ``support_z`` (world z, set by
``reset``; :func:`~haptic_env.grasping.base.support_height`) and subtracts it from every grasp it scores.
Fewer than two touching fingers, or degenerate contacts (coplanar, ...), carry no information, unless the
belief also weighs the hand's *touch pattern* (``touch_weight > 0``, :mod:`haptic_env.recognizers.touch`): then
every grasp adds ``w log P(pattern | object)`` to the contacts' log-likelihoods in the same Bayes step.

Complete grasps of a Bayesian updater over a pooled KDE take a compiled path (:class:`GraspScorer`: Phi and the
KDE search in one call; with gradient boosting, Phi compiled and then its walk; ``compiled=False`` forces the
general path, which gives the same result).

The maths of the posterior step live in :mod:`haptic_env.recognizers.updaters` (IC, BC-NP, BC-IP), whose
:func:`~haptic_env.recognizers.updaters.bayes_steps` updates ``B`` log beliefs ``(B, K)`` in one call:
:meth:`predict` uses it for ``G`` candidate grasps, and the native vector env's fast path uses it with the compiled
:class:`~haptic_env.recognizers.scorer.GraspScorer` for ``B`` episodes at once.

The recognisers themselves are built (or loaded from the cache) once per process per configuration
(:func:`get_recognizer`).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from typing import TYPE_CHECKING, Any

import numpy as np

from haptic_env.grasp_features import feature_dim
from haptic_env.recognizers.touch import check_touch_updater, check_touch_weight
from haptic_env.recognizers.updaters import DEFAULT_IC_CERTAINTY, DEFAULT_THRESHOLD, DEFAULT_UPDATER, UPDATERS
from haptic_env.recognizers.zfinger import (DEFAULT_SUBSET_K, check_min_fingers, check_subset_k, check_z_fingers,
                                             subset_weight)

if TYPE_CHECKING:
    from haptic_env.config import HapticRecogConfig

__all__ = ["Belief", "get_recognizer", "check_grasp_vectors"]

#: Recognisers kept in memory per process (the envs of one process share them; each is on disk too).
MAX_RECOGNIZERS = 4
_RECOGNIZERS: OrderedDict[str, Any] = OrderedDict()  # least recently used first


def get_recognizer(objects, config: HapticRecogConfig):
    """The recogniser for ``objects`` and ``config`` (built/cached on disk once, then memoised per process: the last
    :data:`MAX_RECOGNIZERS` used stay in memory, so a long process that goes through many configs stays flat)."""
    from haptic_env.cache import config_key
    from haptic_env.config import recognizer_kwargs

    lowest = config.z_fingers if config.min_fingers is None else config.min_fingers
    z_values = tuple(range(lowest, config.n_fingers)) if lowest is not None else ()
    kwargs = recognizer_kwargs(config)  # torch: imported on first use only
    from haptic_env.recognizers import build_recognizer, models_for

    kwargs.setdefault("models", models_for(config.updater))  # BC-NP: the KDE only
    # the meshes' hashes, not only their names: a set loaded in other units or from another folder is another set
    key = config_key(objects.name, objects.identity, config.n_fingers, config.normals, z_values, kwargs)
    if key in _RECOGNIZERS:
        _RECOGNIZERS.move_to_end(key)
        return _RECOGNIZERS[key]
    rec = build_recognizer(objects, config.n_fingers, config.normals, z_values=z_values, **kwargs)
    _RECOGNIZERS[key] = rec
    while len(_RECOGNIZERS) > MAX_RECOGNIZERS:
        _RECOGNIZERS.popitem(last=False)
    return rec


def check_grasp_vectors(recognizer, config: HapticRecogConfig) -> None:
    """A ``ValueError`` unless the recogniser's grasp vectors are the ones the env config asks for: the contact
    heights exactly when ``grasp_heights`` (the observation's width follows the config) and the config's
    ``normal_axis``."""
    axis = getattr(recognizer, "normal_axis", "t2")
    if axis != config.normal_axis:
        raise ValueError(f"the recogniser's grasp vectors take each normal's second angle to {axis!r} but the config "
                         f"has normal_axis={config.normal_axis!r}; set both alike (recognizer_kwargs' "
                         "DatasetConfig.normal_axis follows normal_axis unless given)")
    has = bool(getattr(recognizer, "heights", False))
    if has != bool(config.grasp_heights):
        raise ValueError(f"the recogniser's grasp vectors {'carry' if has else 'lack'} the contact heights but the "
                         f"config has grasp_heights={config.grasp_heights}; set both alike (recognizer_kwargs' "
                         "DatasetConfig.heights follows grasp_heights unless given)")


class Belief:
    """The posterior over a recogniser's objects and everything that moves it (see the module docstring).

    Args:
        recognizer: a :class:`~haptic_env.recognizers.Recognizer`.
        kind: the updater, one of :data:`~haptic_env.recognizers.UPDATERS`.
        threshold: the certainty at which the belief has decided.
        calibrated: temperature-scaled scores (False: the paper's raw ones).
        z_fingers: also score incomplete grasps of ``t >= z_fingers`` touching fingers (the recogniser needs
            those models); None: complete grasps only.
        score_subsets: score every grasp of ``t >= z_fingers`` touching fingers through its ``z_fingers``-subsets.
        min_fingers: with ``score_subsets``, also score a grasp of ``min_fingers <= t < z_fingers`` touching fingers
            by the ``t``-finger model; None: ``z_fingers`` (such grasps carry no contact information).
        subset_k: with ``score_subsets``, the subsets a Bayesian step counts at most (see the module docstring; the
            paper's 4, as the env config's); None: all of them, the plain product of Algorithm 3.
        touch_weight: ``w`` of the touch-pattern log-likelihood added at every grasp
            (:mod:`~haptic_env.recognizers.touch`; BC-NP and BC-IP, whose classifier prior then comes with the first
            grasp the classifier scores; the recogniser needs its ``touch`` model); 0: off, the paper's method.
        ic_certainty: with ``kind="ic"``, IC's certainty rule (``IterativeClassification``): "count" or "share".
    """

    def __init__(self, recognizer, kind: str = DEFAULT_UPDATER, threshold: float = DEFAULT_THRESHOLD, *,
                 calibrated: bool = True, z_fingers: int | None = None, score_subsets: bool = False,
                 touch_weight: float = 0.0, subset_k: int | None = DEFAULT_SUBSET_K, min_fingers: int | None = None,
                 ic_certainty: str = DEFAULT_IC_CERTAINTY):
        if kind not in UPDATERS:
            raise ValueError(f"unknown updater kind {kind!r}; choose one of {UPDATERS}")
        z_fingers = check_z_fingers(z_fingers, int(recognizer.n_fingers))
        if score_subsets and z_fingers is None:
            raise ValueError("score_subsets=True needs z_fingers (the subset size)")
        min_fingers = check_min_fingers(min_fingers, z_fingers, score_subsets)
        subset_k = check_subset_k(subset_k)
        touch_weight = check_touch_weight(touch_weight)
        check_touch_updater(touch_weight, kind)
        if touch_weight > 0 and getattr(recognizer, "touch", None) is None:
            raise ValueError(f"touch_weight={touch_weight} needs a recogniser with its touch model "
                             "(build_recognizer(touch=True), hand-matched training grasps)")
        self.recognizer = recognizer
        self.touch_weight = touch_weight
        self.kind = kind
        self.z_fingers = z_fingers
        self.score_subsets = bool(score_subsets)
        self.subset_k = subset_k
        #: whether a grasp's subset rows are weighed (:meth:`row_weight`): a Bayesian step of subset scoring with a k
        self._weigh_rows = kind in ("bc-np", "bc-ip") and self.score_subsets and subset_k is not None
        self.n_fingers = int(recognizer.n_fingers)
        self.n_classes = int(recognizer.n_classes)
        #: the fewest touching fingers whose contacts are scored (``n_fingers``: complete grasps only)
        self.min_fingers = int((self.n_fingers if z_fingers is None else z_fingers) if min_fingers is None
                               else min_fingers)
        #: the grasp vectors carry the contacts' heights (then contacts are scored relative to ``support_z``)
        self.heights = bool(getattr(recognizer, "heights", False))
        #: each normal's second angle in the recogniser's grasp vectors (``phi(normal_axis=)``)
        self.normal_axis = getattr(recognizer, "normal_axis", "t2")
        self.feature_dim = feature_dim(self.n_fingers, recognizer.normals, heights=self.heights,
                                       normal_axis=self.normal_axis)
        #: the episode's table height (world z, m); see :meth:`reset`
        self.support_z = 0.0
        #: the recogniser's touch model when its pattern is weighed in, else None (off)
        self._touch = recognizer.touch if touch_weight > 0 else None
        self.models = recognizer.models.with_calibration(calibrated)
        #: the posterior maths (read-only use: :mod:`haptic_env.recognizers.updaters`)
        self.updater = recognizer.make_updater(kind=kind, threshold=threshold, calibrated=calibrated,
                                               ic_certainty=ic_certainty)
        bayes = kind in ("bc-np", "bc-ip") and not self.score_subsets
        self._scorer = recognizer.grasp_scorer(calibrated) if bayes else None
        #: use the compiled scorer for complete grasps where it applies (False: the general path, same result)
        self.compiled = True
        self._normalize = bool(getattr(getattr(recognizer, "config", None), "grasps", None)
                               and recognizer.config.grasps.normalize_scale)
        self.reset()

    @classmethod
    def from_config(cls, objects, config: HapticRecogConfig, recognizer=None) -> Belief:
        """The belief of an env config over ``objects`` (its recogniser from :func:`get_recognizer` unless given):
        the one place that maps the config's belief settings to a :class:`Belief`."""
        rec = get_recognizer(objects, config) if recognizer is None else recognizer
        check_grasp_vectors(rec, config)
        return cls(rec, config.updater, config.threshold, calibrated=config.calibrated, z_fingers=config.z_fingers,
                   score_subsets=config.score_subsets, touch_weight=config.touch_weight, subset_k=config.subset_k,
                   min_fingers=config.min_fingers, ic_certainty=config.ic_certainty)

    # ------------------------------------------------------------------------------------- state
    @property
    def probs(self) -> np.ndarray:
        """The posterior ``(K,)`` (read-only; IC's sub-stochastic ``S / k`` is reported as ``S / sum S``)."""
        return self._probs

    @property
    def certainty(self) -> float:
        """Max of the posterior; IC: its own ``max S / k`` (the winning score per grasp)."""
        if self.kind == "ic":
            return float(self.updater.certainty)
        return float(self._probs[int(self._probs.argmax())])

    @property
    def decided(self) -> bool:
        return bool(self.updater.decided)

    @property
    def prediction(self) -> int:
        return int(self._probs.argmax())

    @property
    def n_grasps(self) -> int:
        """Grasps that updated the belief since the last reset."""
        return int(self.updater.n_grasps)

    @property
    def threshold(self) -> float:
        return float(self.updater.threshold)

    def reset(self, prior=None, *, support_z: float = 0.0) -> np.ndarray:
        """Forget all grasps; returns the prior ``(K,)`` (uniform by default). ``support_z``: the table top's height
        (world z) under this episode's object, which a heights recogniser measures the contacts from."""
        support_z = float(support_z)
        if not math.isfinite(support_z):
            raise ValueError(f"support_z must be a finite height (m), got {support_z!r}")
        self._probs = self._checked(self.updater.reset(prior))
        self._probs.flags.writeable = False  # read-only, as every later belief (_set)
        self.support_z = support_z
        return self._probs

    def _support_frame(self, contacts, support_z: float | None = None) -> np.ndarray:
        """``contacts (..., 3)`` as the recogniser reads them: moved down by the table height (``support_z``, default
        the episode's) when its vectors carry heights, else unchanged."""
        if not self.heights:
            return contacts
        z = self.support_z if support_z is None else float(support_z)
        return np.asarray(contacts, dtype=np.float64) - np.array([0.0, 0.0, z])

    def _set(self, b) -> None:
        b = self._checked(b)
        if self.kind == "ic":  # IC's belief S / k is sub-stochastic: report S / sum(S), which sums to 1
            total = b.sum()
            if total > 0:
                b /= total
        b.flags.writeable = False
        self._probs = b

    def _checked(self, b) -> np.ndarray:
        if not (isinstance(b, np.ndarray) and b.dtype == np.float64 and b.ndim == 1):
            b = np.asarray(b, dtype=np.float64).reshape(-1)
        if b.shape != (self.n_classes,) or not math.isfinite(np.add.reduce(b)):  # NaN / inf propagate to the sum
            raise RuntimeError(f"belief updater returned an invalid belief {b!r} (expected {self.n_classes} finite values)")
        return b.copy()

    # ------------------------------------------------------------------------------------ grasps
    def update(self, contacts, normals, touched) -> tuple[np.ndarray, bool]:
        """One grasp: ``contacts``/``normals`` ``(n, 3)`` (normals None without them), ``touched (n,)``.

        Returns ``(q, usable)``: the grasp vector of the touching contacts zero-padded to ``(d,)`` (a fresh array;
        all 0 with fewer than two touching) and whether the grasp updated the belief."""
        touched = np.asarray(touched, dtype=bool).reshape(-1)
        if touched.shape != (self.n_fingers,):  # checked before the compiled path, which reads only its count
            raise ValueError(f"touched must have shape ({self.n_fingers},), got {touched.shape}")
        if not self.recognizer.normals:  # a recogniser without normals ignores them on every path
            normals = None
        contacts = self._support_frame(contacts)  # from here on in the support frame: rows(..., support_z=0.0)
        if self._touch is None:
            if (self._scorer is not None and self.compiled and np.count_nonzero(touched) == touched.size
                    and (self.kind == "bc-np" or self.updater.prior_set)):  # BC-IP: its prior from the classifier
                q, log_lik = self._scorer(contacts, normals)  # = rows + the likelihood of updater.update
                if log_lik is None:
                    return q, False
                self._set(self.updater.update_scores(log_lik=log_lik))
                return q, True
            q, Q = self.rows(contacts, normals, touched, support_z=0.0)
            if Q is None:
                return q, False
            self._set(self._update(Q))
            return q, True
        # with the touch pattern: its row joins the contacts' rows in one Bayes step (every grasp has one)
        rows = self.touch_rows(touched[None])
        if self.kind == "bc-ip" and not self.updater.prior_set:  # the classifier's prior comes with the first grasp
            q, Q = self.rows(contacts, normals, touched, support_z=0.0)  # it scores, the pattern's row beside it
            proba = None if Q is None else self.models.predict_proba(Q)
            self._set(self.updater.update_scores(proba=proba, evidence=rows))
            return q, True
        if self._scorer is not None and self.compiled and np.count_nonzero(touched) == touched.size:
            q, log_lik = self._scorer(contacts, normals)
        else:
            q, Q = self.rows(contacts, normals, touched, support_z=0.0)
            log_lik = None if Q is None else self.row_weight(len(Q)) * self.models.log_likelihood(Q)
        self._set(self.updater.update_scores(log_lik=log_lik, evidence=rows))
        return q, True

    def row_weight(self, m: int) -> float:
        """The weight of the summed log-likelihood of one grasp's ``m`` score rows in a Bayes step:
        ``min(1, subset_k / m)`` for a Bayesian updater with ``score_subsets`` and ``subset_k``, else 1 (see the
        module docstring)."""
        return subset_weight(m, self.subset_k) if self._weigh_rows else 1.0

    def _update(self, Q) -> np.ndarray:
        """The updater's step of one grasp's score rows ``Q (m, d)``, weighted by :meth:`row_weight`."""
        Q = np.atleast_2d(np.asarray(Q, dtype=np.float64))
        w = self.row_weight(len(Q))
        return self.updater.update(Q) if w == 1.0 else self.updater.update(Q, weight=w)

    def touch_rows(self, touched) -> np.ndarray:
        """``(B, K)``: the weighted touch-pattern log-likelihoods ``w log P(pattern | object)`` of ``touched (B, n)``
        (zeros without the touch pattern, ``touch_weight=0``)."""
        touched = np.asarray(touched, dtype=bool).reshape(-1, self.n_fingers)
        if self._touch is None:
            return np.zeros((len(touched), self.n_classes))
        return self.touch_weight * self._touch.log_likelihood(touched)

    def update_rows(self, Q) -> np.ndarray:
        """One grasp given as its score rows ``(m, d)`` (or one vector ``(d,)``); returns the posterior. The rows
        carry no touch pattern: with ``touch_weight`` use :meth:`update`."""
        self._set(self._update(Q))
        return self._probs

    def rows(self, contacts, normals, touched, *, support_z: float | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """The grasp vector ``q (d,)`` of one grasp's touching contacts (zero-padded) and the rows ``Q (m, d_z)`` that
        score it, or None (no information). Both come from ``Recognizer.features`` (a recogniser trained
        scale-normalised sees normalised vectors): the touching contacts as one grasp, or their ``z``-subsets
        with ``score_subsets``. ``support_z``: the table height the contacts are measured from (default: the
        episode's, :meth:`reset`)."""
        touched = np.asarray(touched, dtype=bool).reshape(-1)
        contacts = self._support_frame(contacts, support_z)
        t = np.count_nonzero(touched)
        q = np.zeros(self.feature_dim)
        if t < 2:
            return q, None
        Q = self.recognizer.features(contacts, normals, touched=touched)
        if len(Q):
            q[: Q.shape[1]] = Q[0]
        z = self.z_fingers
        if self.score_subsets and t >= z:
            Q = self.recognizer.features(contacts, normals, touched=touched, z=z)
            return q, (Q if len(Q) else None)
        return q, (Q if t >= self.min_fingers and len(Q) else None)

    def rows_batch(self, contacts, normals, touched, *,
                   support_z: float | None = None) -> tuple[list[np.ndarray], np.ndarray]:
        """:meth:`rows` for ``B`` grasps ``(B, n, 3)`` / ``(B, n)``: ``(rows, scored)`` with ``scored (G,)`` the batch
        indices of the grasps that would update the belief and ``rows[g] (m_g, d_g)`` the score rows of grasp
        ``scored[g]``. Vectorised when only complete grasps are scored by one model (the default)."""
        contacts = np.asarray(self._support_frame(contacts, support_z), dtype=np.float64)
        touched = np.asarray(touched, dtype=bool)
        if self.z_fingers is None and not self._normalize:
            from haptic_env.recognizers.zfinger import grasp_vectors_for

            full = np.flatnonzero(touched.all(axis=1))
            if full.size == 0:
                return [], full
            if self.recognizer.normals and normals is None:
                raise ValueError("this recogniser was trained with normals; pass the contact normals")
            N = np.asarray(normals, dtype=np.float64)[full] if self.recognizer.normals else None
            q, valid = grasp_vectors_for(contacts[full], N, heights=self.heights, normal_axis=self.normal_axis)
            return list(q[valid][:, None, :]), full[valid]
        rows, scored = [], []
        for i in range(len(contacts)):
            _, Q = self.rows(contacts[i], None if normals is None else normals[i], touched[i],
                             support_z=0.0)  # contacts: already in the support frame
            if Q is not None:
                rows.append(Q)
                scored.append(i)
        return rows, np.asarray(scored, dtype=np.int64)

    # ------------------------------------------------------------------------------- prediction
    def predict(self, rows: list[np.ndarray]) -> np.ndarray:
        """The posteriors ``(G, K)`` after ONE more grasp, for ``G`` candidate grasps given by their score rows
        ``rows[g] (m_g, d_g)`` (widths may differ: one batched call per width); the belief is unchanged.
        Exactly what :meth:`update_rows` would give (reported as :attr:`probs` is)."""
        out = np.zeros((len(rows), self.n_classes))
        if not rows:
            return out
        dims = np.array([r.shape[1] for r in rows])
        for d in np.unique(dims):
            idx = np.flatnonzero(dims == d)
            Q = np.concatenate([rows[i] for i in idx])
            starts = np.concatenate([[0], np.cumsum([len(rows[i]) for i in idx])])
            if self._weigh_rows:
                out[idx] = self.updater.predict(Q, starts, weights=[self.row_weight(len(rows[i])) for i in idx])
            else:
                out[idx] = self.updater.predict(Q, starts)
        if self.kind == "ic":
            total = out.sum(axis=1, keepdims=True)
            out = np.divide(out, total, out=out, where=total > 0)
        return out

    def predict_grasps(self, contacts, normals, touched, *,
                       support_z: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`predict` of ``B`` grasps ``(B, n, 3)``: ``(posteriors (G, K), scored (G,))``, the grasps that
        would update the belief (see :meth:`rows_batch`; with ``touch_weight`` every grasp does, ``G = B``)."""
        rows, scored = self.rows_batch(contacts, normals, touched, support_z=support_z)
        if self._touch is None:
            return self.predict(rows), scored
        # with the touch pattern every grasp updates: its contacts' rows (if scored) plus its pattern's row
        from haptic_env.recognizers.updaters import bayes_steps, model_rows

        touch = self.touch_rows(touched)
        B = len(touch)
        per = [np.zeros((0, self.n_classes))] * B
        base = np.broadcast_to(self.updater.log_belief, (B, self.n_classes))
        if self.kind == "bc-ip" and not self.updater.prior_set:  # a scored grasp would set the classifier prior,
            base = base.copy()  # multiplied into its log belief before the step (as BCIP.update_scores)
            for g, i in enumerate(scored):
                base[i] = self.updater.with_prior(base[i], self.models.predict_proba(rows[g]))
        else:
            for g, i in enumerate(scored):  # combined as the updater's step combines them (the pattern's row apart)
                per[i] = model_rows(self.row_weight(len(rows[g])) * self.models.log_likelihood(rows[g]),
                                    self.updater.combine)
        L = np.concatenate([np.concatenate([per[i], touch[i:i + 1]]) for i in range(B)]) if B else touch
        starts = np.concatenate([[0], np.cumsum([len(per[i]) + 1 for i in range(B)])]).astype(np.int64)
        post, _ = bayes_steps(base, L, starts, combine="product", max_log_ratio=self.updater.max_log_ratio)
        return np.exp(post), np.arange(B)

    # ----------------------------------------------------------------------------------- scores
    def scores(self, Q) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The models' scores of score rows ``Q (m, d)``: ``(log_lik (m, K), proba (m, K))``, None for a model the
        recogniser was built without."""
        Q = np.atleast_2d(np.asarray(Q, dtype=np.float64))
        entry = self.models.entries.get(Q.shape[1])
        if entry is None:
            self.models.log_likelihood(Q)  # raises, naming the finger counts this recogniser has
        _, clf, kde = entry
        return (self.models.log_likelihood(Q) if kde is not None else None,
                self.models.predict_proba(Q) if clf is not None else None)

    def subset_scores(self, contacts, normals, z: int, k: int | None = None, rng: np.random.Generator | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """z-subset scores of ``G`` grasps ``contacts (G, n, 3)`` (paper, Algorithms 3 and 4), batched.

        Per grasp: every z-subset of its contacts (``k=None``), or ``k`` distinct random ones drawn from ``rng``
        (an independent random order per grasp), mapped to ``Phi_z`` and scored by the ``z``-finger models;
        degenerate subsets are left out. Returns ``(log_lik (G', K), proba (G', K), kept (G',))``: the summed
        log-likelihoods (the product of the likelihoods) and mean probabilities of each grasp with at least one
        valid subset, and those grasps' indices. A model the recogniser was built without scores zeros."""
        from itertools import combinations

        from haptic_env.recognizers.zfinger import grasp_vectors_for

        C = np.asarray(self._support_frame(contacts), dtype=np.float64)
        G, n, _ = C.shape
        allsub = np.array(list(combinations(range(n), z)))
        if not self.recognizer.normals:  # a recogniser without normals ignores them, as rows_batch does
            normals = None
        elif normals is None:  # as rows_batch says it (the vectors without normals found no model)
            raise ValueError("this recogniser was trained with normals; pass the contact normals")
        if k is None or k >= len(allsub):
            pick = np.broadcast_to(np.arange(len(allsub)), (G, len(allsub)))
        else:
            if rng is None:
                raise ValueError(f"subset_scores: k={k!r} of the {len(allsub)} {z}-subsets are drawn at random; "
                                 "pass rng (a numpy Generator)")
            pick = np.argsort(rng.random((G, len(allsub))), axis=1)[:, :k]
        idx = allsub[pick]  # (G, m, z)
        at = np.arange(G)[:, None, None]
        Pz = C[at, idx].reshape(-1, z, 3)
        Nz = None if normals is None else np.asarray(normals, dtype=np.float64)[at, idx].reshape(-1, z, 3)
        q, valid = grasp_vectors_for(Pz, Nz, normalize=self._normalize, heights=self.heights,
                                     normal_axis=self.normal_axis)
        m = idx.shape[1]
        K = self.n_classes
        ll = np.zeros((G * m, K))
        pr = np.zeros((G * m, K))
        if valid.any():
            L, P = self.scores(q[valid])
            if L is not None:
                ll[valid] = L
            if P is not None:
                pr[valid] = P
        v = valid.reshape(G, m)
        cnt = v.sum(1)
        keep = cnt > 0
        ll = ll.reshape(G, m, K).sum(1)
        pr = pr.reshape(G, m, K).sum(1) / np.maximum(cnt, 1)[:, None]
        return ll[keep], pr[keep], np.flatnonzero(keep)
