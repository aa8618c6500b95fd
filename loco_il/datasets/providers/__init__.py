"""Dataset providers: the code that builds a task's dataset for each dataset type.

* ``perfect``: deterministic rollouts of the task's expert (:mod:`.expert`; the experts themselves are
  found and loaded by `loco_il.experts.files`);
* ``preference``: rollouts of >= 4 expert snapshots of increasing quality, ranked (:mod:`.expert`,
  labels in :mod:`.levels`);
* ``real``: motion capture, supplied by a provider registered with :func:`register_real_provider`.

Generated datasets are cached (:mod:`.cache`) with the simulator state where each episode starts
(:mod:`.init_states`). Users normally call ``env.create_dataset()`` / :func:`loco_il.datasets.create_dataset`.
"""
from loco_il.datasets.providers.cache import datasets_cache_dir, init_states_path
from loco_il.datasets.providers.expert import (
    DEFAULT_PERFECT_EPISODES,
    DEFAULT_PREFERENCE_EPISODES,
    STATS,
    create_preference_sets,
    episode_seeds,
    perfect_provider,
    preference_provider,
    replay_episode,
    rollout,
)
from loco_il.datasets.providers.init_states import InitStates, dataset_init_state_sampler
from loco_il.datasets.providers.levels import episode_levels, transition_levels
from loco_il.datasets.providers.registry import (
    ProviderUnavailableError,
    get_provider,
    motions_dir,
    register_provider,
    register_real_provider,
    registered_providers,
    unregister_provider,
)

__all__ = [
    "DEFAULT_PERFECT_EPISODES", "DEFAULT_PREFERENCE_EPISODES", "STATS", "InitStates", "ProviderUnavailableError",
    "create_preference_sets", "dataset_init_state_sampler", "datasets_cache_dir", "episode_levels", "episode_seeds",
    "get_provider", "init_states_path", "motions_dir", "perfect_provider", "preference_provider",
    "register_provider", "register_real_provider", "registered_providers", "replay_episode", "rollout",
    "transition_levels", "unregister_provider",
]
