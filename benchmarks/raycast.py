"""Ray-cast speed: the full native paper N rig + the LUX, Embree vs. PyBullet, on one scene.

The scene is :func:`~negobs_gym.sensors.raycast.agreement.agreement_terrain` (rough course with a
pit, a trench, a rock, a pedestrian, a parked car and a mound) plus a second vehicle as a dynamic
body; the sensors ride on the own vehicle, which both backends exclude. One revolution of every
sensor: HDL-64E S2 (64 x 4000), two HDL-32E (32 x 2250 each) and the IBEO LUX (4 x 341).

Embree runs four ways, on one thread each: the default packets (the widest the CPU's kernels
cast natively, 16 rays with AVX-512, 8 with AVX2) over shared buffers with the fast terrain test
(``EmbreeConfig(ray_packets=True, fast_terrain=True)``: Embree's non-watertight triangle test, the
rays it may have let through cast again robustly), the same packets on the robust scene alone
(``fast_terrain=False``), 16-ray packets on the robust scene (``packet_width=16``:
``packet_width_speedup=``, 1.00 where 16 is the native width), and embreex's single-ray loop
(robust), with their scene builds, the dynamic scene's rebuild after the other vehicle moved,
whether the robust packets equal the single-ray loop and the 16-ray packets bit for bit, and how
far the fast terrain test's ranges are from the robust ones.

The last two lines are ``speedup_vs_pybullet=<ratio>`` (best-of-N time of PyBullet / Embree)
and ``agreement=<fraction>`` (share of rays with the same hit/miss and, for hits, |dr| <= 1 cm).

Run: ``python benchmarks/raycast.py [--repeats 5] [--stations 4 20] [--pybullet-threads 0]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from negobs_gym.core.pose import Pose
from negobs_gym.sensors import paper_n_rig, paper_t_rig
from negobs_gym.sensors.lidar import scan_rays_world
from negobs_gym.sensors.raycast.agreement import agreement_terrain, compare_ranges
from negobs_gym.sensors.raycast.embree_backend import EmbreeCaster, EmbreeConfig
from negobs_gym.sensors.raycast.pybullet_backend import PyBulletCaster
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World

MAX_RANGE_M = 120.0  # HDL-64E S2 datasheet range; the LUX's 200 m is cut to it here


def _best_time(fn, repeats: int) -> tuple[float, np.ndarray]:
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=5, help="Embree repeats (best time is kept)")
    parser.add_argument("--pybullet-repeats", type=int, default=2)
    parser.add_argument("--pybullet-threads", type=int, default=0, help="rayTestBatch numThreads (0 = all)")
    parser.add_argument("--stations", type=float, nargs="+", default=[4.0, 20.0], help="vehicle stations [m]")
    args = parser.parse_args()

    terrain = agreement_terrain(seed=args.seed)
    with World(terrain) as world:
        own = Vehicle(world)
        xy, yaw = terrain.track.pose_at(9.0, 2.2)
        other = Vehicle(world, start_pose=Pose(float(xy[0]), float(xy[1]), 0.0, 0.0, 0.0, float(yaw)))
        casters, t_build, t_rebuild = {}, {}, {}
        for name, packets, fast_terrain, width in (
            ("packets", True, True, None),
            ("robust_packets", True, False, None),
            ("robust_packets_16", True, False, 16),
            ("single_ray", False, False, None),
        ):
            t0 = time.perf_counter()
            casters[name] = EmbreeCaster.from_world(
                world,
                exclude_body_ids=[own.body_id],
                config=EmbreeConfig(
                    ray_packets=packets, auto_update=False, fast_terrain=fast_terrain, packet_width=width
                ),
            )
            t_build[name] = time.perf_counter() - t0
        pose0 = other.true_pose()
        other.reset(
            Pose(pose0.x + 0.5, pose0.y, 0.0, 0.0, 0.0, pose0.yaw)
        )  # moved: rebuild the dynamic scene
        for name, caster in casters.items():
            t0 = time.perf_counter()
            caster.update_dynamic()
            t_rebuild[name] = time.perf_counter() - t0
        embree = casters["packets"]
        bullet = PyBulletCaster(
            world.client_id, exclude_body_ids=[own.body_id], num_threads=args.pybullet_threads
        )
        mounts = [*paper_n_rig().mounts, *paper_t_rig().mounts]
        t_e = t_b = t_single = t_robust = t_wide = 0.0
        refs, fasts, robusts = [], [], []
        n_rays = 0
        same = same_wide = True
        for station in args.stations:
            sxy, syaw = terrain.track.pose_at(station)
            own.reset(Pose(float(sxy[0]), float(sxy[1]), 0.0, 0.0, 0.0, float(syaw)))
            pose = own.true_pose()
            rays = [scan_rays_world(m, pose) for m in mounts]
            o = np.concatenate([r[0] for r in rays])
            d = np.concatenate([r[1] for r in rays])
            n_rays += len(o)
            te, fast = _best_time(lambda o=o, d=d: embree.cast(o, d, MAX_RANGE_M), args.repeats)
            robust = casters["robust_packets"]
            tr, exact = _best_time(lambda o=o, d=d, c=robust: c.cast(o, d, MAX_RANGE_M), args.repeats)
            wide = casters["robust_packets_16"]
            tw, wide16 = _best_time(lambda o=o, d=d, c=wide: c.cast(o, d, MAX_RANGE_M), args.repeats)
            same_wide &= bool(np.array_equal(exact, wide16, equal_nan=True))
            t_wide += tw
            single = casters["single_ray"]
            ts, slow = _best_time(lambda o=o, d=d, c=single: c.cast(o, d, MAX_RANGE_M), args.repeats)
            tb, ref = _best_time(lambda o=o, d=d: bullet.cast(o, d, MAX_RANGE_M), args.pybullet_repeats)
            same &= bool(np.array_equal(exact, slow, equal_nan=True))
            t_e += te
            t_robust += tr
            t_single += ts
            t_b += tb
            refs.append(ref)
            fasts.append(fast)
            robusts.append(exact)
            print(
                f"station {station:5.1f} m: {len(o)} rays, embree {te * 1e3:.1f} ms "
                f"(robust scene {tr * 1e3:.1f} ms, single-ray {ts * 1e3:.1f} ms), pybullet {tb * 1e3:.0f} ms"
            )
    a = compare_ranges(np.concatenate(refs), np.concatenate(fasts), tol_m=0.01)
    print(f"rig: {', '.join(f'{m.name} {m.model.n_lasers}x{m.model.n_columns}' for m in mounts)}")
    print(
        f"embree_scene_build_s={t_build['packets']:.3f} (single-ray: {t_build['single_ray']:.3f}; "
        f"{embree.n_static_triangles} static triangles)"
    )
    print(
        f"embree_dynamic_rebuild_ms={t_rebuild['packets'] * 1e3:.1f} "
        f"(single-ray: {t_rebuild['single_ray'] * 1e3:.1f}; the other vehicle moved)"
    )
    print(
        f"embree_rays_per_s={n_rays / t_e:.3e} (robust scene: {n_rays / t_robust:.3e}; "
        f"single-ray: {n_rays / t_single:.3e})"
    )
    fast_all, robust_all = np.concatenate(fasts), np.concatenate(robusts)
    both = ~np.isnan(fast_all) & ~np.isnan(robust_all)
    print(
        f"fast_terrain_speedup={t_robust / t_e:.2f} hit_miss_equal_robust="
        f"{np.mean(np.isnan(fast_all) == np.isnan(robust_all)):.6f} "
        f"max_abs_dr_vs_robust_m={np.abs(fast_all[both] - robust_all[both]).max():.2e}"
    )
    print(
        f"packet_speedup={t_single / t_robust:.2f} packets_equal_single_ray={same} (robust scenes, "
        f"{robust.packet_width} rays per packet)"
    )
    print(
        f"packet_width_speedup={t_wide / t_robust:.2f} (16 rays per packet against {robust.packet_width}, "
        f"robust scene) equal={same_wide}"
    )
    print(f"pybullet_rays_per_s={n_rays / t_b:.3e} (numThreads={args.pybullet_threads})")
    print(f"hit_miss_agreement={a.hit_miss:.6f}")
    print(
        f"range_within_1cm={a.within_tol:.6f} of {a.n_common_hits} common hits "
        f"(max |dr| {a.max_abs_dr_m:.3f} m)"
    )
    print(f"speedup_vs_pybullet={t_b / t_e:.1f}")
    print(f"agreement={a.overall:.6f}")


if __name__ == "__main__":
    main()
