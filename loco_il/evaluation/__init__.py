"""Scoring trained policies: returns, normalized scores, trajectory similarity, result tables.

    python -m loco_il.evaluation run_dir=results/InvertedPendulum.balance.perfect/bc/seed0 episodes=10
    python -m loco_il.evaluation record run_dir=... out=video.mp4
    python -m loco_il.evaluation.leaderboard results/

The metrics themselves (rollouts, scores, trajectory similarity, tables; defined in its docstring) live in
`loco_il.experiment.scoring`, below this package, since the runner scores its runs as they train; they are
re-exported here. Modules: `runs` (scoring a run dir), `leaderboard` and `progress` (tables over many run dirs).
"""
from loco_il.experiment.scoring import (evaluate_agent, evaluate_averaged_actor, evaluate_policy, format_eval_table,
                                         identical_episodes_note, mmd, nn_distance, normalized, trajectory_similarity)
from loco_il.evaluation.runs import (RunFileError, evaluate_run, expert_observations, load_final_agent,
                                     load_run_agent, load_run_config, record_run)

__all__ = ["evaluate_policy", "evaluate_agent", "evaluate_averaged_actor", "identical_episodes_note", "normalized",
           "trajectory_similarity", "nn_distance", "mmd", "format_eval_table", "load_run_config", "RunFileError",
           "load_final_agent", "load_run_agent", "expert_observations", "evaluate_run", "record_run"]
