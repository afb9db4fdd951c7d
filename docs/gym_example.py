"""Evaluate heuristic exploration policies through palpate's Gymnasium environment (``palpate/Explore-v0``).

Three policies press cells of the explore_info_gain block with the offline press model (presses drawn from the
trained memory's Gaussians) over a few seeded episodes, and the script prints each one's mean return (the gain in
the post-processed map's accuracy), final accuracy and presses per episode:

- ``random``: a uniformly drawn unpressed cell;
- ``raster``: the next unpressed cell in row order;
- ``max_entropy``: the unpressed cell whose post-processed probabilities are least sure (highest entropy), ties
  broken by the lowest index.

Run: ``python docs/gym_example.py [--episodes N] [--vector N]`` (the ``gym`` and ``sim`` extras; a few seconds,
most of it training the memory on simulated presses once). ``--vector`` steps N environments together through
``gymnasium.make_vec`` (a SyncVectorEnv: palpate has no batched press, so the presses run one after another).
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import palpate.gym  # noqa: F401  (registers palpate/Explore-v0)
from palpate.core.session.explore_env import train_env_memory


def random_policy(obs, rng) -> int:
    free = np.flatnonzero(obs["explored"].ravel() == 0)
    return int(rng.choice(free)) if len(free) else int(rng.integers(obs["explored"].size))


def raster_policy(obs, rng) -> int:
    free = np.flatnonzero(obs["explored"].ravel() == 0)
    return int(free[0]) if len(free) else 0


def max_entropy_policy(obs, rng) -> int:
    p = obs["probabilities"].reshape(-1, obs["probabilities"].shape[-1]).astype(float)
    h = -np.sum(p * np.log(np.clip(p, 1e-12, None)), axis=1)
    h[obs["explored"].ravel() == 1] = -np.inf
    return int(np.argmax(h))


POLICIES = {"random": random_policy, "raster": raster_policy, "max_entropy": max_entropy_policy}


def evaluate(policy, memory, episodes: int, seed: int = 0) -> dict:
    """Mean return, final accuracy and presses of ``policy`` over seeded episodes (episode i: reset(seed + i))."""
    env = gym.make("palpate/Explore-v0", memory=memory)
    rng = np.random.default_rng(seed)
    returns, accuracies, presses = [], [], []
    for i in range(episodes):
        obs, info = env.reset(seed=seed + i)
        total, done = 0.0, False
        while not done:
            obs, reward, terminated, truncated, info = env.step(policy(obs, rng))
            total += reward
            done = terminated or truncated
        returns.append(total)
        accuracies.append(info["accuracy"])
        presses.append(info["k"])
    env.close()
    return {"return": float(np.mean(returns)), "accuracy": float(np.mean(accuracies)),
            "presses": float(np.mean(presses))}


def evaluate_vector(policy, memory, num_envs: int, seed: int = 0) -> float:
    """Mean return of one episode per environment of a vector, stepped together."""
    envs = gym.make_vec("palpate/Explore-v0", num_envs=num_envs, memory=memory)
    rng = np.random.default_rng(seed)
    obs, _ = envs.reset(seed=seed)
    totals, done = np.zeros(num_envs), np.zeros(num_envs, bool)
    while not done.all():
        actions = np.array([policy({k: v[j] for k, v in obs.items()}, rng) for j in range(num_envs)])
        obs, reward, terminated, truncated, _ = envs.step(actions)
        totals += np.where(done, 0.0, reward)  # an environment that finished resets itself: ignore its next one
        done |= terminated | truncated
    envs.close()
    return float(totals.mean())


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=5)
    ap.add_argument("--vector", type=int, default=0, help="also step this many environments together")
    args = ap.parse_args(argv)
    memory = train_env_memory("explore_info_gain")
    results = {name: evaluate(policy, memory, args.episodes) for name, policy in POLICIES.items()}
    for name, r in results.items():
        print(f"{name:<12} mean return {r['return']:.3f}  final accuracy {r['accuracy']:.3f}  "
              f"presses {r['presses']:.1f}")
    if args.vector:
        results["vector_max_entropy"] = {"return": evaluate_vector(max_entropy_policy, memory, args.vector)}
        print(f"max_entropy, {args.vector} environments together: mean return "
              f"{results['vector_max_entropy']['return']:.3f}")
    return results


if __name__ == "__main__":
    main()
