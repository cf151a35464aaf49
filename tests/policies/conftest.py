"""Demonstrations shared by the policy tests: pure pursuit on OffroadNav-v1's oracle grid."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import stable_baselines3

from negobs_gym.policies.pretrain import PolicyActor, collect_demonstrations
from negobs_gym.policies.training import make_training_env


@pytest.fixture(scope="module")
def demos(request):
    """``DEMO_STEPS`` noisy steps on seed ``DEMO_SEED`` (module constants; 120 and 11 unless set)."""
    env = make_training_env("negobs_gym/OffroadNav-v1", ("observation.source=oracle",))
    steps, seed = getattr(request.module, "DEMO_STEPS", 120), getattr(request.module, "DEMO_SEED", 11)
    try:
        yield collect_demonstrations(env, steps, noise_std=0.3, seed=seed)
    finally:
        env.close()


@pytest.fixture
def reloaded(tmp_path):
    """``reloaded(model, obs)``: the model's policy after a save and load, checked to act on ``obs``
    as the model does, as must the :class:`PolicyActor` a DAgger worker unpickles."""

    def check(model, obs):
        action = model.predict(obs, deterministic=True)[0]
        model.save(tmp_path / "model.zip")
        loaded = stable_baselines3.PPO.load(tmp_path / "model.zip", device="cpu")
        np.testing.assert_allclose(loaded.predict(obs, deterministic=True)[0], action, atol=1e-6)
        actor = pickle.loads(pickle.dumps(PolicyActor(model.policy)))
        np.testing.assert_allclose(actor(obs), action, atol=1e-6)
        return loaded.policy

    return check
