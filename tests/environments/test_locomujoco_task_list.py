"""LocoMuJoCo 0.4.1's task list here: its 55 redistributable Task-IDs make, reset, step and build their
datasets with LocoMuJoCo's observation and action sizes; carry draws a carried mass, 4Ages a body size."""
import mujoco
import numpy as np
import pytest

from loco_il import LocoEnv
from loco_il.environments.registry import UnknownTaskError, get_all_task_names, parse_task_id
from loco_il.experts.files import NoExpertError
from loco_il.motion.mocap.clips import ClipSpec

# loco_mujoco 0.4.1 `LocoEnv.get_all_task_names()` without MyoSkeleton's two (its licence forbids redistribution),
# with (obs, act) sizes from its environment docs (shared/reference/locomujoco-0.4.1.md)
LOCOMUJOCO_TASKS = {
    "Atlas.walk.real": (30, 10), "Atlas.walk.perfect": (30, 10),
    "Atlas.carry.real": (31, 10), "Atlas.carry.perfect": (31, 10),
    "Talos.walk.real": (34, 12), "Talos.walk.perfect": (34, 12), "Talos.carry.real": (35, 12),
    "UnitreeH1.walk.real": (32, 11), "UnitreeH1.walk.perfect": (32, 11), "UnitreeH1.run.real": (32, 11),
    "UnitreeH1.run.perfect": (32, 11), "UnitreeH1.carry.real": (33, 11),
    "UnitreeG1.walk.real": (56, 23), "UnitreeG1.run.real": (56, 23),
    "HumanoidTorque.walk.real": (36, 13), "HumanoidTorque.walk.perfect": (36, 13),
    "HumanoidTorque.run.real": (36, 13), "HumanoidTorque.run.perfect": (36, 13),
    "HumanoidMuscle.walk.real": (36, 92), "HumanoidMuscle.walk.perfect": (36, 92), "HumanoidMuscle.run.real": (36, 92),
    **{f"HumanoidTorque4Ages.{t}.{m}.{d}": (38, 13) for t in ("walk", "run") for m in ("all", "1", "2", "3", "4")
       for d in ("real", "perfect")},
    **{f"HumanoidMuscle4Ages.{t}.{m}.real": (38, 92) for t in ("walk", "run") for m in ("all", "1", "2", "3", "4")},
    "UnitreeA1.simple.real": (37, 12), "UnitreeA1.simple.perfect": (37, 12),
    "UnitreeA1.hard.real": (37, 12), "UnitreeA1.hard.perfect": (37, 12),
}
WITH_EXPERT = {"UnitreeA1.simple.perfect", "UnitreeA1.hard.perfect",   # the built-in trot controller
               "Atlas.walk.perfect", "Talos.walk.perfect",     # the shipped motion-tracking experts
               "UnitreeG1.walk.perfect", "HumanoidTorque.walk.perfect", "UnitreeH1.walk.perfect"}
SHORT_CLIP = [ClipSpec("deepmimic/humanoid3d_walk.txt")]     # one gait cycle: a dataset in a fraction of a second


def test_the_list_has_55_ids_all_registered():
    assert len(LOCOMUJOCO_TASKS) == 55
    assert not set(LOCOMUJOCO_TASKS) - set(get_all_task_names())


@pytest.mark.parametrize("task_id", list(LOCOMUJOCO_TASKS))
def test_makes_resets_steps_with_locomujoco_sizes(task_id):
    env = LocoEnv.make(task_id, seed=0)
    assert env.task_id == task_id
    obs = env.reset()
    obs_dim, act_dim = LOCOMUJOCO_TASKS[task_id]
    assert (obs.shape, env.info.action_space.shape) == ((obs_dim,), (act_dim,))
    obs, reward, absorbing, _ = env.step(np.zeros(env.info.action_space.shape))
    assert obs.shape == env.info.observation_space.shape and 0.0 < reward <= 1.0


@pytest.mark.parametrize("task_id", list(LOCOMUJOCO_TASKS))
def test_builds_its_dataset_or_says_how_to_get_the_expert(task_id, tmp_path, monkeypatch):
    """real builds (humanoids: one short clip; UnitreeA1: one simulated trot); perfect builds where an expert
    exists (UnitreeA1's built-in one, the five bipeds' walk tasks' shipped ones) and otherwise names how to get one."""
    monkeypatch.setenv("LOCO_IL_DATASETS", str(tmp_path))
    env = LocoEnv.make(task_id)
    kwargs = {"n_episodes": 1} if task_id.startswith("UnitreeA1") or task_id in WITH_EXPERT else {"clips": SHORT_CLIP}
    if task_id.endswith(".perfect") and task_id not in WITH_EXPERT:
        key = task_id.rsplit(".", 1)[0]
        with pytest.raises(NoExpertError, match=rf"no expert for {key}.*experts train task={key}"):
            env.create_dataset(n_episodes=1, verbose=False)
        return
    data = env.create_dataset(verbose=False, **kwargs)
    assert data.obs_dim == env.info.observation_space.shape[0] and data.n_transitions > 0
    if env.draw is not None:       # the clip once per drawn version, each with its own draw entries
        assert data.n_trajectories == len(env.draw_indices)
        draw_entries = data.obs[:, -len(env.draw.names):]
        assert len(np.unique(draw_entries, axis=0)) == len(env.draw_indices)


def _load_mass(env) -> float:
    return float(env.model.body_mass[mujoco.mj_name2id(env.model, mujoco.mjtObj.mjOBJ_BODY, "weight")])


@pytest.mark.parametrize("task_id", ["Atlas.carry.real", "Talos.carry.real", "UnitreeH1.carry.real"])
def test_carry_draws_a_mass_per_episode_and_observes_it(task_id):
    env = LocoEnv.make(task_id, seed=3)
    assert env.full_obs_spec.names[-1] == "carried_mass" and env.full_obs_spec.groups[-1] == "weight"
    masses = []
    for _ in range(12):
        obs = env.reset()
        assert obs[-1] == _load_mass(env) == env.command[0]
        masses.append(obs[-1])
    assert set(masses) == {0.1, 1.0, 5.0, 10.0}
    heavy = LocoEnv.make(task_id)
    heavy.select_draw(3)
    light = LocoEnv.make(task_id)
    light.select_draw(0)
    assert heavy.model.body_subtreemass[0] - light.model.body_subtreemass[0] == pytest.approx(9.9)
    assert LocoEnv.make(task_id, hide=("weight",)).reset().shape[0] == LOCOMUJOCO_TASKS[task_id][0] - 1


def test_ages_scale_the_model_and_the_target_speed():
    sizes = {}
    for mode, scale in (("1", 0.4), ("2", 0.6), ("3", 0.8), ("4", 1.0)):
        env = LocoEnv.make(f"HumanoidTorque4Ages.walk.{mode}.real", seed=0)
        obs = env.reset()
        sizes[scale] = (env.model.body_subtreemass[1], env.data.xpos[1, 2], env.model.actuator_gear[0, 0])
        assert env.command[0] == scale and list(obs[-2:]) == [(mode in "34") * 1.0, (mode in "24") * 1.0]
        # the reward's target is 1.25 m/s times the size: moving at it earns the full reward
        env.data.qvel[:] = 0.0
        _, reward, _, info = env.step(np.zeros(13))
        assert info["reward_terms"]["target_velocity"] == pytest.approx(1.25 * scale)
    adult = sizes[1.0]
    for scale, (mass, height, gear) in sizes.items():
        assert mass == pytest.approx(adult[0] * scale ** 3, rel=1e-6)
        assert height == pytest.approx(adult[1] * scale, abs=0.02)
        assert gear == pytest.approx(adult[2] * scale ** 2)


def test_ages_start_from_dataset_states_of_the_drawn_size(tmp_path, monkeypatch):
    from loco_il.datasets.providers import dataset_init_state_sampler
    monkeypatch.setenv("LOCO_IL_DATASETS", str(tmp_path))
    env = LocoEnv.make("HumanoidTorque4Ages.walk.all.real", seed=0)
    data = env.create_dataset(clips=SHORT_CLIP, verbose=False)
    env.init_state_sampler = dataset_init_state_sampler(env=env, trajs=data)
    for _ in range(8):
        env.reset()
        assert env.data.xpos[1, 2] == pytest.approx(0.975 * env.command[0], abs=0.05)   # the pelvis of that size


def test_ages_all_draws_every_size():
    env = LocoEnv.make("HumanoidMuscle4Ages.run.all.real", seed=0)
    drawn = set()
    for _ in range(16):
        env.reset()
        drawn.add(env.command[0])
    assert drawn == {0.4, 0.6, 0.8, 1.0}


def test_mode_part_parses_and_bad_modes_fail_in_one_line():
    assert parse_task_id("HumanoidTorque4Ages.walk.real").mode == "all"
    assert str(parse_task_id("HumanoidTorque4Ages.run.3")) == "HumanoidTorque4Ages.run.3.real"
    assert str(parse_task_id("HumanoidTorque4Ages.walk.2.real.pomdp")) == "HumanoidTorque4Ages.walk.2.real.pomdp"
    assert str(parse_task_id("Atlas.walk.perfect")) == "Atlas.walk.perfect"
    for bad, why in (("HumanoidTorque4Ages.walk.5.real", "not one of all, 1, 2, 3, 4"),
                     ("Atlas.walk.2.real", "has no mode part")):
        with pytest.raises(UnknownTaskError, match=why) as err:
            parse_task_id(bad)
        assert "\n" not in str(err.value)


@pytest.mark.parametrize("task_id", ["Talos.carry.real", "HumanoidTorque4Ages.walk.all.real"])
def test_domain_randomization_and_pomdp_cover_the_draws(task_id):
    env = LocoEnv.make(task_id + ".pomdp", seed=1, randomization="default")
    for _ in range(3):
        obs = env.reset()
        obs, *_ = env.step(np.zeros(env.info.action_space.shape))
        assert np.isfinite(obs).all() and obs.shape == env.info.observation_space.shape
    assert env.obs_spec.groups[-1] in ("weight", "env_type") and "velocities" not in env.obs_spec.groups
