"""Dataset providers: the code that builds a task's dataset for each dataset type.

* ``perfect``: deterministic rollouts of the task's expert (:mod:`.expert`);
* ``preference``: rollouts of >= 4 expert snapshots of increasing quality, ranked (:mod:`.expert`);
* ``real``: motion capture, supplied by a provider registered with :func:`register_real_provider`.

Users normally call ``env.create_dataset()`` / :func:`loco_il.datasets.create_dataset`.
"""
from loco_il.datasets.providers.expert import (
    DEFAULT_PERFECT_EPISODES,
    DEFAULT_PREFERENCE_EPISODES,
    MIN_PREFERENCE_LEVELS,
    SHIPPED_DIR,
    STATS,
    InitStates,
    NoExpertError,
    available_experts,
    available_snapshot_sets,
    create_preference_sets,
    dataset_init_state_sampler,
    datasets_cache_dir,
    episode_levels,
    episode_seeds,
    expert_search_path,
    find_expert,
    find_snapshots,
    init_states_path,
    perfect_provider,
    preference_provider,
    replay_episode,
    rollout,
    task_key,
    transition_levels,
)
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
    "DEFAULT_PERFECT_EPISODES", "DEFAULT_PREFERENCE_EPISODES", "MIN_PREFERENCE_LEVELS", "SHIPPED_DIR", "STATS",
    "InitStates", "NoExpertError", "ProviderUnavailableError", "available_experts", "available_snapshot_sets",
    "create_preference_sets", "dataset_init_state_sampler", "datasets_cache_dir", "episode_levels",
    "episode_seeds", "expert_search_path", "find_expert", "find_snapshots", "get_provider", "init_states_path",
    "motions_dir", "perfect_provider", "preference_provider", "register_provider", "register_real_provider",
    "registered_providers", "replay_episode", "rollout", "task_key", "transition_levels", "unregister_provider",
]
