"""A steering head with K scored candidates, for clones of a demonstrator that passes on either side.

SB3's Gaussian head has one mean, and a behaviour-cloning fit by mean squared error puts it
between the demonstrator's actions wherever they differ for like observations: where the track
planner passes an obstacle to the left on one course and to the right on a similar one, the clone
learns to steer half as hard, or straight on (docs/notebook/training_studies.md, "Where the clones' drives
leave the expert's"). :class:`SteeringModesPolicy` outputs K steering candidates and a score for each;
its action mean is the best-scored candidate (with the other action values as SB3 computes them),
so PPO, ``predict`` and ``negobs eval policy`` use it as any ``MultiInputPolicy``. Behaviour
cloning fits it with :meth:`SteeringModesPolicy.imitation_loss`: one candidate learns each
label, the one whose steering bin holds it (``SteeringHeadConfig.bin_edges``) or else the nearest
(multiple-choice learning, Guzman-Rivera et al. 2012; relaxed as in Rupprecht et al. 2017), and
the scores learn which candidate that was. PPO's gradient reaches the chosen candidate, not the
scores.
"""

from __future__ import annotations

from typing import Any

import torch
from stable_baselines3.common.distributions import DiagGaussianDistribution, Distribution
from stable_baselines3.common.policies import BasePolicy, MultiInputActorCriticPolicy
from stable_baselines3.common.preprocessing import get_action_dim
from stable_baselines3.common.type_aliases import PyTorchObs, Schedule
from torch import nn

from negobs_gym.errors import ConfigError
from negobs_gym.policies.config import STEERING, SteeringHeadConfig

__all__ = ["SteeringModesPolicy"]

#: Without bin edges, the candidates' initial steering values span this much of each side, so
#: that each starts nearest to other labels (identical candidates would stay identical).
INITIAL_SPREAD = 0.5


class SteeringModesPolicy(MultiInputActorCriticPolicy):
    """``MultiInputPolicy`` whose steering mean is the best-scored of ``head.modes`` candidates.

    ``action_net`` outputs, per observation, K scores, K steering candidates and the other action
    values (throttle/brake); ``log_std`` and the value function are SB3's.
    """

    def __init__(self, *args: Any, head: SteeringHeadConfig, **kwargs: Any) -> None:
        if not isinstance(head, SteeringHeadConfig) or head.modes < 2:
            raise ConfigError("head", f"candidates need a SteeringHeadConfig with modes >= 2, got {head!r}")
        self.head = head  # _build, called by the base constructor, reads it
        super().__init__(*args, **kwargs)
        if not isinstance(self.action_dist, DiagGaussianDistribution):
            raise ConfigError("head", "steering candidates need a Gaussian policy (no gSDE)")

    def _build(self, lr_schedule: Schedule) -> None:
        super()._build(lr_schedule)
        action_dim = get_action_dim(self.action_space)
        if action_dim <= STEERING:
            raise ConfigError("head", f"the action has {action_dim} values, no steering at column {STEERING}")
        k = self.head.modes
        self.action_net = nn.Linear(self.mlp_extractor.latent_dim_pi, 2 * k + action_dim - 1)
        if self.ortho_init:
            self.init_weights(self.action_net, gain=0.01)  # SB3's gain for the action mean
        with torch.no_grad():
            self.action_net.bias[k : 2 * k] = _initial_candidates(self.head)
        # the base class built the optimiser over the replaced layer's parameters
        self.optimizer = self.optimizer_class(self.parameters(), lr=lr_schedule(1), **self.optimizer_kwargs)

    def _get_constructor_parameters(self) -> dict[str, Any]:
        return {**super()._get_constructor_parameters(), "head": self.head}

    def _split(self, out: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        k = self.head.modes
        return out[:, :k], out[:, k : 2 * k], out[:, 2 * k :]

    def candidates(self, obs: PyTorchObs) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Scores (B, K), steering candidates (B, K) and the other action values (B, A - 1)."""
        features = BasePolicy.extract_features(self, obs, self.pi_features_extractor)
        return self._split(self.action_net(self.mlp_extractor.forward_actor(features)))

    def _get_action_dist_from_latent(self, latent_pi: torch.Tensor) -> Distribution:
        scores, steering, others = self._split(self.action_net(latent_pi))
        chosen = steering.gather(1, scores.argmax(dim=1, keepdim=True))
        mean = torch.cat([others[:, :STEERING], chosen, others[:, STEERING:]], dim=1)
        return self.action_dist.proba_distribution(mean, self.log_std)

    def imitation_loss(self, obs: PyTorchObs, target: torch.Tensor) -> torch.Tensor:
        """Behaviour-cloning loss on labels ``target`` (B, A), on the scale of a mean squared error
        over the A action values, plus ``head.choice_weight`` x the scores' cross-entropy against
        the candidate that learns each steering label (its bin, or the nearest)."""
        scores, steering, others = self.candidates(obs)
        label = target[:, STEERING]
        error = (steering - label[:, None]) ** 2
        if self.head.bin_edges:
            edges = torch.tensor(self.head.bin_edges, dtype=label.dtype)
            learner, w = torch.bucketize(label.contiguous(), edges), 0.0
        else:
            learner, w = error.argmin(dim=1), self.head.other_modes_weight
        steering_error = (1 - w) * error.gather(1, learner[:, None]).squeeze(1) + w * error.mean(dim=1)
        other_targets = torch.cat([target[:, :STEERING], target[:, STEERING + 1 :]], dim=1)
        squared = steering_error + ((others - other_targets) ** 2).sum(dim=1)
        choice = nn.functional.cross_entropy(scores, learner)
        return squared.mean() / target.shape[1] + self.head.choice_weight * choice


def _initial_candidates(head: SteeringHeadConfig) -> torch.Tensor:
    """The candidates' steering before the fit: the middle of each bin of [-1, 1], or spread."""
    if not head.bin_edges:
        return torch.linspace(-INITIAL_SPREAD, INITIAL_SPREAD, head.modes)
    bounds = torch.tensor([-1.0, *head.bin_edges, 1.0])
    return (bounds[:-1] + bounds[1:]) / 2
