"""The detector grid and the PEM grid on the same close passes: vetoes, blobs in the car's path and
pits grown sideways.

Drives ``grid_planner`` (heading lattice, 0.2 m cells, 15 km/h, ``filter_lead_s = 1``, behind paper
N's brake-only filter with the 8 m hazard hold: docs/training.md, "The heading lattice") on the
detector grid of OffroadNav-v2 from seed ``--first-seed`` on, then applies the actions the filter
let through unchanged to the same course on the PEM grid, so both grids see the same true poses
(the vehicle draws from its own generator). At every step it asks a :class:`BrakingSafetyFilter`
on each env whether it would veto the action, and compares the two grids' ``negative`` layers
with the oracle's on the same poses:

- ``vetoes``: the steps each grid's filter would veto (on the detector's none were applied
  differently: the actions are the ones it let through);
- ``path_blobs``: blobs clear of every true pit by 1 m whose centre lies within 2.5 m of the
  car's axis and 1 m behind to 8 m ahead of the rear axle: what the filter's hold keeps in the
  car's way;
- ``overhang_m``: for each true pit beside the car (its cells reach from 1 m behind the rear axle
  to the front bumper, all on one side, within 3 m of the axis), how much nearer the axis the
  grid draws its inner side than the pit's own cells lie (mean over pit-steps).

Prints one line per seed and the totals. docs/notebook/pem.md, "Close passes on OffroadNav-v2".

Run: python studies/pem_close_passes.py [--seeds 7] [--first-seed 1000000] [--pem-model FILE]
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy import ndimage

from negobs_gym.envs import make_env
from negobs_gym.eval.scenario_runner import make_driver
from negobs_gym.safety import BrakingSafetyFilter

SETTINGS = (
    "run.target_speed_mps=4.17",
    "observation.downsample=1",
    "filter.margin_m=0",
    "filter.hazard_memory_hold_m=8",
    "run.driver_settings.planner.bend_steps=1",
    "run.driver_settings.filter_lead_s=1.0",
)
CLEAR_CELLS = 5  # 1 m of 0.2 m cells: a blob this far from every true pit is not a fragment of one
FRONT_M = 3.65  # the car's front bumper ahead of its rear axle [m]


def _env(source: str, extra: tuple[str, ...]):
    env = make_env("offroad_nav_v2", [*SETTINGS, *extra, f"observation.source={source}"])
    return env, BrakingSafetyFilter(env, env.unwrapped.scenario.filter)


def _drive(seed: int, extra: tuple[str, ...], max_steps: int = 600):
    """The detector drive's applied actions and each step's ``negative`` layer and veto."""
    env, guard = _env("detector", extra)
    obs, info = guard.reset(seed=seed)
    driver = make_driver("grid_planner", env.unwrapped.scenario, env.unwrapped.terrain)
    driver.reset(seed)
    actions, layers, vetoes = [], [], []
    for _ in range(max_steps):
        action, decision = guard.filter_action(driver.act(obs, info))
        actions.append(np.asarray(action))
        vetoes.append(bool(decision.vetoed))
        obs, _, terminated, truncated, info = env.step(action)
        layers.append(obs["grid"][0].astype(bool))
        if terminated or truncated:
            break
    env.close()
    return actions, layers, vetoes


def _replay(seed: int, source: str, actions, extra: tuple[str, ...]):
    env, guard = _env(source, extra)
    guard.reset(seed=seed)
    layers, vetoes = [], []
    for action in actions:
        vetoes.append(bool(guard.filter_action(action)[1].vetoed))
        obs, *_ = env.step(action)
        layers.append(obs["grid"][0].astype(bool))
    env.close()
    return layers, vetoes


def _path_blobs(layer: np.ndarray, truth: np.ndarray, x: np.ndarray, y: np.ndarray) -> int:
    clear = layer & ~ndimage.binary_dilation(truth, iterations=CLEAR_CELLS)
    labels, count = ndimage.label(clear, structure=np.ones((3, 3), dtype=bool))
    if not count:
        return 0
    index = np.arange(1, count + 1)
    cx, cy = ndimage.mean(x, labels, index), ndimage.mean(y, labels, index)
    return int(np.sum((np.abs(cx) < 2.5) & (cy > -1.0) & (cy < 8.0)))


def _overhangs(layer: np.ndarray, truth: np.ndarray, x: np.ndarray, y: np.ndarray) -> list[float]:
    labels, count = ndimage.label(truth, structure=np.ones((3, 3), dtype=bool))
    out = []
    for k in range(1, count + 1):
        pit = labels == k
        side = np.sign(x[pit])
        if not (y[pit].min() < FRONT_M and y[pit].max() > -1.0) or np.any(side != side[0]):
            continue
        inner = np.abs(x[pit]).min()
        zone = ndimage.binary_dilation(pit, iterations=CLEAR_CELLS) & (np.sign(x) == side[0]) & layer
        if inner <= 3.0 and zone.any():
            out.append(float(inner - np.abs(x[zone]).min()))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=7)
    parser.add_argument("--first-seed", type=int, default=1_000_000)
    parser.add_argument("--pem-model", default=None, help="PEM file (default: the shipped one)")
    args = parser.parse_args()
    extra = (f"observation.pem_model={args.pem_model}",) if args.pem_model else ()
    totals = {g: {"vetoes": 0, "path_blobs": 0, "overhang": []} for g in ("detector", "pem")}
    steps = 0
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        actions, detector_layers, detector_vetoes = _drive(seed, extra)
        pem_layers, pem_vetoes = _replay(seed, "pem", actions, extra)
        oracle_layers, _ = _replay(seed, "oracle", actions, extra)
        env = make_env("offroad_nav_v2", [*SETTINGS, "observation.source=oracle"])
        x, y = env.unwrapped.scenario.observation.grid.cell_centres().transpose(2, 0, 1)
        env.close()
        steps += len(actions)
        line = [f"seed={seed}", f"steps={len(actions)}"]
        for grid, layers, vetoes in (
            ("detector", detector_layers, detector_vetoes),
            ("pem", pem_layers, pem_vetoes),
        ):
            blobs = sum(_path_blobs(a, t, x, y) for a, t in zip(layers, oracle_layers, strict=True))
            over = [o for a, t in zip(layers, oracle_layers, strict=True) for o in _overhangs(a, t, x, y)]
            totals[grid]["vetoes"] += sum(vetoes)
            totals[grid]["path_blobs"] += blobs
            totals[grid]["overhang"] += over
            line += [f"{grid}_vetoes={sum(vetoes)}", f"{grid}_path_blobs={blobs}"]
        print(" ".join(line), flush=True)
    print(f"steps={steps}")
    for grid, t in totals.items():
        mean = float(np.mean(t["overhang"])) if t["overhang"] else float("nan")
        print(
            f"{grid}_vetoes={t['vetoes']} {grid}_path_blobs={t['path_blobs']} "
            f"{grid}_overhang_m={mean:.3f} {grid}_overhang_pit_steps={len(t['overhang'])}"
        )


if __name__ == "__main__":
    main()
