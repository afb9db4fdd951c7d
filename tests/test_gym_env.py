"""The Gymnasium environment palpate/Explore-v0: passes gymnasium's checker, seeded episodes repeat, rewards add up
to the map's accuracy gain (or entropy fall), the stop rule terminates and the budget truncates, the offline press
model draws from the memory's Gaussians, the vector form steps together, and the example script runs."""

from __future__ import annotations

import runpy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")
pytest.importorskip("mujoco")

from gymnasium.utils.env_checker import check_env  # noqa: E402

import palpate  # noqa: E402
import palpate.gym  # noqa: E402, F401
from palpate.core.errors import ValidationError  # noqa: E402
from palpate.core.session.explore_env import ENV_ID, ExploreEnv, train_env_memory  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def memory():
    return train_env_memory("explore_info_gain")


def _episode(env, seed, actions):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        out.append((obs, r, term, trunc))
    return out


def test_importing_palpate_does_not_import_gymnasium():
    code = "import sys, palpate; palpate.load_scenario('sweeps/tiny_base'); print('gymnasium' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_the_registered_environment_passes_gymnasiums_checker(memory):
    env = gym.make(ENV_ID, memory=memory)
    check_env(env.unwrapped, skip_render_check=True)
    nx, ny = env.unwrapped.geometry.plane_shape
    assert env.action_space.n == nx * ny
    assert env.observation_space["probabilities"].shape == (ny, nx, 3)
    # "module:id" imports the module that registers the id
    assert isinstance(gym.make("palpate.gym:" + ENV_ID, memory=memory).unwrapped, ExploreEnv)


def test_a_seed_gives_the_same_episode_and_another_seed_another(memory):
    env = ExploreEnv(memory=memory)
    actions = [0, 14, 14, 50, 95]
    a, b, c = _episode(env, 7, actions), _episode(env, 7, actions), _episode(env, 8, actions)
    for x, y in zip(a[1:], b[1:], strict=True):
        assert x[1] == y[1] and all(np.array_equal(x[0][k], y[0][k]) for k in x[0])
    assert not np.array_equal(a[1][0]["features"], c[1][0]["features"])


def test_accuracy_rewards_add_up_to_the_maps_accuracy_gain(memory):
    env = ExploreEnv(memory=memory, budget=30)
    _, info0 = env.reset(seed=1)
    rng = np.random.default_rng(0)
    total = 0.0
    for _ in range(30):
        _, r, term, trunc, info = env.step(int(rng.integers(env.action_space.n)))
        total += r
        if term or trunc:
            break
    assert info0["accuracy"] == 0.0  # the untouched map decides no cell
    assert total == pytest.approx(info["accuracy"] - info0["accuracy"], abs=1e-12)
    assert info["accuracy"] > 0.3


def test_entropy_rewards_add_up_to_the_fall_of_the_mean_entropy(memory):
    env = ExploreEnv(memory=memory, reward="entropy", budget=10)
    _, info0 = env.reset(seed=2)
    assert info0["mean_entropy"] == pytest.approx(np.log10(3))  # three materials, all equally likely
    total = sum(env.step(a)[1] for a in (5, 17, 40, 41, 90))
    info = env._info()
    assert total == pytest.approx(info0["mean_entropy"] - info["mean_entropy"], abs=1e-9)
    assert total > 0


def test_the_stop_rule_terminates_and_the_budget_truncates(memory):
    env = ExploreEnv(memory=memory, stop_mean_entropy=0.47, budget=50)  # log10(3) = 0.477: one press is enough
    env.reset(seed=0)
    _, _, term, trunc, info = env.step(20)
    assert term and not trunc and info["stop"] == "mean_entropy"
    env = ExploreEnv(memory=memory, budget=2)
    env.reset(seed=0)
    assert env.step(0)[2:4] == (False, False)
    _, _, term, trunc, info = env.step(1)
    assert (term, trunc, info["stop"]) == (False, True, "budget")


def test_offline_presses_draw_from_the_memorys_gaussians_of_the_true_material(memory):
    env = ExploreEnv(memory=memory, budget=400)
    env.reset(seed=3)
    nx = env.geometry.plane_shape[0]
    ix, iy = 2, 1  # the hard lump
    t = int(env.truth[iy, ix])
    feats = np.array([env.step(ix + nx * iy)[0]["features"] for _ in range(400)], dtype=float)
    mean = np.concatenate([memory.means_N[t], memory.means_A[t]])
    sd = np.sqrt(np.concatenate([np.diag(memory.covs_N[t]), np.diag(memory.covs_A[t])]))
    # the sample mean of 400 draws lies within 4 standard errors of the Gaussian's mean
    assert np.all(np.abs(feats.mean(axis=0) - mean) < 4 * sd / np.sqrt(400))


def test_the_simulated_press_model_presses_the_object(memory):
    env = ExploreEnv(press_model="sim", memory=memory, budget=2)
    obs, _ = env.reset(seed=0)
    obs, _, _, _, info = env.step(0)
    assert info["k"] == 1 and obs["explored"][0, 0] == 1
    assert np.all(np.isfinite(obs["features"])) and np.any(obs["features"] != 0)


def test_bad_arguments_and_actions_are_refused(memory):
    with pytest.raises(ValidationError, match="press_model"):
        ExploreEnv(memory=memory, press_model="fast")
    with pytest.raises(ValidationError, match="object 'Nope'"):
        ExploreEnv(memory=memory, object="Nope")
    with pytest.raises(ValidationError, match=r"exploration.map = 'voxel'.*2-D maps"):
        ExploreEnv("volumetric", memory=memory)
    env = ExploreEnv(memory=memory)
    with pytest.raises(ValidationError, match="reset"):
        env.step(0)
    env.reset(seed=0)
    with pytest.raises(ValidationError, match="cell index"):
        env.step(env.action_space.n)


def test_the_vector_form_steps_its_environments_together(memory):
    envs = gym.make_vec(ENV_ID, num_envs=3, memory=memory, budget=4)
    obs, _ = envs.reset(seed=11)
    assert obs["probabilities"].shape[0] == 3
    obs, reward, term, trunc, info = envs.step(np.array([0, 1, 2]))
    assert reward.shape == (3,) and obs["explored"].reshape(3, -1)[np.arange(3), [0, 1, 2]].all()
    envs.close()


def test_the_vector_form_presses_in_one_batch_and_steps_as_a_loop_would(memory, monkeypatch):
    from palpate.core.session.explore_env import ExploreVectorEnv
    from palpate.core.session.sources import scenario_source_maker
    from palpate.sim.source import SimSource

    sc = palpate.load_scenario("explore_info_gain")
    maker = scenario_source_maker(sc, sc.training.source)  # one law cache: each law is solved once for both
    actions = [np.array([0, 7, 7]), np.array([13, 2, 40]), np.array([5, 5, 1])]  # budget 2: the third step resets

    def episode(vector):
        envs = vector([lambda: ExploreEnv(sc, memory=memory, press_model="sim", budget=2, source_maker=maker)
                       for _ in range(3)])
        out = [envs.reset(seed=4)[0]]
        out += [envs.step(a)[:4] for a in actions]
        envs.close()
        return out

    loop = episode(gym.vector.SyncVectorEnv)
    batches = []
    press_across = SimSource.press_across
    monkeypatch.setattr(SimSource, "press_across", staticmethod(lambda pairs: batches.append(len(pairs))
                                                                 or press_across(pairs)))
    batched = episode(ExploreVectorEnv)
    assert batches == [3, 3]  # every environment's press of a step in one batch; none while they reset
    for a, b in zip(loop, batched, strict=True):
        a, b = (a, b) if isinstance(a, tuple) else ((a,), (b,))
        for x, y in zip(a, b, strict=True):
            if isinstance(x, dict):
                assert all(np.array_equal(x[k], y[k]) for k in x)
            else:
                np.testing.assert_array_equal(x, y)
    assert np.any(loop[1][0]["features"] != 0)  # the presses were perceived and fitted


def test_the_vector_form_takes_gymnasiums_autoreset_modes_and_still_steps_as_a_loop_would(memory):
    same_step = gym.vector.AutoresetMode.SAME_STEP
    actions = [np.array([0, 7]), np.array([13, 2]), np.array([5, 1])]  # budget 2: each resets within a step
    loop = gym.vector.SyncVectorEnv([lambda: ExploreEnv(memory=memory, press_model="sim", budget=2)
                                     for _ in range(2)], autoreset_mode=same_step)
    batched = gym.make_vec(ENV_ID, num_envs=2, memory=memory, press_model="sim", budget=2, autoreset_mode=same_step)
    runs = []
    for envs in (loop, batched):
        assert envs.autoreset_mode == same_step
        envs.reset(seed=2)
        runs.append([envs.step(a)[:4] for a in actions])
        envs.close()
    for a, b in zip(*runs, strict=True):
        assert all(np.array_equal(a[0][k], b[0][k]) for k in a[0])
        for x, y in zip(a[1:], b[1:], strict=True):
            np.testing.assert_array_equal(x, y)
    assert runs[1][1][3].all()  # the budget truncated both environments on the second step


def test_the_example_script_evaluates_heuristic_policies():
    results = runpy.run_path(str(ROOT / "docs" / "gym_example.py"))["main"](["--episodes", "1", "--vector", "2"])
    assert set(results) == {"random", "raster", "max_entropy", "vector_max_entropy"}
    for r in results.values():
        assert np.isfinite(r["return"])
    # the least-sure cell first covers the block better than a raster in the same budget
    assert results["max_entropy"]["accuracy"] > results["raster"]["accuracy"]
