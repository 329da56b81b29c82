"""pimm/ActiveLocalization-v0: spaces, checkers, determinism, the forward guard and the belief features."""

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import pimm_env  # noqa: F401  (registers the envs)
from pimm_agents.active.env import ActiveConfig, belief_features, scan_sectors, weight_near
from pimm_agents.active.primitives import blocked_ahead
from pimm_agents.localizer import Hypothesis, PoseEstimate
from pimm_env.errors import EnvError, ExperimentError

ROOT = Path(__file__).resolve().parents[1]


def _estimate(*hypotheses: tuple[float, float, float, float], status: str = "ambiguous") -> PoseEstimate:
    hs = tuple(Hypothesis(x, y, t, w, np.diag([0.04, 0.04, 0.01])) for x, y, t, w in hypotheses)
    x, y, t, _ = hypotheses[0]
    return PoseEstimate(x, y, t, np.diag([0.04, 0.04, 0.01]), status=status, hypotheses=hs)


def test_belief_features_are_relative_to_the_estimate_and_bounded():
    est = _estimate((2.0, 1.0, np.pi / 2, 0.7), (2.0, 4.0, np.pi / 2, 0.3), (100.0, 1.0, 0.0, 0.0))
    f = belief_features(est, k=4, max_offset=30.0)
    assert f.shape == (4, 6) and np.all(np.abs(f) <= 1.0)
    assert f[0, :2] == pytest.approx([0.0, 0.0]) and f[0, 4] == pytest.approx(0.7)
    # 3 m along +y of the map is straight ahead of an estimate facing +y
    assert f[1, :2] == pytest.approx([3.0 / 30.0, 0.0], abs=1e-6) and f[1, 4] == pytest.approx(0.3)
    assert f[2, 0] == pytest.approx(0.0, abs=1e-6) and f[2, 1] == pytest.approx(-1.0)  # 98 m off: clipped
    assert not f[3].any()  # fewer hypotheses than K: zero rows
    assert not belief_features(None, 4, 30.0).any()


def test_weight_near_the_truth():
    est = _estimate((0.0, 0.0, 0.0, 0.75), (5.0, 0.0, 0.0, 0.25))
    assert weight_near(est, np.array([5.2, 0.1, 0.05])) == pytest.approx(0.25)
    assert weight_near(est, np.array([0.0, 0.0, np.pi])) == 0.0


def test_scan_sectors_keep_the_nearest_return():
    scan = np.full(360, 20.0)
    scan[100] = 1.0
    sectors = scan_sectors(scan, 60, 20.0)
    assert sectors.shape == (60,) and sectors[16] == pytest.approx(0.05) and sectors[0] == 1.0


def test_the_forward_guard_looks_ahead_and_along_the_bodys_lane_only():
    bearings = np.radians(np.arange(360) - 180.0)
    scan = np.full(360, 10.0)
    scan[180 + 90] = 0.2  # something at the robot's left
    assert not blocked_ahead(scan, bearings)
    scan[180 + 40] = 1.0  # a doorway's edge 40 deg off, a metre away: the body passes it by 0.64 m
    assert not blocked_ahead(scan, bearings)
    scan[180 + 40] = 0.45  # the same 0.45 m away, out of the cone but 0.29 m beside the lane: the body grazes it
    assert blocked_ahead(scan, bearings)
    scan[180 + 40] = 10.0
    scan[180 + 10] = 0.3  # something 10 deg off straight ahead
    assert blocked_ahead(scan, bearings)


def test_a_blocked_forward_stands_still_for_its_second():
    from types import SimpleNamespace

    from pimm_agents.active.primitives import PRIMITIVES, drive

    class Sim:  # the control steps' commands; a wall 0.3 m ahead all along
        def __init__(self) -> None:
            self.unwrapped = SimpleNamespace(config=SimpleNamespace(robot=SimpleNamespace(control_dt=0.032)))
            self.commands: list[np.ndarray] = []

        def step(self, command: np.ndarray):
            self.commands.append(command)
            return {"scan": np.full(360, 0.3)}, 0.0, False, False, {"collision": False}

    sim, bearings = Sim(), np.radians(np.arange(360) - 180.0)
    _, _, steps, stopped = drive(sim, PRIMITIVES[0], {"scan": np.full(360, 0.3)}, lambda o, i: False, bearings)
    assert stopped and steps == len(sim.commands) == 31  # the clock runs: a policy cannot stall an episode
    assert not np.any(sim.commands)


def test_config_values_are_checked():
    with pytest.raises(EnvError, match="hypotheses"):
        ActiveConfig(hypotheses=0)


@pytest.mark.expensive
def test_the_env_passes_both_checkers_and_repeats_per_seed():
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make("pimm/ActiveLocalization-v0", world="iilab", localizer="amcl")
    check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=False)
    runs = []
    for _ in range(2):
        obs, _ = env.reset(seed=7)
        trace = [obs["hypotheses"].copy()]
        for action in (0, 1, 0, 2):
            obs, reward, *_ = env.step(action)
            trace += [obs["hypotheses"].copy(), obs["scan"].copy(), np.array([reward])]
        runs.append(trace)
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a, b)
    for bad in (5, 1.7, -1, "1"):  # 1.7 is not primitive 1; a string is no action
        with pytest.raises(EnvError, match=r"action .*: must be one of 0..2"):
            env.step(bad)
    env.step(np.int64(1))  # whole numbers of any type are actions
    with pytest.raises(EnvError, match="reset option 'kidnap' is True or False, got 'false'"):
        env.reset(options={"kidnap": "false"})
    env.close()


def test_evaluate_active_prints_and_writes_the_policies_figures(tmp_path):
    import json

    from typer.testing import CliRunner

    import evaluate

    args = ["active", "--localizer", "amcl", "--policy", "random", "--policy", "greedy", "--limit-s", "3", "--json"]
    result = CliRunner().invoke(evaluate.app, [*args, "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    printed = json.loads(result.output)
    policies = printed["policies"]
    written = json.loads((Path(printed["folder"]) / "summary.json").read_text())
    assert written["policies"] == policies and written["worlds"]["iilab"] == policies  # one world: the same
    assert len(written["episodes"]) == 6 and written["record"]["commit"]
    assert set(policies) == {"random", "greedy"}
    for row in policies.values():
        assert set(row) == {
            "episodes",
            "success_rate",
            "median_time_s",
            "p90_time_s",
            "distance_m",
            "collisions",
            "false_localized_s",
        }
        assert row["episodes"] == 3 and 0.0 <= row["success_rate"] <= 1.0  # the iiLab's three routes' starts
    bad = CliRunner().invoke(evaluate.app, ["active", "--policy", "clever", "--localizer", "amcl", "--limit-s", "1"])
    assert bad.exit_code != 0 and "policy 'clever'" in bad.output


@pytest.mark.expensive
def test_policy_training_repeats_per_seed(tmp_path):
    import torch
    from stable_baselines3 import PPO

    from training.policy import train_policy

    paths = [train_policy(["iilab"], 32, tmp_path / f"p{k}.zip", seed=3, localizer="amcl") for k in range(2)]
    a, b = (PPO.load(str(p), device="cpu").policy.state_dict() for p in paths)
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert (tmp_path / "p0_log" / "progress.csv").is_file() and (tmp_path / "p0.json").is_file()
    import json

    # the record's command names each world with its own --world, as the command line takes them
    assert json.loads((tmp_path / "p0.json").read_text())["reproduce"].endswith("--localizer amcl --world iilab")


@pytest.mark.expensive
def test_policy_training_on_ray_writes_the_policy_of_local_workers(tmp_path):
    """The recipe's steps (imitation with the critic, then PPO) over two envs: Ray actors or worker processes,
    the same weights to the bit."""
    pytest.importorskip("ray")
    import json

    import torch
    from stable_baselines3 import PPO

    from training.policy import train_policy

    def train(name: str, **backend: str) -> dict:
        path = train_policy(
            ["iilab"], 32, tmp_path / name, seed=5, localizer="amcl", workers=2, imitate=32, critic=True, **backend
        )
        return PPO.load(str(path), device="cpu").policy.state_dict()

    local, on_ray = train("local.zip"), train("ray.zip", backend="ray")
    assert all(torch.equal(local[k], on_ray[k]) for k in local)
    assert " --backend ray" in json.loads((tmp_path / "ray.json").read_text())["reproduce"]
    with pytest.raises(ExperimentError, match="local or ray"):
        train_policy(["iilab"], 32, tmp_path / "x.zip", localizer="amcl", backend="slurm")


@pytest.mark.expensive
def test_dagger_fits_the_network_to_greedy_where_the_network_itself_drives(tmp_path):
    import json

    from training.policy import train_policy

    train_policy(["iilab"], 16, tmp_path / "p.zip", seed=3, localizer="amcl", imitate=64, dagger=64)
    record = json.loads((tmp_path / "p.json").read_text())
    fit = record["imitation"]
    assert fit["dagger_steps"] == 64 and record["dagger"] == 64
    # on the states its own driving led to, the refit follows greedy far better than the first fit did
    assert fit["dagger_agreement"] > fit["dagger_agreement_before"] + 0.3
    assert " --imitate 64 --dagger 64 --seed 3 " in record["reproduce"]


def test_dagger_and_critic_need_the_imitation_they_start_from(tmp_path):
    from training.policy import train_policy

    with pytest.raises(EnvError, match="--imitate"):
        train_policy(["iilab"], 16, tmp_path / "p.zip", localizer="amcl", dagger=64)
    with pytest.raises(EnvError, match="--imitate"):
        train_policy(["iilab"], 16, tmp_path / "p.zip", localizer="amcl", critic=True)


def test_returns_are_discounted_to_each_episodes_end_and_unknown_for_a_running_one():
    from training.policy import discounted_returns

    rewards = np.array([[1.0, 0.0], [2.0, 1.0], [4.0, 1.0]])  # three steps of two envs
    ended = np.array([[False, False], [True, False], [False, False]])  # env 0's first episode ends at step 1
    returns = discounted_returns(rewards, ended, 0.5)
    assert returns[:, 0][:2].tolist() == [2.0, 2.0] and np.isnan(returns[2, 0])  # 1 + 0.5 x 2; then running
    assert np.isnan(returns[:, 1]).all()  # env 1's only episode never ended
    ended[2] = True
    assert discounted_returns(rewards, ended, 0.5)[:, 1].tolist() == [0.75, 1.5, 1.0]


def test_the_imitation_fits_the_critic_to_the_returns_and_leaves_the_actor_as_it_was():
    import torch
    from stable_baselines3.common.policies import MultiInputActorCriticPolicy

    from training.policy import explained_variance, fit_to

    env = gym.make("pimm/ActiveLocalization-v0", world="iilab", localizer="amcl")
    env.observation_space.seed(0)
    observations = [env.observation_space.sample() for _ in range(2048)]
    env.close()
    rng = np.random.default_rng(0)
    actions = rng.integers(3, size=2048).tolist()
    returns = np.array([10.0 * o["status"][0] - 5.0 for o in observations])  # a return the input shows
    returns[:16] = np.nan  # steps of an episode that had not ended: left out
    fitted = []
    for with_returns in (False, True):
        torch.manual_seed(0)
        policy = MultiInputActorCriticPolicy(env.observation_space, env.action_space, lambda _: 3e-4)
        fit_to(policy, observations, actions, torch.Generator().manual_seed(1), returns if with_returns else None)
        fitted.append(policy)
    untrained, trained = (explained_variance(p, observations, returns) for p in fitted)
    assert trained > 0.8 and untrained < 0.2
    actor = [k for k in fitted[0].state_dict() if "value" not in k]  # the value head and its own layers
    assert all(torch.equal(fitted[0].state_dict()[k], fitted[1].state_dict()[k]) for k in actor)
    assert any(not torch.equal(fitted[0].state_dict()[k], fitted[1].state_dict()[k]) for k in fitted[0].state_dict())


def test_active_episodes_in_worker_processes_are_those_run_here():
    from pimm_agents.experiments.active_episodes import evaluate_active

    here = evaluate_active("iilab", ["random", "greedy"], 1, 4, "amcl", limit_s=3.0)
    pooled = evaluate_active("iilab", ["random", "greedy"], 1, 4, "amcl", limit_s=3.0, workers=2)
    assert pooled["episodes"] == here["episodes"] and len(here["episodes"]) == 6
    assert pooled["policies"] == here["policies"]


def test_training_envs_draw_every_building_and_repeat_per_seed():
    from training.policy import WorldCycle

    def drawn(seed: int) -> list[str]:
        env = WorldCycle(["iilab", str(ROOT / "maps" / "iilab" / "world.yaml")], "amcl")  # two names, two envs
        env.reset(seed=seed)
        picks = [env.current]
        for _ in range(7):
            env.reset()
            picks.append(env.current)
        names = [next(w for w, e in env._envs.items() if e is p) for p in picks]
        env.close()
        return names

    first = drawn(5)
    assert len(set(first)) == 2  # both within 8 episodes
    assert drawn(5) == first


@pytest.mark.expensive
def test_a_checkpoint_is_the_policy_a_shorter_run_would_have_written(tmp_path):
    import torch
    from stable_baselines3 import PPO

    from training.policy import train_policy

    train_policy(["iilab"], 1024, tmp_path / "full.zip", seed=3, localizer="amcl")
    short = train_policy(["iilab"], 512, tmp_path / "short.zip", seed=3, localizer="amcl")
    a = PPO.load(str(tmp_path / "full_log" / "checkpoints" / "full_512_steps.zip"), device="cpu").policy.state_dict()
    b = PPO.load(str(short), device="cpu").policy.state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert (tmp_path / "full_log" / "progress.png").is_file()  # the learning curve, drawn at the end


def test_explore_and_last_action_are_the_memory_greedy_keeps_itself():
    from pimm_agents.active.explorer import Explorer

    env = gym.make("pimm/ActiveLocalization-v0", world="iilab", localizer="amcl")
    obs, _ = env.reset(seed=3)
    assert not obs["last_action"].any()  # nothing driven yet
    own = Explorer(env.unwrapped.scan_range)  # what greedy keeps for itself, fed the same observations
    assert obs["explore"].argmax() == own(obs) and obs["explore"].sum() == 1.0
    for action in (1, 1, 0, 2, 0, 0, 1):
        obs, *_ = env.step(action)
        assert obs["last_action"].argmax() == action and obs["last_action"].sum() == 1.0
        assert obs["explore"].argmax() == own(obs)
    # a new episode starts a new memory: the explorer's faced directions and the last action are forgotten
    obs, _ = env.reset(seed=3)
    assert not obs["last_action"].any()
    assert env.unwrapped.explorer.faced.keys() == {env.unwrapped.explorer.last_faced}
    env.close()


def test_the_shipped_policy_loads_with_its_record_and_acts_on_the_envs_observations():
    import json

    from pimm_agents.active.policies import SHIPPED_POLICY, make_policy

    record = json.loads(SHIPPED_POLICY.with_suffix(".json").read_text())
    assert record["algo"] == "ppo" and "python -m training policy" in record["reproduce"]
    env = gym.make("pimm/ActiveLocalization-v0", localizer="amcl")
    obs, _ = env.reset(seed=2)
    policy = make_policy("trained")
    assert policy.name == "trained"
    for _ in range(3):
        action = policy(obs)
        assert action in (0, 1, 2)
        obs, *_ = env.step(action)
    env.close()


def test_a_trained_policy_never_drives_into_a_blocked_way():
    import torch

    from pimm_agents.active.policies import make_policy
    from pimm_agents.active.primitives import FORWARD

    env = gym.make("pimm/ActiveLocalization-v0", localizer="amcl")
    obs, _ = env.reset(seed=2)
    policy = make_policy("trained", env.unwrapped.scan_range)
    with torch.no_grad():  # a network that prefers forward whatever it sees
        policy.model.policy.action_net.bias[FORWARD] += 100.0
    clear = {**obs, "scan": np.ones_like(obs["scan"])}
    assert policy(clear) == FORWARD
    walled = {**obs, "scan": np.full_like(obs["scan"], 0.3 / env.unwrapped.scan_range)}  # 0.3 m all round
    turn = policy(walled)
    assert turn != FORWARD and turn == policy.likeliest({k: walled[k] for k in policy.keys}, exclude=FORWARD)
    env.close()


def box_scan(pose: tuple[float, float, float], size: tuple[float, float], bearings: np.ndarray) -> np.ndarray:
    """The ranges from ``pose`` (x, y, heading) to the walls of the room [0, size[0]] x [0, size[1]]."""
    x, y, heading = pose
    a = heading + bearings
    c, s = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (size[0] - x) / c, np.where(c < 0, -x / c, np.inf))
        ty = np.where(s > 0, (size[1] - y) / s, np.where(s < 0, -y / s, np.inf))
    return np.minimum(tx, ty)


def test_a_turn_squares_the_robot_up_with_the_walls_it_sees():
    from pimm_agents.active.primitives import squared_turn, wall_axis

    bearings = np.radians(np.arange(360) - 180.0)
    rng = np.random.default_rng(0)
    for heading_deg in (38.0, -7.0, 0.0, 84.0):
        scan = box_scan((2.0, 1.5, np.radians(heading_deg)), (6.0, 4.0), bearings) + rng.normal(0, 0.01, 360)
        axis = wall_axis(scan, bearings)
        # the walls run along the map's axes: in the robot's frame at -heading, modulo 90 deg
        assert axis is not None and abs(np.degrees(axis) - ((-heading_deg + 45) % 90 - 45)) < 0.5
        for turn in (np.pi / 4, -np.pi / 4):
            after = heading_deg + np.degrees(squared_turn(turn, scan, bearings))
            # a multiple of 45 deg from the walls, about 45 deg (22.5-67.5) from where it was
            assert min(after % 45, 45 - after % 45) < 0.5 and 22.4 < abs(after - heading_deg) < 67.6
    # a round room has no wall direction: the turn is the plain 45 deg
    round_room = np.full(360, 3.0) + rng.normal(0, 0.01, 360)
    assert wall_axis(round_room, bearings) is None
    assert squared_turn(np.pi / 4, round_room, bearings) == np.pi / 4
