"""Does the Allegro's touch pattern (which fingertips touch) carry family information? Measured on VALIDATION
members only (2026-12-07, forty-sixth session), with experiment 5's seed-0 members and grasps (40 training members
per family, size factor U(0.7, 1.6), 1,000 approaches each; 13 validation members per family, 400 approaches each):
a per-family categorical over the 16 patterns (``TouchModel``, Laplace smoothing) fitted on the training members,
scored on the validation members' grasps, one grasp and 10 random grasps at a time.

    python docs/results/families/touch_pattern.py > docs/results/families/touch_pattern.txt
"""
import numpy as np
from haptic_env.experiments.config import AnalysisConfig
from haptic_env.experiments.families import grasp_config
from haptic_env.dataset import hand_pool
from haptic_env.objects import FAMILIES, family_set
from haptic_env.recognizers.touch import TouchModel
from haptic_env.splits import FAMILY_VAL_SEED_OFFSET

cfg = AnalysisConfig(objects="default", normals=False, family_source="hand", family_members=40,
                     family_size_range=(0.7, 1.6), grasps_per_object=1000, seed=0, progress=False)
members = {"scale_range": cfg.family_scale_range, "size_range": cfg.family_size_range, "lying": cfg.family_lying}
train = family_set(40, np.random.default_rng(0), **members)
val = family_set(13, np.random.default_rng(0 + FAMILY_VAL_SEED_OFFSET), **members)
fi = {f: i for i, f in enumerate(FAMILIES)}
per_obj = max(1000, cfg.grasps_per_object * 17 // len(train))
ptr = hand_pool(train, grasp_config(cfg, per_obj, 0))
pva = hand_pool(val, grasp_config(cfg, cfg.test_grasps, 0 + FAMILY_VAL_SEED_OFFSET, val_fraction=0.0))
ftr = np.array([fi[train.families[n]] for n in train.names]); fva = np.array([fi[val.families[n]] for n in val.names])
Ttr = ptr.touched  # (M, A, 4)
fam_T = np.stack([Ttr[ftr == f].reshape(-1, Ttr.shape[-1]) for f in range(3)])
tm = TouchModel.fit(fam_T)
Tva = pva.touched
print("touched shape", Ttr.shape, Tva.shape)
for f in range(3):
    pats, cnt = np.unique((fam_T[f] * [1, 2, 4, 8]).sum(1), return_counts=True)
    print(FAMILIES[f], "4-finger share %.3f" % (fam_T[f].sum(1) == 4).mean(), dict(zip(pats.tolist(), np.round(cnt / cnt.sum(), 3).tolist())))
L = np.stack([tm.log_likelihood(Tva[m]) for m in range(len(val))])  # (V, A, 3)
one = (L.argmax(-1) == fva[:, None]).mean()
print("one-shot touch-only family accuracy on validation members %.3f" % one)
# per member: sum of log-likelihoods over 10 grasps -> vote
rng = np.random.default_rng(1)
right = 0
for m in range(len(val)):
    for t in range(10):
        idx = rng.choice(L.shape[1], 10, replace=False)
        right += L[m, idx].sum(0).argmax() == fva[m]
print("10-grasp touch-only member accuracy %.3f" % (right / (10 * len(val))))
