"""Stage timings for ``evaluate.py bench``: medians over repeated runs, in milliseconds."""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.model import Element, World
from pimm_env.world.semantics import SemanticClass
from pimm_env.world.shapes import Box, Cylinder

if TYPE_CHECKING:
    from pimm_agents.pimm.feature_filter import FeatureFilter
    from pimm_agents.pimm.rivals import RivalTracker
    from pimm_agents.pimm.scan_stack import ScanStack


#: the stages of a PIMM update that perceive the scan (``pimm_perception_ms``); the rest is the filter's update
PERCEPTION_STAGES = ("segmentation", "corners", "pose_inference")


def median_ms(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1000 * float(np.median(times))


def run_benchmarks(repeats: int = 30) -> dict[str, float]:
    """Env step with and without a fresh 3D scan, both ray casters, and an area_a rollout's real-time factor."""
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    ensure_derived_maps(load_world("iilab"))
    from pimm_env.driving.rollout import run
    from pimm_env.driving.scenarios import get_scenario
    from pimm_env.envs.base_env import SimConfig
    from pimm_env.envs.iilab_env import IILabEnv
    from pimm_env.sim.lidar import azimuths_3d, elevations_3d
    from pimm_env.sim.raycast import BulletRayCaster
    from pimm_env.sim.scene import BulletScene

    figures: dict[str, float] = {}
    env = IILabEnv(terminate_on_collision=False)
    env.reset(seed=0, options={"pose": [-10.0, 4.2, 0.0]})
    stepped_plain: list[float] = []
    stepped_scan: list[float] = []
    action = np.array([0.2, 0.0], dtype=np.float32)
    while min(len(stepped_plain), len(stepped_scan)) < repeats:
        start = time.perf_counter()
        _, _, _, _, info = env.step(action)
        elapsed = time.perf_counter() - start
        (stepped_scan if info["fresh_cloud"] else stepped_plain).append(elapsed)
        if env.robot.pose[0] > -2.0:
            env.reset(seed=0, options={"pose": [-10.0, 4.2, 0.0]})
    figures["env_step_ms"] = 1000 * float(np.median(stepped_plain))
    figures["env_step_scan_ms"] = 1000 * float(np.median(stepped_scan))
    l3 = env.config.lidar3d
    origin = np.array([-10.0, 4.2, env.world.floor_z + l3.height])
    scene = BulletScene(env.world, env.config.robot.footprint_radius)  # the env builds none unless asked
    bullet = BulletRayCaster(scene.client, scene.body_classes)
    azimuths, elevations = azimuths_3d(l3), elevations_3d(l3)
    figures["lidar3d_bullet_ms"] = median_ms(
        lambda: bullet.cast(origin, azimuths, elevations, l3.max_range), max(3, repeats // 5)
    )
    scene.close()
    figures.update(big_world_benchmarks(env, origin, repeats))
    env.close()
    config = replace(SimConfig(), lidar3d=replace(SimConfig().lidar3d, rate_hz=10.0))
    rollout_env = IILabEnv(config=config, terminate_on_collision=False)
    result = run(get_scenario("area_a"), env=rollout_env)
    rollout_env.close()
    figures["realtime_factor"] = result.realtime_factor
    figures.update(amcl_benchmarks(repeats))
    figures["corners_ms"] = corners_benchmark(repeats)
    figures.update(perception_benchmarks(repeats))
    figures.update(pimm_benchmarks(repeats))
    figures["thesis_pointnet_ms"] = thesis_pointnet_benchmark(max(3, repeats // 10))
    # same run, same load: how many times the thesis's network alone costs our whole pipeline and segmentation
    figures["thesis_pointnet_over_pipeline"] = figures["thesis_pointnet_ms"] / figures["pimm_pipeline_ms"]
    figures["thesis_pointnet_over_segmentation"] = figures["thesis_pointnet_ms"] / figures["segmentation_ms"]
    figures["thesis_pointnet_over_perception"] = figures["thesis_pointnet_ms"] / figures["pimm_perception_ms"]
    figures.update(registration_benchmarks(repeats))
    figures.update(node_benchmarks())
    return figures


def node_benchmarks(seconds: float = 30.0) -> dict[str, float]:
    """PIMM as a ROS 2 node beside ``sim-robot`` (area_a at real time, loopback): from a cloud's arrival to the
    publication of the pose made with it (median, p99, max over ``seconds``), and the clouds it skipped."""
    from pimm_agents.ros2.latency import node_latency

    report = node_latency("pimm", "area_a", seconds)
    latency = report["latency_ms"] or {"median": float("nan"), "p99": float("nan"), "max": float("nan")}
    return {
        "node_latency_ms": latency["median"],
        "node_latency_p99_ms": latency["p99"],
        "node_latency_max_ms": latency["max"],
        "node_skipped_clouds": float(report["skipped_clouds"]),
    }


def thesis_pointnet_benchmark(repeats: int) -> float:
    """The thesis's segmentation network (3.5 M parameters, ``perception/thesis_pointnet.py``) on one scan of
    10 000 points, inference only, as the thesis ran it: the yardstick for our perception's cost."""
    import torch

    from pimm_agents.perception.thesis_pointnet import ThesisPointNet

    with torch.random.fork_rng():  # the layers' initial weights, seeded without touching torch's global stream
        torch.manual_seed(0)
        model = ThesisPointNet().eval()
    points = torch.randn(1, 3, 10_000, generator=torch.Generator().manual_seed(0))
    with torch.inference_mode():
        model(points)  # the first call allocates

        def forward() -> object:
            return model(points)

        return median_ms(forward, repeats)


def registration_benchmarks(repeats: int) -> dict[str, float]:
    """The registration localizer on one iilab scan: the scan's preparation (voxels, normals), a tracking
    ICP from a guess 0.2 m and 3 deg off, and a global search."""
    from pimm_agents.factory import make_localizer
    from pimm_agents.perception.point_features import valid_returns
    from pimm_agents.registration.localizer import RegistrationLocalizer
    from pimm_env.envs.iilab_env import IILabEnv

    env = IILabEnv(terminate_on_collision=False)
    obs, info = env.reset(seed=0, options={"pose": [-18.5, 14.0, 1.5708]})
    env.close()
    loc = make_localizer("registration", world="iilab")
    assert isinstance(loc, RegistrationLocalizer)
    loc.reset(seed=0)
    points = obs["cloud"][valid_returns(obs["cloud"], obs["cloud_mask"])].astype(float)
    points[:, 2] += loc.lidar3d.height
    scan = loc.prepare(points)
    guess = np.asarray(info["true_pose"], dtype=float) + np.array([0.2, 0.0, np.radians(3.0)])
    return {
        "registration_prepare_ms": median_ms(lambda: loc.prepare(points), repeats),
        "registration_icp_ms": median_ms(lambda: loc.refine(scan, guess), repeats),
        "registration_global_ms": median_ms(lambda: loc.search(scan), max(3, repeats // 10)),
    }


def cluttered(world: World, occupancy: OccupancyGrid, pieces: int, seed: int = 0) -> World:
    """``world`` with ``pieces`` more boxes and posts at random free places: a world of many elements."""
    rng = np.random.default_rng(seed)
    free = np.argwhere(occupancy.free)
    elements = list(world.elements)
    for k in range(pieces):
        row, col = free[rng.integers(len(free))]
        x, y = occupancy.grid.origin + (np.array([col, row]) + 0.5) * occupancy.grid.resolution
        shape = (
            Box((x, y, 0.5), (0.3, 0.2, 0.5), float(rng.uniform(0, np.pi)))
            if k % 2
            else Cylinder((x, y), 0.15, (0, 1.8))
        )
        elements.append(Element(f"bench_{k}", SemanticClass.CLUTTER, shape, True))
    return World(f"{world.name}+{pieces}", elements, world.areas, world.floor_z, world.source)


def big_world_benchmarks(env, origin: np.ndarray, repeats: int) -> dict[str, float]:
    """One 3D scan by Embree (the default) and by the prism caster in the iilab and in the iilab with 400
    pieces more (529 elements)."""
    from pimm_env.sim.lidar import azimuths_3d, elevations_3d
    from pimm_env.sim.raycast import EmbreeRayCaster, PrismRayCaster, RayCaster

    l3 = env.config.lidar3d
    azimuths, elevations = azimuths_3d(l3), elevations_3d(l3)
    figures = {}
    for label, world in (("", env.world), ("_529_elements", cluttered(env.world, env.maps.occupancy, 400))):
        casters: dict[str, RayCaster] = {"embree": EmbreeRayCaster(world), "prism": PrismRayCaster(world)}
        for name, caster in casters.items():

            def scan(c: RayCaster = caster) -> object:
                return c.cast(origin, azimuths, elevations, l3.max_range)

            figures[f"lidar3d_{name}{label}_ms"] = median_ms(scan, repeats)
    return figures


def pimm_benchmarks(repeats: int) -> dict[str, float]:
    """The feature filter's measurement update (10 000 particles, 5 features), and PIMM while driving from a
    global start: its update whenever it perceives a scan (segmentation, corners, retrieval, and the filter's
    weighing with it), each stage's share, and all its time spread over the scans that arrived."""
    from pimm_agents.factory import make_localizer
    from pimm_agents.particles.likelihood_field import LikelihoodField
    from pimm_agents.pimm.localizer import PimmLocalizer
    from pimm_agents.pimm.rivals import RivalTracker
    from pimm_env.envs.iilab_env import IILabEnv
    from pimm_env.mapping.derived_maps import load_derived_maps
    from pimm_env.world.files import load_world

    pimm = make_localizer("pimm")
    assert isinstance(pimm, PimmLocalizer)
    pimm.reset(seed=0)
    rng = np.random.default_rng(0)
    features = np.column_stack(
        [rng.uniform(-6, 6, (5, 2)), rng.uniform(-np.pi, np.pi, 5), np.full(5, 0.3), np.full(5, 0.2)]
    )
    figures = {"pf_update_ms": measurement_update_ms(pimm.filter, features, repeats)}
    figures.update(converged_update_benchmark(pimm.filter, features, repeats))
    env = IILabEnv(terminate_on_collision=False)
    obs, _ = env.reset(seed=0, options={"pose": [-10.0, 4.2, 0.0]})
    pimm.reset(seed=0)
    stages: dict[str, list[float]] = {}
    action = np.array([0.3, 0.0], dtype=np.float32)
    scans, all_updates_ms = 1, 0.0
    walls, occupancy = pimm.config.wall_field, load_derived_maps(load_world("iilab")).occupancy
    field = LikelihoodField(occupancy, walls.field_params())
    tracker = RivalTracker(field, occupancy.free, walls.temperature, pimm.config.rivals)
    while len(stages.get("total", [])) < repeats:
        estimate = pimm.update(obs)
        if "walls" in estimate.inside:  # the wall points it weighed: the scans its rival check keeps
            tracker.add_scan(np.asarray(obs["odom"], dtype=float), estimate.inside["walls"])
        all_updates_ms += estimate.timings["total"]
        if "segmentation" in estimate.timings:
            for stage, ms in estimate.timings.items():
                stages.setdefault(stage, []).append(ms)
        obs, _, _, _, info = env.step(action)
        scans += bool(info["fresh_cloud"])
    env.close()
    figures["pimm_pipeline_ms"] = float(np.median(stages.pop("total")))
    # what the thesis's network stands for in an update: the scan's perception (labels, corners, retrieval),
    # without the filter's weighing and its rival and twin checks
    perception = [sum(stages[s][k] for s in PERCEPTION_STAGES) for k in range(len(stages["segmentation"]))]
    figures["pimm_perception_ms"] = float(np.median(perception))
    # where that time goes: each stage's median over the same updates
    figures.update({f"pimm_stage_{stage}_ms": float(np.median(ms)) for stage, ms in sorted(stages.items())})
    # PIMM perceives a scan only when it weighs with it (docs/design.md): its cost per scan that arrived
    figures["pimm_per_scan_ms"] = all_updates_ms / scans
    figures["pimm_scans_perceived_share"] = repeats / scans
    figures.update(rival_evidence_benchmark(tracker, np.asarray(obs["odom"], dtype=float), repeats))
    return figures


def rival_evidence_benchmark(tracker: RivalTracker, odom: np.ndarray, repeats: int) -> dict[str, float]:
    """The rival check's evidence of 30 poses over the scans ``tracker`` kept: compiled (as PIMM runs it) and
    as the NumPy expression it replaced (the measurement behind the compiled loop, docs/design.md)."""
    stack = tracker.stack(odom)
    rng = np.random.default_rng(0)
    poses = np.column_stack([rng.normal(-10.0, 0.5, (30, 2)), rng.uniform(-np.pi, np.pi, 30)])
    return {
        "rival_evidence_ms": median_ms(lambda: tracker.evidence(poses, stack), repeats),
        "rival_evidence_numpy_ms": median_ms(lambda: numpy_scan_evidence(tracker, poses, stack), repeats),
        "rival_evidence_points": float(len(stack.points) * len(poses)),
    }


def numpy_scan_evidence(tracker: RivalTracker, poses: np.ndarray, stack: ScanStack) -> np.ndarray:
    """``tracker.evidence`` as NumPy arrays of every (pose, point) pair: what the compiled loop replaced."""
    k, m = len(poses), stack.motions
    c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
    tx, ty = poses[:, 0:1] + c * m[:, 0] - s * m[:, 1], poses[:, 1:2] + s * m[:, 0] + c * m[:, 1]
    heading = poses[:, 2:3] + m[:, 2]
    of = stack.scan_of
    ca, sa = np.cos(heading)[:, of], np.sin(heading)[:, of]
    x = tx[:, of] + ca * stack.points[:, 0] - sa * stack.points[:, 1]
    y = ty[:, of] + sa * stack.points[:, 0] + ca * stack.points[:, 1]
    grid = tracker.field.grid
    rows, cols, valid = grid.cells_of(np.column_stack([x.ravel(), y.ravel()]))
    log_pz = np.where(valid, tracker.log_pz[np.where(valid, rows, 0), np.where(valid, cols, 0)], tracker.log_pz_off)
    rows, cols, on_map = grid.cells_of(np.column_stack([tx.ravel(), ty.ravel()]))
    free = on_map & tracker.free[np.where(on_map, rows, 0), np.where(on_map, cols, 0)]
    outside = (~free).reshape(k, -1).sum(axis=1)
    return tracker.temperature * log_pz.reshape(k, -1).sum(axis=1) + np.log(0.1) * outside


def converged_update_benchmark(filt: FeatureFilter, features: np.ndarray, repeats: int) -> dict[str, float]:
    """The measurement update of a copy of ``filt`` (KLD-sampling, as by default) once it has converged:
    particles about one pose (0.1 m, 3 deg), resampled so that KLD's bound shrinks the set, then one injection's
    worth added (as after every informed update). Also the set's size then."""
    adaptive = copy.copy(filt)  # the same maps; reset gives the copy its own particles and weights
    adaptive.config = replace(filt.config, thesis=False)
    adaptive.reset(np.random.default_rng(0), np.array([-10.0, 4.2, 0.0]), np.diag([0.01, 0.01, 0.003]))
    adaptive.ess = 1.0  # taken as degenerate: the resampling draws from particles 0.1 m about the pose, few bins
    adaptive.resample_if_degenerate()
    adaptive.inject(np.zeros((0, 2)))
    return {
        "pf_update_converged_ms": measurement_update_ms(adaptive, features, repeats),
        "pf_converged_particles": float(len(adaptive.particles)),
    }


def measurement_update_ms(filt: FeatureFilter, features: np.ndarray, repeats: int) -> float:
    """Median ms of ``filt``'s measurement update with ``features``, each time from its present weights."""
    weights = filt.weights.copy()

    def measurement() -> None:
        filt.weights = weights.copy()
        filt.measurement_update(features)

    return median_ms(measurement, repeats)


def perception_benchmarks(repeats: int) -> dict[str, float]:
    """Segmentation + descriptor of one scan, and one fingerprint-map query, with the shipped iilab files."""
    from pimm_agents.perception.files import SHIPPED_CLOUD_WEIGHTS, load_perception
    from pimm_agents.perception.segmenter import CloudSegmenter
    from pimm_env.envs.iilab_env import IILabEnv

    segmenter, fingerprints = load_perception("iilab")
    env = IILabEnv()
    obs, _ = env.reset(seed=3)
    env.close()
    cloud, mask = obs["cloud"], obs["cloud_mask"]
    descriptor = segmenter.segment(cloud, mask).descriptor
    figures = {
        "segmentation_ms": median_ms(lambda: segmenter.segment(cloud, mask), repeats),
        "fingerprint_query_ms": median_ms(lambda: fingerprints.query(descriptor), repeats),
    }
    if SHIPPED_CLOUD_WEIGHTS.is_file():  # the layout-free network on the same scan
        cloud_segmenter = CloudSegmenter(SHIPPED_CLOUD_WEIGHTS)
        figures["cloud_segmentation_ms"] = median_ms(lambda: cloud_segmenter.segment(cloud, mask), repeats)
    return figures


def corners_benchmark(repeats: int) -> float:
    """Median corner-detection time per scan (true labels) over scans at random free poses, each scan's time the
    median of three (the first call, which loads the compiled code, is not timed)."""
    from pimm_agents.corners.detector import detect_corners
    from pimm_agents.measurement.corner_quality import collect_scans

    scans = collect_scans("iilab", max(10, repeats // 2), seed=7)
    detect_corners(*scans[0].corner_input()[:2])
    times = []
    for scan in scans:
        points, labels, _, _ = scan.corner_input()

        def detect(p: np.ndarray = points, lab: np.ndarray = labels) -> object:
            return detect_corners(p, lab)

        times.append(median_ms(detect, 3))
    return float(np.median(times))


def amcl_benchmarks(repeats: int) -> dict[str, float]:
    """AMCL's measurement update (2 000 particles x 60 beams, the stage the thesis timed) and a whole
    filter update (motion, measurement, KLD resampling, cluster estimate) from a global start; the
    measurement update of nav2's beam and likelihood_field_prob models, and the time to cast the beam model's
    range table."""
    from pimm_agents.amcl.localizer import Amcl
    from pimm_agents.factory import make_localizer
    from pimm_env.envs.iilab_env import IILabEnv

    env = IILabEnv(terminate_on_collision=False)
    obs, _ = env.reset(seed=0, options={"pose": [-18.5, 14.0, 1.5708]})
    env.close()
    amcl = make_localizer("amcl")
    assert isinstance(amcl, Amcl)
    amcl.reset(seed=0)
    scan = np.asarray(obs["scan"], dtype=float)
    figures = {"amcl_update_ms": median_ms(lambda: amcl.measurement_update(scan), repeats)}
    assert amcl.particle_count == amcl.config.max_particles == 2000

    particles, weights = amcl.particles.copy(), amcl.weights.copy()

    def whole_update() -> None:
        amcl.particles, amcl.weights = particles.copy(), weights.copy()
        amcl.filter_update(np.zeros(3), scan, (0.0, 0.3, 0.0), {})

    figures["amcl_filter_update_ms"] = median_ms(whole_update, max(5, repeats // 3))
    # nav2's other laser models, the same 2 000 particles x 60 beams from a global start
    for name, key in (("amcl-beam", "amcl_beam_update_ms"), ("amcl-lfp", "amcl_lfp_update_ms")):
        began = time.perf_counter()
        other = make_localizer(name)
        if name == "amcl-beam":  # its range table is cast once per map and process
            figures["amcl_beam_table_s"] = time.perf_counter() - began
        assert isinstance(other, Amcl)
        other.reset(seed=0)
        figures[key] = median_ms(partial(other.measurement_update, scan), max(5, repeats // 3))
    return figures
