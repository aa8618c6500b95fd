"""Dataset providers: perfect/preference rollouts, exact replay, caching, splits, errors, baselines."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from loco_il.datasets import DatasetError, Trajectories, create_dataset
from loco_il.datasets import providers as prov
from loco_il.datasets.providers import expert as expert_mod
from loco_il.environments.base import LocoEnv
from loco_il.environments.registry import get_body, make
from loco_il.experts import files as expert_files
from loco_il.experts.registry import builtin_expert

torch.set_num_threads(1)

PENDULUM_GOOD = np.array([0.5, 5.0, 0.5, 1.0])   # a stabilizing linear controller of InvertedPendulum


class LinearExpert:
    """Stand-in expert: deterministic a = W obs + b (deliberately NOT clipped: the provider clips)."""

    def __init__(self, W: np.ndarray, b: np.ndarray | None = None):
        self.W = np.atleast_2d(np.asarray(W, dtype=np.float64))
        self.b = np.zeros(self.W.shape[0]) if b is None else np.asarray(b, dtype=np.float64)
        self.obs_dim, self.act_dim = self.W.shape[1], self.W.shape[0]
        self.calls = 0

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        self.calls += 1
        return self.W @ obs + self.b

    def checksum(self) -> str:
        import hashlib
        return hashlib.sha256(self.W.tobytes() + self.b.tobytes()).hexdigest()


def linear_expert_file(path, K, task_id="InvertedPendulum.balance.perfect"):
    """A real `ExpertPolicy` file whose network is the linear map K (no hidden layers)."""
    from loco_il.experts.policy import ExpertPolicy
    K = np.atleast_2d(np.asarray(K, dtype=np.float64))
    pol = ExpertPolicy(K.shape[1], K.shape[0], hidden=(), metadata={"task_id": task_id, "training_steps": 0})
    with torch.no_grad():
        pol.policy.net[0].weight.copy_(torch.as_tensor(K, dtype=torch.float32))
        pol.policy.net[0].bias.zero_()
    path.parent.mkdir(parents=True, exist_ok=True)
    pol.save(path)
    return pol


@pytest.fixture
def dirs(tmp_path, monkeypatch):
    cache, experts, shipped = tmp_path / "cache", tmp_path / "experts", tmp_path / "shipped"
    experts.mkdir()
    shipped.mkdir()
    monkeypatch.setenv("LOCO_IL_DATASETS", str(cache))
    monkeypatch.setenv("LOCO_IL_EXPERTS", str(experts))
    monkeypatch.setattr(expert_files, "SHIPPED_DIR", shipped)   # ignore experts the repository ships
    return {"cache": cache, "experts": experts}


@pytest.fixture
def hopper_expert():
    rng = np.random.default_rng(1)
    return LinearExpert(2.0 * rng.standard_normal((3, 11)), rng.uniform(-0.5, 0.5, 3))


def _episodes(d: Trajectories):
    stops = np.flatnonzero(d.last) + 1
    return list(zip(np.concatenate([[0], stops[:-1]]), stops))


def _check_replay(task_id, data, init, with_seed=True):
    env = make(task_id)
    for e, (a, b) in enumerate(_episodes(data)):
        rep = prov.replay_episode(env, init.qpos[e], init.qvel[e], data.actions[a:b],
                                  seed=init.seeds[e] if with_seed else None)
        assert len(rep["obs"]) == b - a
        np.testing.assert_allclose(rep["obs"], data.obs[a:b], rtol=0, atol=1e-9)
        np.testing.assert_allclose(rep["next_obs"], data.next_obs[a:b], rtol=0, atol=1e-9)
        np.testing.assert_allclose(rep["rewards"], data.rewards[a:b], rtol=0, atol=1e-9)
        np.testing.assert_array_equal(rep["absorbing"], data.absorbing[a:b])


# ----------------------------------------------------------------------------- perfect


def test_perfect_shapes_flags_info(dirs, hopper_expert):
    env = make("Hopper.run.perfect")
    data, init = create_dataset(env, expert=hopper_expert, n_episodes=4, return_init_states=True, verbose=False)
    assert data.n_trajectories == 4 and len(init) == 4
    assert data.obs.shape[1] == env.obs_spec.dim and data.next_obs.shape == data.obs.shape
    assert data.actions.shape == (data.n_transitions, env.model.nu)
    assert np.abs(data.actions).max() <= 1.0            # clipped before recording...
    raw = np.stack([hopper_expert(o) for o in data.obs])
    assert np.abs(raw).max() > 1.0                       # ...although the expert asked for more
    np.testing.assert_array_equal(data.actions, np.clip(raw, -1, 1))
    assert not np.any(data.absorbing & ~data.last) and data.last[-1]
    assert data.absorbing[data.last].all()               # this bad expert makes the hopper fall every time
    for a, b in _episodes(data):
        np.testing.assert_array_equal(data.next_obs[a:b - 1], data.obs[a + 1:b])
    assert init.qpos.shape == (4, env.model.nq) and init.qvel.shape == (4, env.model.nv)
    info = data.info
    assert info["task_id"] == "Hopper.run.perfect" and info["dataset_type"] == "perfect"
    assert info["source"] == "expert rollout" and info["obs_names"] == list(env.obs_spec.names)
    assert info["simulator"].startswith("mujoco ") and info["seed"] == 0
    assert info["policy_checksum"] == hopper_expert.checksum()
    returns = [data.rewards[a:b].sum() for a, b in _episodes(data)]
    np.testing.assert_allclose(info["episode_returns"], returns)
    assert info["expert_return_mean"] == pytest.approx(np.mean(returns))


def test_replay_reproduces_observations_exactly(dirs, hopper_expert):
    data, init = create_dataset("Hopper.run.perfect", expert=hopper_expert, n_episodes=3,
                                return_init_states=True, verbose=False)
    _check_replay("Hopper.run.perfect", data, init)
    _check_replay("Hopper.run.perfect", data, init, with_seed=False)   # the stored state alone suffices here
    pend = LinearExpert(PENDULUM_GOOD[None] * 0.3)
    data, init = create_dataset("InvertedPendulum.balance.perfect", expert=pend, n_episodes=2,
                                return_init_states=True, verbose=False)
    assert data.obs.shape[1] == 4 and data.actions.shape[1] == 1
    _check_replay("InvertedPendulum.balance.perfect", data, init)


def test_cache_hit_and_key(dirs, hopper_expert, capsys):
    env = make("Hopper.run.perfect")
    g0 = prov.STATS["generated"]
    first = create_dataset(env, expert=hopper_expert, n_episodes=3)
    assert "episode 3/3" in capsys.readouterr().err            # progress is printed while generating
    assert prov.STATS["generated"] == g0 + 1
    calls = hopper_expert.calls
    hits = prov.STATS["cache_hits"]
    again = env.create_dataset(expert=hopper_expert, n_episodes=3)      # LocoEnv delegates here
    assert prov.STATS["generated"] == g0 + 1 and prov.STATS["cache_hits"] == hits + 1
    assert hopper_expert.calls == calls                          # no rollout on a cache hit
    assert again.equals(first)
    files = sorted(p.name for p in (dirs["cache"] / "Hopper.run").glob("*.npz"))
    assert len(files) == 2 and any(f.endswith(".init_states.npz") for f in files)
    other = create_dataset(env, expert=hopper_expert, n_episodes=3, generation_seed=1, verbose=False)
    assert prov.STATS["generated"] == g0 + 2
    assert other.info["cache_key"] != first.info["cache_key"] and not np.array_equal(other.obs[0], first.obs[0])
    more = create_dataset(env, expert=hopper_expert, n_episodes=4, verbose=False)
    assert more.info["cache_key"] != first.info["cache_key"]
    # episode seeds are prefix-stable: the first 3 episodes of the 4-episode set are the 3-episode set
    assert more.select_episodes([0, 1, 2]).equals(first, check_info=False)
    assert len(list((dirs["cache"] / "Hopper.run").glob("*.npz"))) == 6


def test_corrupt_cache_is_reported_then_regenerated(dirs, hopper_expert):
    env = make("Hopper.run.perfect")
    first = create_dataset(env, expert=hopper_expert, n_episodes=2, verbose=False)
    [path] = [p for p in (dirs["cache"] / "Hopper.run").glob("*.npz") if not p.name.endswith(".init_states.npz")]
    path.write_bytes(b"this is not a zip file")
    with pytest.raises(DatasetError) as exc:
        create_dataset(env, expert=hopper_expert, n_episodes=2, verbose=False)
    assert str(path) in str(exc.value) and "regenerate=True" in str(exc.value)
    fixed = create_dataset(env, expert=hopper_expert, n_episodes=2, regenerate=True, verbose=False)
    assert fixed.equals(first)
    side = prov.init_states_path(path)
    side.write_bytes(b"\x00" * 10)
    with pytest.raises(DatasetError, match="init_states"):
        create_dataset(env, expert=hopper_expert, n_episodes=2, verbose=False)


def test_split_disjoint_reproducible_and_aligned(dirs, hopper_expert):
    env = make("Hopper.run.perfect")
    kw = dict(expert=hopper_expert, n_episodes=8, verbose=False, return_init_states=True)
    full, init_full = create_dataset(env, **kw)
    train, init_tr = create_dataset(env, split="train", n_trajectories=6, seed=3, **kw)
    test, init_te = create_dataset(env, split="test", n_trajectories=6, seed=3, **kw)
    tr, te = train.info["split"]["episodes"], test.info["split"]["episodes"]
    assert len(tr) + len(te) == 6 and not set(tr) & set(te)
    assert train.equals(create_dataset(env, split="train", n_trajectories=6, seed=3, **kw)[0])
    assert train.equals(full.split(6, "train", seed=3))
    np.testing.assert_array_equal(init_tr.qpos, init_full.qpos[tr])
    np.testing.assert_array_equal(init_te.seeds, init_full.seeds[te])
    _check_replay("Hopper.run.perfect", test, init_te)
    pool = create_dataset(env, n_trajectories=5, seed=3, expert=hopper_expert, n_episodes=8, verbose=False)
    assert pool.n_trajectories == 5


def test_installed_expert_file_and_pomdp(dirs):
    pol = linear_expert_file(dirs["experts"] / "InvertedPendulum.balance" / "expert.pt", PENDULUM_GOOD[None] * 0.3)
    assert expert_files.available_experts() == ["InvertedPendulum.balance"]
    env = make("InvertedPendulum.balance.perfect")
    data, init = create_dataset(env, n_episodes=2, verbose=False, return_init_states=True)
    assert data.info["policy_checksum"] == pol.checksum()
    assert data.info["expert_metadata"]["task_id"] == "InvertedPendulum.balance.perfect"
    assert data.info["expert_return_mean"] > 100
    _check_replay("InvertedPendulum.balance.perfect", data, init)
    g = prov.STATS["generated"]
    same = create_dataset(env, n_episodes=2, verbose=False,
                          expert_path=dirs["experts"] / "InvertedPendulum.balance" / "expert.pt")
    assert same.equals(data) and prov.STATS["generated"] == g
    # .pomdp: the same cached full-observation data, handed out with the env's mask
    penv = make("InvertedPendulum.balance.perfect.pomdp")
    masked = create_dataset(penv, n_episodes=2, verbose=False)
    assert prov.STATS["generated"] == g
    assert masked.obs_dim == penv.obs_spec.dim == 2 and masked.info["obs_names"] == list(penv.obs_spec.names)
    assert masked.info["full_obs_names"] == list(env.obs_spec.names)
    np.testing.assert_array_equal(masked.obs, data.obs[:, penv.obs_mask])
    full = create_dataset(penv, n_episodes=2, verbose=False, full_obs=True)
    assert full.obs_dim == 4 and full.info["task_id"] == "InvertedPendulum.balance.perfect.pomdp"
    # an expert trained on the wrong task is refused
    wrong = dirs["experts"] / "wrong.pt"
    linear_expert_file(wrong, PENDULUM_GOOD[None], task_id="Hopper.run.perfect")
    with pytest.raises(DatasetError, match="trained on"):
        create_dataset(env, expert_path=wrong, n_episodes=1, verbose=False)


def test_task_without_expert_names_those_with_one(dirs):
    linear_expert_file(dirs["experts"] / "InvertedPendulum.balance" / "expert.pt", PENDULUM_GOOD[None])
    with pytest.raises(expert_files.NoExpertError) as exc:
        create_dataset("Hopper.run.perfect", verbose=False)
    msg = str(exc.value)
    assert "Hopper.run" in msg and "InvertedPendulum.balance" in msg
    assert "python -m loco_il.experts train task=Hopper.run" in msg


# ----------------------------------------------------------------------------- preference


def test_preference_levels(dirs):
    snaps = dirs["experts"] / "InvertedPendulum.balance" / "snapshots"
    scales = {0: 0.0, 1: 1.0, 2: 0.2, 3: 0.6}       # gains of PENDULUM_GOOD's hinge terms -> different quality
    for k, s in scales.items():
        K = PENDULUM_GOOD * np.array([s, 1.0, s, 1.0]) * (s > 0)
        linear_expert_file(snaps / f"level_{k}.pt", K[None])
    env = make("InvertedPendulum.balance.preference")
    sets = prov.create_preference_sets(env, n_episodes=2, verbose=False)
    assert len(sets) == 4
    means = [s.info["mean_return"] for s in sets]
    assert means == sorted(means) and means[0] < means[-1]
    assert [s.info["level"] for s in sets] == [0, 1, 2, 3]
    table = sets[0].info["levels"]
    assert [row["level"] for row in table] == [0, 1, 2, 3]
    assert [row["mean_return"] for row in table] == means
    assert all(row["snapshot"].endswith(".pt") for row in table)
    assert sets[0].info["snapshot"].endswith("level_0.pt")     # the zero policy is the worst

    data, init = create_dataset(env, n_episodes=2, verbose=False, return_init_states=True)
    assert data.n_trajectories == 8 and len(init) == 8 and data.info["dataset_type"] == "preference"
    assert data.info["episode_level"] == [0, 0, 1, 1, 2, 2, 3, 3]
    assert len(data.info["levels"]) == 4
    lv = prov.transition_levels(data)
    assert lv.shape == (data.n_transitions,) and np.all(np.diff(lv) >= 0)
    _check_replay("InvertedPendulum.balance.preference", data, init)
    test = create_dataset(env, split="test", n_episodes=2, verbose=False)
    eps = test.info["split"]["episodes"]
    assert test.info["episode_level"] == [data.info["episode_level"][i] for i in eps]
    np.testing.assert_array_equal(prov.episode_levels(test), np.asarray(data.info["episode_level"])[eps])
    # a user split of the full dataset still maps the labels
    np.testing.assert_array_equal(prov.episode_levels(data.split(split="test", seed=5)),
                                  np.asarray(data.info["episode_level"])[data.split_indices(split="test", seed=5)])
    with pytest.raises(DatasetError, match="at least 4"):
        prov.create_preference_sets(env, snapshots=sorted(snaps.glob("*.pt"))[:3], n_episodes=1, verbose=False)


# ----------------------------------------------------------------------------- real, init sampler, baselines


def test_real_without_provider_is_a_clear_error(dirs, monkeypatch):
    from loco_il.datasets.providers import registry
    monkeypatch.setattr(registry, "REAL_PROVIDER_MODULES", ())   # no auto-registration by a real-data module
    saved = prov.unregister_provider("real")
    try:
        env = LocoEnv(get_body("Hopper"), "run", "real")
        with pytest.raises(prov.ProviderUnavailableError) as exc:
            create_dataset(env)
        msg = str(exc.value)
        assert "Hopper.run.real" in msg and "motion" in msg and str(prov.motions_dir(env)) in msg

        def fake_real(env, **kwargs):
            n, d = 5, env.full_obs_spec.dim
            return Trajectories(np.zeros((n, d)), np.zeros((n, d)), None, np.zeros(n), np.zeros(n, bool),
                                np.array([False, True, False, False, True]),
                                {"dataset_type": "real", "obs_names": list(env.full_obs_spec.names)})

        prov.register_real_provider(fake_real)
        data = create_dataset(env, split="train", portion=(0.0, 0.5))
        assert data.n_trajectories == 1 and data.actions is None and data.info["task_id"] == "Hopper.run.real"
    finally:
        prov.unregister_provider("real")
        if saved is not None:
            prov.register_real_provider(saved)


def test_dataset_init_state_sampler(dirs, hopper_expert):
    env = make("Hopper.run.perfect")
    data, init = create_dataset(env, expert=hopper_expert, n_episodes=3, verbose=False, return_init_states=True)
    env.init_state_sampler = prov.dataset_init_state_sampler(init)
    env.seed(0)
    env.reset()
    q, _ = env.get_sim_state()
    assert any(np.array_equal(q, row) for row in init.qpos)
    env.init_state_sampler = prov.dataset_init_state_sampler(env=env, trajs=data)
    obs = env.reset()
    states = np.concatenate([data.obs, data.next_obs[data.last]])
    assert np.any(np.all(np.isclose(states, obs, rtol=0, atol=1e-12), axis=1))


def test_baselines(tmp_path):
    from loco_il.datasets import baselines as bl
    path = tmp_path / "b.yaml"
    bl.save_baselines({"Hopper.run": {"random": {"return_mean": 20.0, "return_std": 5.0},
                                      "expert": {"return_mean": 3020.0, "return_std": 10.0}},
                       "Walker2d.run": {"random": {"return_mean": 1.0}}}, path)
    assert bl.get_baseline("Hopper.run.perfect.pomdp", path)["expert"]["return_mean"] == 3020.0
    assert bl.normalized_score("Hopper.run.perfect", 1520.0, path) == pytest.approx(0.5)
    np.testing.assert_allclose(bl.normalized_score("Hopper.run", np.array([20.0, 3020.0]), path), [0.0, 1.0])
    with pytest.raises(bl.BaselineMissingError, match="no expert return"):
        bl.normalized_score("Walker2d.run", 1.0, path)
    with pytest.raises(bl.BaselineMissingError, match="python -m loco_il.datasets.baselines update Ant.run"):
        bl.get_baseline("Ant.run.perfect", path)
    for key, entry in bl.load_baselines().items():     # the shipped table: only measured, documented numbers
        for part in ("random", "expert"):
            if part in entry:
                assert {"return_mean", "return_std", "episodes", "seed", "command", "commit"} <= set(entry[part]), key


# ----------------------------------------------------------------------------- worker processes


def _rollout_both_ways(task_id, policy, n, horizon, log=None):
    env = make(task_id)
    seeds = prov.episode_seeds(0, n)
    one = prov.rollout(env, policy, seeds, horizon=horizon)
    many = prov.rollout(env, policy, seeds, horizon=horizon, workers=2, log=log, label=task_id)
    return one, many


def _assert_same_rollouts(one, many):
    (d1, i1), (d2, i2) = one, many
    for name in ("obs", "next_obs", "actions", "rewards", "absorbing", "last"):
        np.testing.assert_array_equal(getattr(d2, name), getattr(d1, name), err_msg=name)
    for name in ("qpos", "qvel", "seeds"):
        np.testing.assert_array_equal(getattr(i2, name), getattr(i1, name), err_msg=name)
    assert d2.info == d1.info


def test_workers_record_the_same_episodes_in_seed_order():
    """Episodes recorded in 2 spawned processes (each with its own env) equal those of one process, bit for bit,
    for a trained expert file and for the quadrupeds' built-in expert, which reads the simulator at every step;
    the progress lines still count the episodes in order."""
    from loco_il.experts.policy import load_expert
    lines: list[str] = []
    hopper = load_expert(expert_files.SHIPPED_DIR / "Hopper.run" / "expert.pt")
    one, many = _rollout_both_ways("Hopper.run.perfect", hopper, 5, 60, log=lines.append)
    _assert_same_rollouts(one, many)
    starts = [a for a, _ in one[0].episode_bounds()]
    assert len(starts) == 5 and len(np.unique(one[0].obs[starts], axis=0)) == 5     # five different episodes
    assert "recording 5 episodes in 2 worker processes" in lines[0]
    assert [line.split("episode ")[1].split(",")[0] for line in lines[1:]] == [f"{k}/5" for k in range(1, 6)]
    env = make("UnitreeA1.simple.perfect")
    trot = builtin_expert("UnitreeA1.simple").expert(env)
    _assert_same_rollouts(*_rollout_both_ways("UnitreeA1.simple.perfect", trot, 3, 40))


def test_workers_come_from_a_fork_server_and_spawned_workers_record_the_same(hopper_expert, monkeypatch):
    """Linux starts the workers from a fork server that imported torch and loco_il once; the spawn start that
    platforms without one use gives the same episodes too."""
    from loco_il.datasets.providers import rollout_workers
    assert rollout_workers.START_METHOD == "forkserver"          # the CI and development machines: Linux
    assert rollout_workers._context().get_start_method() == "forkserver"
    monkeypatch.setattr(rollout_workers, "START_METHOD", "spawn")
    assert rollout_workers._context().get_start_method() == "spawn"
    _assert_same_rollouts(*_rollout_both_ways("Hopper.run.perfect", hopper_expert, 3, 30))


class _Unpicklable(LinearExpert):
    def __init__(self, *args):
        super().__init__(*args)
        self.hook = lambda obs: obs      # a lambda: pickle cannot send this policy to a worker


def test_a_policy_that_cannot_be_pickled_is_recorded_in_this_process(hopper_expert):
    lines: list[str] = []
    policy = _Unpicklable(hopper_expert.W, hopper_expert.b)
    one, many = _rollout_both_ways("Hopper.run.perfect", policy, 3, 30, log=lines.append)
    _assert_same_rollouts(one, many)
    assert "recording the episodes in this process (the policy cannot be sent to worker processes" in lines[0]


def test_create_dataset_passes_workers_to_rollout_providers(dirs, hopper_expert, monkeypatch):
    seen = []
    real_rollout = expert_mod.rollout
    monkeypatch.setattr(expert_mod, "rollout", lambda *a, **k: seen.append(k["workers"]) or real_rollout(
        *a, **{**k, "workers": 1}))
    data = create_dataset("Hopper.run.perfect", expert=hopper_expert, n_episodes=2, verbose=False, workers=3)
    assert seen == [3] and data.n_trajectories == 2
    with pytest.raises(ValueError, match="workers must be >= 1"):
        create_dataset("Hopper.run.perfect", expert=hopper_expert, n_episodes=2, verbose=False, workers=0)


def test_train_configs_dataset_workers_reaches_create_dataset():
    from loco_il.datasets.loading import dataset_kwargs
    assert dataset_kwargs({"workers": 4, "n_episodes": 12})["workers"] == 4
    assert "workers" not in dataset_kwargs({"workers": None})
