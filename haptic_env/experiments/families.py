"""Experiment 5: geometry recognition. Models learn three families (boxes, elliptic cylinders, ellipsoids)
from random members, classify held-out members, and classify the objects of ``cfg.objects`` into the
families (n = 4, scale-normalised).

The family models are trained here, not by :func:`~haptic_env.recognizers.build_recognizer`: their classes
are families, not objects. Their temperatures are fitted on NEW validation members
(:func:`family_temperatures`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.special import softmax

from haptic_env.dataset import DatasetConfig, build_dataset, hand_dataset, hand_vectors
from haptic_env.experiments.config import AnalysisConfig
from haptic_env.experiments.plots import plot_family_votes
from haptic_env.experiments.report import Report, mean_std
from haptic_env.experiments.trials import family_trials, simulate_trials
from haptic_env.numbers import finite_number, whole_at_least
from haptic_env.recognizers.calibration import _finite_rows, fit_temperature, sequence_scores, tempered_nll
from haptic_env.recognizers.kde import KDELikelihood
from haptic_env.recognizers.mlp import MLPClassifier
from haptic_env.splits import FAMILY_VAL_SEED_OFFSET, TEST_SEED_OFFSET

__all__ = ["run", "EXPECTED_FAMILY", "FAMILY_OBJECT_TRIALS", "family_temperatures",
           "family_floor", "floored", "sequence_fit", "family_models", "FamilyModels", "family_vectors", "grasp_config",
           "member_grasps"]

#: The family a person would expect for the objects of ``default``, ``ycb10`` and ``kit20`` (None: no clear
#: family; such objects are listed in experiment 5 but left out of its score).
EXPECTED_FAMILY = {
    # default set
    "box": "box", "can": "elliptic_cylinder", "apple": "ellipsoid", "bottle": "elliptic_cylinder",
    "mug": "elliptic_cylinder", "cone": None, "ring": None, "hammer": None, "ball": "ellipsoid",
    # ycb10
    "001_chips_can": "elliptic_cylinder", "002_master_chef_can": "elliptic_cylinder", "006_mustard_bottle": None,
    "013_apple": "ellipsoid", "021_bleach_cleanser": None, "025_mug": "elliptic_cylinder", "029_plate": None,
    "035_power_drill": None, "036_wood_block": "box", "048_hammer": None,
    # kit20
    "Deodorant": "elliptic_cylinder", "GreenCup": "elliptic_cylinder", "HeringTin": "box",
    "HygieneSpray": "elliptic_cylinder", "WhiteCup": "elliptic_cylinder", "cube": "box",
}
#: Trials per object of experiment 5's object table (the paper's GraspNet-style table).
FAMILY_OBJECT_TRIALS = 10


def floored(S: np.ndarray, floor: float) -> np.ndarray:
    """Log-likelihoods ``S`` with an outlier floor: ``log(exp(S) + exp(floor))`` elementwise (``floor = -inf``: ``S``
    unchanged). A grasp unlike every family's training grasps (all its log-likelihoods far below ``floor``) then
    gives every family about the same score, so it moves a belief little instead of by the ratio of tail densities."""
    return np.logaddexp(S, floor)


def family_temperatures(kde, clf, X, fam, *, member=None, grasps: int = 1,
                        rng: np.random.Generator | None = None, floor: float = -np.inf) -> tuple[float, float]:
    """Calibration temperatures ``(T_kde, T_mlp)`` of family models, fitted on grasps ``X`` of NEW validation
    members with families ``fam`` (the models' own temperatures are fitted on held-back grasps of the training
    members, which overstates how well a family model knows an unseen member).

    With ``grasps > 1`` the KDE's temperature is fitted for BC-NP's beliefs of ``1 .. grasps`` grasps of ONE member
    (``member``: the validation member of each row; sums drawn with ``rng``,
    :func:`~haptic_env.recognizers.calibration.sequence_scores`): a member unlike its family's training members
    keeps looking like another family grasp after grasp, so a belief summed over its grasps is over-confident by
    more than one grasp's temperature corrects. The MLP's stays one-shot (IC averages, it does not sum).
    ``floor``: the KDE's outlier floor (:func:`floored`), applied before the fit."""
    whole_at_least(grasps, 1, "family_temperatures: grasps")
    S = _finite_rows(floored(kde.log_likelihood(X), floor))
    fam = np.asarray(fam)
    if grasps > 1:
        if member is None or rng is None:
            raise ValueError("family_temperatures: grasps > 1 needs the member of each row and an rng")
        T_kde = fit_temperature(*_member_sequences(S, fam, np.asarray(member), grasps, rng))
    else:
        T_kde = fit_temperature(S, fam)
    T_mlp = fit_temperature(np.log(np.maximum(clf.predict_proba(X), 1e-300)), fam)
    return float(T_kde), float(T_mlp)


def _member_sequences(S, fam, member, grasps: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """Scores of beliefs over 1 .. ``grasps`` grasps of ONE member (:func:`sequence_scores` per member), stacked."""
    parts = [sequence_scores(S[member == m], fam[member == m], grasps, rng) for m in np.unique(member)]
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


def family_floor(kde, X_held, y_held, X, fam, member, *, quantiles, grasps: int, seed) -> tuple[float, float]:
    """Experiment 5's outlier floor (:func:`floored`), chosen on NEW validation members: for each ``q`` in
    ``quantiles`` the floor is the ``q``-quantile of the true family's log-likelihood on held-back grasps of the
    TRAINING members ``X_held`` / ``y_held`` (``q = 0``: no floor), and the ``q`` whose floored, sequence-tempered
    beliefs of 1 .. ``grasps`` grasps of one validation member (``X``, ``fam``, ``member``; as
    :func:`family_temperatures` fits them) have the lowest NLL wins (the first on a tie). Each candidate draws the
    same sums (``seed``). Returns ``(q, floor)``."""
    qs = [finite_number(q) for q in quantiles]
    if not qs or any(q is None or not 0.0 <= q < 1.0 for q in qs):
        raise ValueError(f"family_floor: quantiles must be a non-empty list in [0, 1), got {quantiles!r}")
    L = kde.log_likelihood(X_held)
    true = L[np.arange(len(L)), np.asarray(y_held)]
    true = true[np.isfinite(true)]
    if len(true) == 0 and any(q > 0 for q in quantiles):
        raise ValueError(f"family_floor: no held-back grasp has a finite log-likelihood under its own family "
                         f"({len(L)} grasps), so no floor quantile exists")
    S = kde.log_likelihood(X)
    best = None
    for q in quantiles:
        c = float(np.quantile(true, q)) if q > 0 else -np.inf
        nll = sequence_fit(floored(S, c), fam, member, grasps=grasps, seed=seed)[1]
        if best is None or nll < best[0]:
            best = (nll, float(q), c)
    return best[1], best[2]


def sequence_fit(S, fam, member, *, grasps: int, seed) -> tuple[float, float]:
    """``(T, nll)``: the temperature of beliefs of 1 .. ``grasps`` grasps of ONE member fitted on the KDE scores ``S``
    of validation grasps (``fam``: each row's family, ``member``: its member; sums drawn with ``default_rng(seed)``,
    as :func:`family_temperatures` draws them), and those beliefs' NLL at ``T``: :func:`family_floor`'s criterion."""
    Sq, Y = _member_sequences(_finite_rows(S), np.asarray(fam), np.asarray(member), grasps,
                              np.random.default_rng(seed))
    T = fit_temperature(Sq, Y)
    return float(T), float(tempered_nll(Sq, Y, T))


def _too_small(cfg: AnalysisConfig, what: str) -> RuntimeError:
    return RuntimeError(f"experiment 5: the {cfg.family_hand} hand grasped {what} with 4 fingers; it needs larger "
                        f"family members than family_scale_range={cfg.family_scale_range}, family_size_range="
                        f"{cfg.family_size_range} give (--family-scale-range, --family-size-range)")


def _check_families(members, left_out, cfg: AnalysisConfig, role: str) -> None:
    """Raise if leaving out the members ``left_out`` (the hand never grasped them) leaves a family without members."""
    from haptic_env.objects import FAMILIES

    kept = {members.families[nm] for nm in members.names if nm not in left_out}
    if missing := [f for f in FAMILIES if f not in kept]:
        raise _too_small(cfg, f"no {role} member of {missing} (left out: {sorted(left_out)})")


def grasp_config(cfg: AnalysisConfig, grasps: int, seed: int, **kw) -> DatasetConfig:
    """Experiment 5's grasps (of members and objects alike): 4 fingers, scale-normalised, ``cfg``'s normals and family
    source; ``grasps`` per object (approaches with a hand source), ``kw``: more :class:`DatasetConfig` fields."""
    return DatasetConfig(n_fingers=4, normals=cfg.normals, grasps_per_object=grasps, normalize_scale=True, seed=seed,
                         normal_axis=cfg.normal_axis, **cfg.family_grasps, **kw)


def family_vectors(objects, dc: DatasetConfig, cfg: AnalysisConfig) -> list[np.ndarray]:
    """Each object's grasp vectors, float64 ``(G_k, d)``, from ``cfg``'s family source as ``dc`` asks (experiment 5's
    :func:`grasp_config`): the hand's MuJoCo grasps under ``dc.grasps_per_object`` approaches, of which the 4-finger
    ones are kept (an object the hand never grasps with 4 fingers gets 0 rows), or the dataset's surface or
    geometric-hand grasps (``dc.grasps_per_object`` each)."""
    if cfg.family_source == "hand":
        return [X.astype(np.float64) for X in hand_vectors(objects, dc, progress=cfg.progress)]
    ds = build_dataset(objects, dc, progress=cfg.progress)
    return [ds.X_train[ds.y_train == k].astype(np.float64) for k in range(len(objects))]


def member_grasps(members, dc: DatasetConfig, cfg: AnalysisConfig, role: str):
    """The family members' grasp dataset and the members left out (name -> rows): with a hand source, a member that
    the hand does not grasp with 4 fingers (too small or too flat for it) is left out; a family left without members
    gets an error that says which setting to change."""
    if cfg.family_source != "hand":
        return build_dataset(members, dc, progress=cfg.progress), {}
    try:
        ds, left_out = hand_dataset(members, dc, progress=cfg.progress)
    except RuntimeError as e:
        raise _too_small(cfg, f"none of the {len(members)} {role} members") from e
    _check_families(members, left_out, cfg, role)
    return ds, left_out


@dataclasses.dataclass(frozen=True)
class FamilyModels:
    """Experiment 5's family models (:func:`family_models`) and the member sets they come from.

    Attributes:
        train_set, val_set, test_set: the training members, the new validation members (the temperatures) and the new
            test members, each a ``family_set`` of ``cfg``'s generator.
        fam_of: ``(M,)`` family index (position in ``FAMILIES``) of each training member.
        left_train, left_val: training / validation members the hand never grasped with 4 fingers (name -> rows).
        clf, kde: the MLP and the KDE over the three families.
        T_kde, T_mlp: their temperatures (1.0 each with raw scores).
        floor_q, floor: the KDE's outlier floor (:func:`floored`, :func:`family_floor`): the quantile chosen on the
            validation members and its log-likelihood level (``0`` and ``-inf``: none, as with raw scores).
    """

    train_set: object
    val_set: object
    test_set: object
    fam_of: np.ndarray
    left_train: dict
    left_val: dict
    clf: MLPClassifier
    kde: KDELikelihood
    T_kde: float
    T_mlp: float
    floor_q: float = 0.0
    floor: float = -np.inf

    def tempered(self, S: np.ndarray) -> np.ndarray:
        """``(G, 3)`` the family KDE's log-likelihoods ``S`` (``kde.log_likelihood``) as experiment 5's beliefs use
        them: floored (:func:`floored`) and divided by ``T_kde``. The floor keeps their order, but grasps far below
        it may tie: take one-shot argmaxes from ``S``."""
        return floored(S, self.floor) / self.T_kde


def family_models(cfg: AnalysisConfig, n_objects: int) -> FamilyModels:
    """Train experiment 5's family models as ``cfg`` says: random members (training, validation and test seeds), the
    training members' grasps (``max(1000, grasps_per_object x n_objects / members)`` each, the budget of an object set
    of ``n_objects``), an MLP and a KDE over the three families, and their temperatures fitted on the validation
    members (:func:`family_temperatures`; the KDE's for beliefs of 1 to ``max_grasps`` grasps)."""
    from haptic_env.objects import FAMILIES, family_set

    members = {"scale_range": cfg.family_scale_range, "size_range": cfg.family_size_range, "lying": cfg.family_lying}
    train_set = family_set(cfg.family_members, np.random.default_rng(cfg.seed), **members)
    n_held = max(2, cfg.family_members // 3)
    val_set = family_set(n_held, np.random.default_rng(cfg.seed + FAMILY_VAL_SEED_OFFSET), **members)
    test_set = family_set(n_held, np.random.default_rng(cfg.seed + TEST_SEED_OFFSET), **members)
    fam_idx = {f: i for i, f in enumerate(FAMILIES)}
    per_obj = max(1000, cfg.grasps_per_object * n_objects // max(len(train_set), 1))
    ds, left_train = member_grasps(train_set, grasp_config(cfg, per_obj, cfg.seed), cfg, "training")
    fam_of = np.array([fam_idx[train_set.families[nm]] for nm in train_set.names])
    clf = MLPClassifier(dataclasses.replace(cfg.mlp, progress=False)).fit(ds.X_train, fam_of[ds.y_train], ds.X_val,
                                                                          fam_of[ds.y_val], n_classes=len(FAMILIES))
    kde = KDELikelihood(cfg.kde).fit(ds.X_train, fam_of[ds.y_train], ds.X_val, fam_of[ds.y_val], n_classes=len(FAMILIES))
    # temperatures on new validation members (another seed than training and test)
    vdc = grasp_config(cfg, cfg.test_grasps, cfg.seed + FAMILY_VAL_SEED_OFFSET, val_fraction=0.0)
    vds, left_val = member_grasps(val_set, vdc, cfg, "validation")
    fam_val = np.array([fam_idx[val_set.families[nm]] for nm in val_set.names])
    if not cfg.calibrated:  # the paper's raw scores: no temperatures, no floor
        return FamilyModels(train_set, val_set, test_set, fam_of, left_train, left_val, clf, kde, 1.0, 1.0)
    Xv, fv, seed = vds.X_train.astype(np.float64), fam_val[vds.y_train], [cfg.seed, FAMILY_VAL_SEED_OFFSET]
    q, floor = family_floor(kde, ds.X_val, fam_of[ds.y_val], Xv, fv, vds.y_train, quantiles=cfg.family_floors,
                            grasps=cfg.max_grasps, seed=seed)
    T_kde, T_mlp = family_temperatures(kde, clf, Xv, fv, member=vds.y_train, grasps=cfg.max_grasps,
                                       rng=np.random.default_rng(seed), floor=floor)
    return FamilyModels(train_set, val_set, test_set, fam_of, left_train, left_val, clf, kde, T_kde, T_mlp, q, floor)


def run(objects, cfg: AnalysisConfig, rep: Report, rng: np.random.Generator) -> None:
    from haptic_env.objects import FAMILIES

    grasps = {"surface": "surface grasps", "geometric": "geometric-hand grasps under random approaches",
              "hand": f"{cfg.family_hand} MuJoCo grasps under random approaches, objects on the table"}[cfg.family_source]
    lo, hi = cfg.family_scale_range
    rep.h("5. Geometry recognition (families: " + ", ".join(FAMILIES) + f"; n = 4, normals: {cfg.normals}, "
          f"scale-normalised, {grasps}; member axes U({lo:g}, {hi:g}) x 0.08 m" + (
              "" if cfg.family_size_range is None else " x a size factor U({:g}, {:g}) per member".format(
                  *cfg.family_size_range)) + ("; every second cylinder lying" if cfg.family_lying else "")
          + ("; with each contact's height above the table" if cfg.family_heights else "")
          + ("" if cfg.family_force_closure is None else f"; only grasps in force closure at friction "
                                                           f"{cfg.family_force_closure:g}")
          + f"; {cfg.family_scores_label})")
    m = family_models(cfg, len(objects))
    fam_idx = {f: i for i, f in enumerate(FAMILIES)}

    def scores(objs):  # test grasps; an object the hand never grasps with 4 fingers gets no rows
        pool = family_vectors(objs, grasp_config(cfg, cfg.test_grasps, cfg.seed + TEST_SEED_OFFSET, val_fraction=0.0),
                              cfg)
        raw = [m.kde.log_likelihood(X) for X in pool]
        PR = [softmax(np.log(np.maximum(m.clf.predict_proba(X), 1e-300)) / m.T_mlp, axis=1) for X in pool]
        return [m.tempered(R) for R in raw], PR, raw

    LL, PR, raw = scores(m.test_set)
    left_test = {nm: 0 for nm, L in zip(m.test_set.names, LL) if len(L) == 0}  # the hand never grasped them
    _check_families(m.test_set, left_test, cfg, "test")
    kept = [k for k, L in enumerate(LL) if len(L)]
    LL, PR, raw = [LL[k] for k in kept], [PR[k] for k in kept], [raw[k] for k in kept]
    fam_test = np.array([fam_idx[m.test_set.families[m.test_set.names[k]]] for k in kept])
    rows = []
    for kind in ("ic", "bc-np"):
        res = simulate_trials(LL, PR, kind, trials=cfg.trials, max_grasps=cfg.max_grasps, threshold=cfg.threshold, rng=rng,
                              ic_certainty=cfg.ic_certainty)
        ok = fam_test[res["truth"]] == res["pred"]
        rows.append([kind, f"{100 * ok.mean():.1f}", f"{100 * res['decided'].mean():.1f}",
                     mean_std(res["grasps"].mean(), res["grasps"].std(), 2)])
    one = np.mean(np.concatenate([p.argmax(1) == fam_test[k] for k, p in enumerate(PR)]))
    one_kde = np.mean(np.concatenate([R.argmax(1) == fam_test[k] for k, R in enumerate(raw)]))
    _, PRh, LLh = scores(m.train_set)  # fresh grasps (test seed) of the training members: held-back family grasps
    held = [k for k, nm in enumerate(m.train_set.names) if nm not in m.left_train and len(LLh[k])]
    one_h = np.mean(np.concatenate([PRh[k].argmax(1) == m.fam_of[k] for k in held]))
    one_kde_h = np.mean(np.concatenate([LLh[k].argmax(1) == m.fam_of[k] for k in held]))
    n_tr, n_val, n_te = (len(st) - len(left) for st, left in ((m.train_set, m.left_train), (m.val_set, m.left_val),
                                                             (m.test_set, left_test)))
    if m.left_train or m.left_val or left_test:
        rep.p(f"The {cfg.family_hand} grasped some random members with fewer than 4 fingers only (too small or too flat "
              f"for it); they are left out: training {sorted(m.left_train)}, validation {sorted(m.left_val)}, "
              f"test {sorted(left_test)}.")
    rep.p(f"Held-back grasps of {len(held)} of the {n_tr} training members (fresh, test seed; a member without such "
          f"grasps is left out): one-shot family accuracy MLP "
          f"{100 * one_h:.1f} %, KDE argmax {100 * one_kde_h:.1f} % (chance 33.3 %).")
    fitted = (f"Temperatures fitted on {n_val} validation members: KDE {m.T_kde:.2f} (for beliefs of "
              f"1-{cfg.max_grasps} grasps of one member), MLP {m.T_mlp:.2f} (one-shot). KDE outlier floor: "
              + ("none" if m.floor_q == 0 else f"the {m.floor_q:g}-quantile of the true family's log-likelihood on "
                 f"held-back training-member grasps ({m.floor:.2f})") + f", chosen from {list(cfg.family_floors)} on "
              "the validation members." if cfg.calibrated else
              "Raw scores (the paper's): no temperatures, no outlier floor.")
    rep.p(f"Held-out family members ({n_te} new random boxes/cylinders/ellipsoids, test seed); one-shot "
          f"family accuracy MLP {100 * one:.1f} %, KDE argmax {100 * one_kde:.1f} % (chance 33.3 %). {fitted} "
          f"{cfg.trials} trials, lambda = {cfg.threshold}, at most {cfg.max_grasps} grasps; success = family right "
          "at the stop.")
    rep.table(["updater", "family success %", "decided %", "grasps"], rows)
    LL, PR, _ = scores(objects)
    ntr = FAMILY_OBJECT_TRIALS
    short = {"box": "box", "elliptic_cylinder": "cyl", "ellipsoid": "ell"}
    rows, hits, labelled, ic_dec, ic_all = [], 0, 0, 0, 0
    all_votes = {kind: np.zeros((len(objects), len(FAMILIES)), dtype=int) for kind in ("ic", "bc-np")}
    ungrasped = []
    for k, nm in enumerate(objects.names):
        exp = EXPECTED_FAMILY.get(nm)
        if len(LL[k]) == 0:  # the hand never touched it with 4 fingers: a labelled object counts as missed
            ungrasped.append(nm)
            labelled += exp is not None
            rows.append([nm, short.get(exp, "-") if exp else "(none)", "no 4-finger grasps", "-", "-", "-", "-", "-",
                         "-" if exp is None else "no"])
            continue
        out = {}
        for kind in ("ic", "bc-np"):
            out[kind] = family_trials(LL[k], PR[k], kind, trials=ntr, max_grasps=cfg.max_grasps,
                                      threshold=cfg.threshold, rng=rng, ic_certainty=cfg.ic_certainty)
            all_votes[kind][k] = out[kind][0]
        ic_dec += out["ic"][1]
        ic_all += ntr
        votes = np.asarray(out["bc-np"][0])
        top = np.flatnonzero(votes == votes.max())
        vote = FAMILIES[int(top[0])] if len(top) == 1 else None  # a tie (5 / 5) is no majority: a miss
        if exp is not None:
            labelled += 1
            hits += vote == exp
        rows.append([nm, short.get(exp, "-") if exp else "(none)",
                     " / ".join(str(v) for v in out["ic"][0]), f"{out['ic'][1]}/{ntr}",
                     " / ".join(str(v) for v in out["bc-np"][0]), f"{out['bc-np'][1]}/{ntr}",
                     f"{out['bc-np'][2].mean():.1f}", "tie" if vote is None else short[vote],
                     "-" if exp is None else ("yes" if vote == exp else "no")])
    rep.p(f"Objects of '{cfg.objects}' classified into families ({ntr} trials per object; votes = predictions at "
          f"the stop, box / cyl / ell; expected = the family a person would expect, '(none)': no clear family, not "
          f"scored; a tie of the most votes is no majority and counts as a miss). BC-NP's majority vote is the "
          f"expected family for {hits}/{labelled} labelled objects; IC decided "
          f"within {cfg.max_grasps} grasps in {ic_dec}/{ic_all} trials."
          + (f" The {cfg.family_hand} never grasped {', '.join(ungrasped)} with 4 fingers in {cfg.test_grasps} "
             "approaches (a labelled one counts as a miss)." if ungrasped else "") + " Plot: `family_votes.png`.")
    rep.table(["object", "expected", "IC votes", "IC decided", "BC-NP votes", "BC-NP decided", "BC-NP grasps",
               "BC-NP vote", "match"], rows)
    plot_family_votes(objects.names, [EXPECTED_FAMILY.get(nm) for nm in objects.names],
                      {kind.upper(): V for kind, V in all_votes.items()}, FAMILIES, f"'{cfg.objects}'",
                      rep.out / "family_votes.png")
