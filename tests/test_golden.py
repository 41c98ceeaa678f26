"""Golden rollouts: fixed seeds give the same observations, rewards and beliefs as when the file was pinned.

Pinned before the refactor of issue 8 (one owner per concept) so that moving code cannot change behaviour
unnoticed. The small test recogniser (tests/conftest.py) is built from fixed seeds; the env's rollouts are
compared with ``tests/golden/env_rollouts.npz`` for BC-NP, BC-IP and IC, with and without z-finger scoring of
incomplete grasps. A deliberate behaviour change re-pins the file:

    HAPTIC_PIN_GOLDEN=1 python -m pytest tests/test_golden.py
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import haptic_env

GOLDEN = Path(__file__).parent / "golden" / "env_rollouts.npz"
CASES = {"bc-np": {}, "bc-ip": {"updater": "bc-ip"}, "ic": {"updater": "ic"},
         "bc-np-z3": {"z_fingers": 3}, "bc-np-raw": {"calibrated": False}}


def _rollouts(config, overrides: dict, episodes: int = 6, steps: int = 8) -> dict[str, np.ndarray]:
    env = haptic_env.make(config.replace(**overrides))
    rng = np.random.default_rng(11)
    obs_, rew, bel, term = [], [], [], []
    for ep in range(episodes):
        obs, info = env.reset(seed=100 + ep)
        obs_.append(obs)
        bel.append(info["belief"])
        for _ in range(steps):
            obs, r, terminated, truncated, info = env.step(rng.uniform(-1, 1, 4).astype(np.float32))
            obs_.append(obs)
            rew.append(r)
            bel.append(info["belief"])
            term.append(terminated or truncated)
            if terminated or truncated:
                break
    env.close()
    return {"obs": np.array(obs_), "reward": np.array(rew), "belief": np.array(bel), "done": np.array(term)}


def _scores(config) -> dict[str, np.ndarray]:
    """The recogniser's scores of fixed surface grasps: KDE log-likelihoods and MLP probabilities, raw and
    calibrated, and a simulated trial run (the analyses' trial runner) over them."""
    from haptic_env.env import get_recognizer
    from haptic_env.objects import load_object_set
    from haptic_env.experiments import simulate_trials

    objects = load_object_set(config.objects)
    rec = get_recognizer(objects, config.replace(updater="bc-ip"))  # both models
    rng = np.random.default_rng(5)
    Q = np.concatenate([rec.features(*o.sample_surface(4, rng)) for o in objects for _ in range(4)])
    out = {}
    for cal in (True, False):
        bank = rec.models.with_calibration(cal)
        out[f"scores/log_lik_{cal}"] = bank.log_likelihood(Q)
        out[f"scores/proba_{cal}"] = bank.predict_proba(Q)
    LL = [out["scores/log_lik_True"][4 * k:4 * k + 4] for k in range(len(objects))]
    PR = [out["scores/proba_True"][4 * k:4 * k + 4] for k in range(len(objects))]
    for kind in ("bc-np", "bc-ip", "ic"):
        res = simulate_trials(LL, PR, kind, trials=30, max_grasps=4, threshold=0.85, rng=np.random.default_rng(9))
        out[f"trials/{kind}_grasps"] = res["grasps"]
        out[f"trials/{kind}_pred"] = res["pred"]
    return out


def test_env_rollouts_match_the_pinned_file(env_config):
    got = {f"{case}/{k}": v for case, kw in CASES.items() for k, v in _rollouts(env_config, kw).items()}
    got.update(_scores(env_config))
    if os.environ.get("HAPTIC_PIN_GOLDEN"):
        GOLDEN.parent.mkdir(exist_ok=True)
        np.savez_compressed(GOLDEN, **got)
        pytest.skip(f"pinned {GOLDEN}")
    want = np.load(GOLDEN)
    assert sorted(want.files) == sorted(got)
    for key in sorted(got):
        assert want[key].shape == got[key].shape, key
        if want[key].dtype.kind in "bi":
            np.testing.assert_array_equal(got[key], want[key], err_msg=key)
        else:
            np.testing.assert_allclose(got[key], want[key], rtol=1e-5, atol=1e-6, err_msg=key)
