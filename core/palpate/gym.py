"""``palpate/Explore-v0``: importing this module registers palpate's Gymnasium environment (the ``gym`` extra).

::

    import gymnasium as gym
    import palpate.gym  # noqa: F401  (or gym.make("palpate.gym:palpate/Explore-v0") without the import)
    env = gym.make("palpate/Explore-v0", scenario="sweeps/tiny_base")

``import palpate`` alone never imports gymnasium. See docs/gym.md and
:mod:`palpate.core.session.explore_env`.
"""

from __future__ import annotations

from palpate.core.extras import require_extra

require_extra("the Gymnasium environment", "gymnasium")

from palpate.core.session.explore_env import (  # noqa: E402
    ENV_ID,
    ExploreEnv,
    ExploreVectorEnv,
    make_vector_env,
    register,
    train_env_memory,
)

register()

__all__ = ["ENV_ID", "ExploreEnv", "ExploreVectorEnv", "make_vector_env", "register", "train_env_memory"]
