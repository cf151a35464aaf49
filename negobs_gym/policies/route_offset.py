"""A steering head that chooses where across the track to drive, and steers there by pure pursuit.

A policy that outputs the steering itself must learn the track's curvature and its own closed-loop
correction besides where to pass each obstacle, and a clone's steering errors compound: a drift
off the demonstrator's line meets states it never saw (the OffroadNav-v2 clones steer half as hard
as their expert and leave the track; docs/notebook/training_studies.md). Policies that predict a
target and leave the tracking to a controller learn the decision alone (waypoints and a PID
controller in Chen et al. 2019, "Learning by Cheating"). :class:`RouteOffsetPolicy` outputs, besides
the throttle/brake, a lateral offset from the centre line at the route point
``SteeringHeadConfig.route_point_m`` ahead, which the ``state`` observation gives in the vehicle
frame (``ObservationConfig.route_points_m``), and steers towards that point by pure pursuit
(curvature 2 x_left / L^2, as :class:`~negobs_gym.drivers.pure_pursuit.PurePursuitDriver`): a
constant offset drives the car along the centre line shifted by it, so errors are corrected by
the geometry instead of compounding. The env's action (throttle/brake, steering) is unchanged, so
the safety filter, ``negobs eval policy`` and every driver run it as any ``MultiInputPolicy``;
behaviour cloning fits the steering it drives (the map is differentiable) and PPO explores around
it.
"""

from __future__ import annotations

from typing import Any

import torch
from stable_baselines3.common.distributions import DiagGaussianDistribution, Distribution
from stable_baselines3.common.policies import BasePolicy, MultiInputActorCriticPolicy
from stable_baselines3.common.type_aliases import PyTorchObs

from negobs_gym.drivers.pure_pursuit import PurePursuitConfig
from negobs_gym.errors import ConfigError
from negobs_gym.policies.config import STEERING, SteeringHeadConfig

__all__ = ["RouteOffsetPolicy", "pursuit_steering", "route_columns"]

#: The car's wheelbase and full steering: the pure-pursuit driver's (the envs' car).
_PURSUIT = PurePursuitConfig()
#: The target's distance is floored at this, so the steering stays finite where the route's
#: points come near the car (at the track's end, where they also coincide) [m].
_SHORT_M = 0.5


def route_columns(state_fields: tuple[str, ...], point_m: float) -> tuple[int, int, int, int]:
    """Indices in ``state`` of the route point ``point_m`` ahead (x, y) and the next one (x, y).

    Raises:
        ConfigError: the state has no such route point or none after it (field ``head.route_point_m``).
    """
    points = sorted({float(name.split("_")[1]) for name in state_fields if name.startswith("route_")})
    if point_m not in points or points.index(point_m) == len(points) - 1:
        raise ConfigError(
            "head.route_point_m",
            f"needs the route point {point_m:g} m and one beyond it in the observation "
            f"(observation.route_points_m), which gives {points}",
        )
    after = points[points.index(point_m) + 1]
    names = (
        f"route_{point_m:g}_x_m",
        f"route_{point_m:g}_y_m",
        f"route_{after:g}_x_m",
        f"route_{after:g}_y_m",
    )
    return tuple(state_fields.index(name) for name in names)  # type: ignore[return-value]


def pursuit_steering(route: torch.Tensor, offset_m: torch.Tensor) -> torch.Tensor:
    """Normalised steering (+ left, 1 = full lock) towards the route point shifted ``offset_m``
    to the left of the route, by pure pursuit.

    Args:
        route: (B, 4) the route point and the next one, x right and y forward [m].
        offset_m: (B,) lateral offset, + left of the route's direction [m].
    """
    point, after = route[:, :2], route[:, 2:]
    heading = after - point
    length = heading.norm(dim=1, keepdim=True)
    forward = torch.tensor([0.0, 1.0], dtype=route.dtype).expand_as(heading)
    heading = torch.where(length > 1e-6, heading / length.clamp_min(1e-6), forward)
    # x right, y forward: left of (0, 1) is (-1, 0)
    left = torch.stack([-heading[:, 1], heading[:, 0]], dim=1)
    target = point + offset_m[:, None] * left
    squared = (target**2).sum(dim=1).clamp_min(_SHORT_M**2)
    curvature = -2.0 * target[:, 0] / squared
    return torch.atan(_PURSUIT.wheelbase_m * curvature) / _PURSUIT.max_steer_rad


class RouteOffsetPolicy(MultiInputActorCriticPolicy):
    """``MultiInputPolicy`` whose steering mean is pure pursuit towards a learned offset from the
    route (module docstring); the offset is ``head.route_offset_m`` x tanh of the action net's output.

    Args:
        head: The steering head, with ``route_offset_m`` > 0 and one candidate.
        state_columns: Indices in the ``state`` observation of the route point and the next one
            (:func:`route_columns`).
    """

    def __init__(
        self, *args: Any, head: SteeringHeadConfig, state_columns: tuple[int, int, int, int], **kwargs: Any
    ) -> None:
        if not isinstance(head, SteeringHeadConfig) or head.route_offset_m <= 0 or head.modes != 1:
            raise ConfigError(
                "head", f"a route-offset policy needs route_offset_m > 0 and one candidate, got {head!r}"
            )
        self.head = head
        self.state_columns = tuple(int(c) for c in state_columns)
        self._route: torch.Tensor | None = None
        super().__init__(*args, **kwargs)
        if not isinstance(self.action_dist, DiagGaussianDistribution):
            raise ConfigError("head", "a route-offset policy needs a Gaussian policy (no gSDE)")

    def _get_constructor_parameters(self) -> dict[str, Any]:
        return {
            **super()._get_constructor_parameters(),
            "head": self.head,
            "state_columns": self.state_columns,
        }

    def _remember_route(self, obs: PyTorchObs) -> None:
        # SB3 hands _get_action_dist_from_latent the latent features alone; the route comes from
        # the same call's observation, kept here by each entry point that builds a distribution
        self._route = obs["state"][:, list(self.state_columns)].float()  # type: ignore[index]

    def forward(self, obs: PyTorchObs, deterministic: bool = False):  # type: ignore[override]
        self._remember_route(obs)
        return super().forward(obs, deterministic)

    def evaluate_actions(self, obs: PyTorchObs, actions: torch.Tensor):  # type: ignore[override]
        self._remember_route(obs)
        return super().evaluate_actions(obs, actions)

    def get_distribution(self, obs: PyTorchObs) -> Distribution:
        self._remember_route(obs)
        return super().get_distribution(obs)

    def offset_m(self, obs: PyTorchObs) -> torch.Tensor:
        """(B,) the lateral offset from the route the policy drives towards [m]."""
        features = BasePolicy.extract_features(self, obs, self.pi_features_extractor)
        return self._offset(self.action_net(self.mlp_extractor.forward_actor(features)))

    def _offset(self, out: torch.Tensor) -> torch.Tensor:
        return self.head.route_offset_m * torch.tanh(out[:, STEERING])

    def _get_action_dist_from_latent(self, latent_pi: torch.Tensor) -> Distribution:
        if self._route is None or self._route.shape[0] != latent_pi.shape[0]:
            raise RuntimeError("RouteOffsetPolicy: a distribution asked for without its observation")
        out = self.action_net(latent_pi)
        steering = pursuit_steering(self._route, self._offset(out))
        mean = torch.cat([out[:, :STEERING], steering[:, None], out[:, STEERING + 1 :]], dim=1)
        return self.action_dist.proba_distribution(mean, self.log_std)
