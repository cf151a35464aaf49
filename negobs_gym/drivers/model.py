"""A trained model as a driver: what ``negobs eval policy``, the braking campaign's ``sb3``
driver and ``negobs scenario run --policy`` drive with.

:func:`match_observation` feeds a raw env observation to a model trained behind
:class:`negobs_gym.policies.PolicyObservation` (flat grid, or the state alone).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces

from negobs_gym.drivers.zoo import resolve_model
from negobs_gym.errors import ConfigError

__all__ = ["ModelDriver", "PolicyDriver", "match_observation"]


def match_observation(observation: Mapping[str, Any], space: spaces.Space) -> Any:
    """``observation`` as ``space`` expects it: keys the space lacks dropped, arrays of the same
    size reshaped (a raw env's 3-D grid for a model trained on the flat one).

    Raises:
        ConfigError: a key of ``space`` is missing, or an array's size differs from its space
            (field ``observation.KEY``).
    """
    if not isinstance(space, spaces.Dict):
        return observation
    out: dict[str, np.ndarray] = {}
    for key, sub in space.spaces.items():
        if key not in observation:
            raise ConfigError(
                f"observation.{key}", f"missing (keys: {sorted(observation)}); the policy needs it"
            )
        value = np.asarray(observation[key])
        if value.shape != sub.shape:
            if value.size != int(np.prod(sub.shape)):
                raise ConfigError(
                    f"observation.{key}", f"has shape {value.shape}, the policy expects {sub.shape}"
                )
            value = value.reshape(sub.shape)
        out[key] = value
    return out


class PolicyDriver:
    """An SB3 model as a driver (``reset(seed)``, ``act(obs, info)``) on a raw env's observations;
    ``name`` is how errors and results name it."""

    def __init__(self, model: Any, name: str = "the model") -> None:
        self.model = model
        self.name = name

    def reset(self, seed: int | None = None) -> None:
        """Stateless policy."""

    def act(self, obs: Any, info: Mapping[str, Any]) -> np.ndarray:
        """The model's deterministic action for ``obs`` (adapted with :func:`match_observation`).

        Raises:
            ConfigError: ``obs`` does not fit the model's observation space (field ``policy``):
                the env observes something else than the model was trained on.
        """
        try:
            observation = match_observation(obs, self.model.observation_space)
        except ValueError as error:
            raise ConfigError(
                "policy", f"the env's observation does not fit {self.name}'s: {error}"
            ) from None
        action, _ = self.model.predict(observation, deterministic=True)
        return np.asarray(action, dtype=np.float32)


class ModelDriver(PolicyDriver):
    """A saved stable-baselines3 model as a driver (deterministic actions); ``path`` may name a
    shipped policy instead (:func:`~negobs_gym.drivers.zoo.resolve_model`).

    Observations are adapted to the model's space (:func:`match_observation`),
    so a model trained by ``negobs train`` (flat grid, or the state alone) runs on the raw env.
    Loading one sets torch to one intra-op thread in this process, as training does
    (``TrainConfig.torch_threads``: the network is too small to gain from more, and with two
    threads on busy cores one ``predict`` took 45 ms instead of 1 ms). It pickles as its path and
    algorithm, so a process it is sent to loads the model again (the scenario runner's workers).

    Attributes:
        name: ``path`` as given (a file or a shipped policy's name): how results name the driver.
        algo: The stable-baselines3 algorithm that saved it.

    Raises:
        ConfigError: an algorithm stable-baselines3 lacks (field ``algo``), or no saved model
            and no shipped policy of that name (``model_path``).
    """

    def __init__(self, path: str, algo: str = "PPO") -> None:
        import stable_baselines3  # heavy (torch): imported when a model is loaded
        import torch

        torch.set_num_threads(1)

        cls = getattr(stable_baselines3, algo, None)
        if cls is None:
            raise ConfigError("algo", f"stable_baselines3 has no algorithm {algo!r}")
        self.algo = algo
        super().__init__(cls.load(resolve_model(str(path)), device="cpu"), str(path))

    def __reduce__(self) -> tuple:
        return type(self), (self.name, self.algo)
