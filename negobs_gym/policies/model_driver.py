"""A saved stable-baselines3 model as a driver: what ``negobs eval policy``, the braking
campaign's ``sb3`` driver and ``negobs scenario run --policy`` drive with."""

from __future__ import annotations

from negobs_gym.errors import ConfigError
from negobs_gym.policies.observation import PolicyDriver

__all__ = ["ModelDriver"]


class ModelDriver(PolicyDriver):
    """A saved stable-baselines3 model as a driver (deterministic actions); ``path`` may name a
    shipped policy instead (:func:`~negobs_gym.policies.baselines.resolve_model`).

    Observations are adapted to the model's space (:func:`~negobs_gym.policies.match_observation`),
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
        import stable_baselines3
        import torch

        from negobs_gym.policies.baselines import resolve_model

        torch.set_num_threads(1)

        cls = getattr(stable_baselines3, algo, None)
        if cls is None:
            raise ConfigError("algo", f"stable_baselines3 has no algorithm {algo!r}")
        self.algo = algo
        super().__init__(cls.load(resolve_model(str(path)), device="cpu"), str(path))

    def __reduce__(self) -> tuple:
        return type(self), (self.name, self.algo)
