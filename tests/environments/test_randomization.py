"""Domain randomization: parameters change within their bounds, consistently, reproducibly, on schedule."""
from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

from loco_il.environments import LocoEnv
from loco_il.environments.assets import gymnasium_asset
from loco_il.environments.randomization import (DomainRandomization, RandomizationConfigError, load_randomization,
                                                lowest_point, parse_distribution)


def _id(model, kind, name):
    return mujoco.mj_name2id(model, kind, name)


def _body(model, name):
    return _id(model, mujoco.mjtObj.mjOBJ_BODY, name)


def _anchor_distance(model, joint_a, joint_b):
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ja, jb = (_id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in (joint_a, joint_b))
    return float(np.linalg.norm(data.xanchor[ja] - data.xanchor[jb]))


# ---------------------------------------------------------------- masses and inertias
@pytest.mark.parametrize("task_id, body", [("Hopper.run.perfect", "leg"),
                                           ("HalfCheetah.run.perfect", "bthigh")])  # settotalmass model
def test_mass_and_inertia_scale_together_within_bounds(task_id, body):
    env = LocoEnv.make(task_id, seed=1, randomization={"mass": {"bodies": [body], "scale": [1.3, 1.5]}})
    mass0, inertia0 = env.model.body_mass.copy(), env.model.body_inertia.copy()
    env.randomize()
    b = _body(env.model, body)
    k = env.model.body_mass[b] / mass0[b]
    assert 1.3 <= k <= 1.5
    np.testing.assert_allclose(env.model.body_inertia[b] / inertia0[b], k, rtol=1e-9)
    others = [i for i in range(1, env.model.nbody) if i != b]
    np.testing.assert_allclose(env.model.body_mass[others], mass0[others], rtol=1e-9)
    np.testing.assert_allclose(env.model.body_inertia[others], inertia0[others], rtol=1e-9)


def test_additive_mass_delta_in_kg():
    env = LocoEnv.make("Hopper.run.perfect", seed=0,
                       randomization={"mass": {"bodies": ["torso"], "add": [0.5, 1.0]}})
    mass0 = env.model.body_mass.copy()
    env.randomize()
    delta = env.model.body_mass[_body(env.model, "torso")] - mass0[_body(env.model, "torso")]
    assert 0.5 <= delta <= 1.0


def test_limb_length_moves_the_next_joint_and_recomputes_mass_and_inertia():
    env = LocoEnv.make("Hopper.run.perfect", seed=0,
                       randomization={"limb_length": {"bodies": ["leg"], "scale": 1.2}})
    base = env.model
    env.randomize()
    ratio = _anchor_distance(env.model, "leg_joint", "foot_joint") / _anchor_distance(base, "leg_joint", "foot_joint")
    assert ratio == pytest.approx(1.2, rel=1e-9)
    # reference: the same leg capsule made 20% longer by hand; its mass and inertia must match
    ref = mujoco.MjSpec.from_file(str(gymnasium_asset("hopper.xml")))
    geom = ref.geom("leg_geom")
    geom.size = np.array([geom.size[0], geom.size[1] * 1.2, 0.0])
    ref_model = ref.compile()
    leg = _body(env.model, "leg")
    r = 0.04
    capsule_mass = 1000 * (np.pi * r ** 2 * 2 * 0.3 + 4 / 3 * np.pi * r ** 3)
    assert env.model.body_mass[leg] == pytest.approx(capsule_mass, rel=1e-9)
    np.testing.assert_allclose(env.model.body_inertia[leg], ref_model.body_inertia[leg], rtol=1e-9)
    assert env.model.body_inertia[leg][0] > base.body_inertia[leg][0] * 1.2   # longer: much larger Ixx
    # the leg grew by 0.1 m; the root was lifted so the foot starts at the same height above the floor
    assert env.model.qpos0[1] == pytest.approx(base.qpos0[1] + 0.1, abs=1e-9)


def test_limb_length_keeps_ground_clearance_and_env_steps():
    cfg = {"limb_length": {"bodies": ["thigh", "leg"], "scale": [1.1, 1.2]}}
    env = LocoEnv.make("Hopper.run.perfect", seed=3, randomization=cfg)
    low0 = lowest_point(env.base_spec.copy())
    env.reset()
    spec = env.base_spec.copy()
    load_randomization(cfg).apply(spec, np.random.default_rng(5))
    assert lowest_point(spec) == pytest.approx(low0, abs=1e-9)
    for _ in range(20):
        obs, _, _, info = env.step(np.zeros(3))
        assert np.isfinite(obs).all() and not info["diverged"]


# ---------------------------------------------------------------- other parameters
def test_friction_damping_armature_ranges_gains_gravity_within_bounds():
    cfg = {"friction": {"geoms": ["foot_geom"], "scale": [0.5, 0.6]},
           "damping": {"joints": ["*_joint"], "scale": [2.0, 3.0]},
           "armature": {"joints": ["*_joint"], "add": [0.1, 0.2]},
           "joint_range": {"joints": ["*_joint"], "scale": [0.5, 0.6], "about": "ref"},
           "actuator_gain": {"actuators": ["*"], "scale": {"dist": "gaussian", "mean": 0.7, "std": 0.2,
                                                           "clip": [0.6, 0.8]}},
           "gravity": {"scale": [0.9, 0.95]}}
    env = LocoEnv.make("Hopper.run.perfect", seed=2, randomization=cfg)
    m0 = env.model
    env.randomize()
    m = env.model
    foot = _id(m, mujoco.mjtObj.mjOBJ_GEOM, "foot_geom")
    assert 0.5 <= m.geom_friction[foot, 0] / m0.geom_friction[foot, 0] <= 0.6
    others = [g for g in range(m.ngeom) if g != foot]
    np.testing.assert_array_equal(m.geom_friction[others], m0.geom_friction[others])
    dofs = [m.jnt_dofadr[_id(m, mujoco.mjtObj.mjOBJ_JOINT, n)] for n in ("thigh_joint", "leg_joint", "foot_joint")]
    ratio = m.dof_damping[dofs] / m0.dof_damping[dofs]
    assert np.all((ratio >= 2.0) & (ratio <= 3.0)) and len(set(np.round(ratio, 12))) == 3   # one draw each
    delta = m.dof_armature[dofs] - m0.dof_armature[dofs]
    assert np.all((delta >= 0.1 - 1e-12) & (delta <= 0.2 + 1e-12))
    np.testing.assert_array_equal(m.dof_damping[:3], m0.dof_damping[:3])   # root joints untouched
    width0, width = np.diff(m0.jnt_range[3:], axis=1)[:, 0], np.diff(m.jnt_range[3:], axis=1)[:, 0]
    assert np.all((width / width0 >= 0.5 - 1e-12) & (width / width0 <= 0.6 + 1e-12))
    assert np.all((m.jnt_range[3:, 0] <= 0) & (m.jnt_range[3:, 1] >= 0))   # about ref: qpos0 stays inside
    gain = m.actuator_gainprm[:, 0] / m0.actuator_gainprm[:, 0]
    assert np.all((gain >= 0.6) & (gain <= 0.8))
    g = m.opt.gravity[2] / m0.opt.gravity[2]
    assert 0.9 <= g <= 0.95


def test_joint_range_scales_about_centre_by_default():
    env = LocoEnv.make("Hopper.run.perfect", seed=0,
                       randomization={"joint_range": {"joints": ["thigh_joint"], "scale": 0.5}})
    r0 = env.model.jnt_range[3].copy()
    env.randomize()
    r = env.model.jnt_range[3]
    assert r.mean() == pytest.approx(r0.mean()) and (r[1] - r[0]) == pytest.approx(0.5 * (r0[1] - r0[0]))


def test_shared_draw_applies_one_factor_to_all_matches():
    env = LocoEnv.make("Walker2d.run.perfect", seed=0,
                       randomization={"mass": {"bodies": ["thigh*"], "scale": [0.5, 2.0], "shared": True}})
    m0 = env.model.body_mass.copy()
    env.randomize()
    right, left = _body(env.model, "thigh"), _body(env.model, "thigh_left")
    k = env.model.body_mass / np.where(m0 > 0, m0, 1)
    assert k[right] == pytest.approx(k[left]) and k[right] != pytest.approx(1.0)


# ---------------------------------------------------------------- reproducibility and schedule
def _fingerprint(model):
    return np.concatenate([model.body_mass, model.body_inertia.ravel(), model.geom_friction.ravel(),
                           model.dof_damping, model.actuator_gainprm[:, 0], model.body_pos.ravel()])


def test_same_seed_same_model_different_seed_different():
    models = []
    for seed in (7, 7, 8):
        env = LocoEnv.make("Walker2d.run.perfect", seed=seed, randomization="default")
        env.reset()
        models.append(_fingerprint(env.model))
    np.testing.assert_array_equal(models[0], models[1])
    assert not np.allclose(models[0], models[2])


def test_reset_rerandomizes_at_the_interval():
    env = LocoEnv.make("Hopper.run.perfect", seed=0, randomize_every=2,
                       randomization={"mass": {"bodies": ["*"], "scale": [0.5, 1.5]}})
    base = env.model.body_mass.copy()
    masses = []
    for _ in range(5):
        env.reset()
        masses.append(env.model.body_mass.copy())
    assert not np.allclose(masses[0], base)                 # first reset randomizes
    np.testing.assert_array_equal(masses[0], masses[1])     # kept for 2 episodes
    assert not np.allclose(masses[1], masses[2])
    np.testing.assert_array_equal(masses[2], masses[3])
    assert not np.allclose(masses[3], masses[4])


def test_config_interval_is_carried_and_used_by_make():
    rand = load_randomization({"every": 3, "mass": {"scale": [0.9, 1.1]}})
    assert rand.every == 3 and load_randomization({"interval": 4}).every == 4
    env = LocoEnv.make("Hopper.run.perfect", seed=0, randomization={"every": 3, "mass": {"scale": [0.9, 1.1]}})
    assert env.randomization.every == 3
    assert env.randomize_every == 3, "registry.make should pass randomization.every as randomize_every"


@pytest.mark.parametrize("task_id", ["Hopper.run.perfect", "Walker2d.run.perfect", "HalfCheetah.run.perfect"])
def test_default_configs_step_with_finite_observations(task_id):
    env = LocoEnv.make(task_id, seed=0, randomization="default")
    assert env.randomization.source.endswith(f"{task_id.split('.')[0]}.yaml")
    rng = np.random.default_rng(0)
    for _ in range(2):
        obs = env.reset()
        assert np.isfinite(obs).all()
        for _ in range(25):
            obs, reward, absorbing, info = env.step(rng.uniform(-1, 1, env.model.nu))
            assert np.isfinite(obs).all() and np.isfinite(reward) and not info["diverged"]
            if absorbing:
                break


def test_named_configs_and_generic_fallback(tmp_path):
    assert load_randomization("default", "Ant").source.endswith("generic.yaml")
    assert load_randomization("default", "Humanoid").source.endswith("Humanoid.yaml")
    assert load_randomization("generic").rules
    path = tmp_path / "mine.yaml"
    path.write_text("every: 2\nfriction:\n  geoms: ['*']\n  scale: {dist: loguniform, low: 0.5, high: 2.0}\n")
    rand = load_randomization(str(path), "Hopper")
    assert rand.every == 2 and rand.rules[0].dist.kind == "loguniform"


# ---------------------------------------------------------------- validation
@pytest.mark.parametrize("cfg, words", [
    ({"masss": {"scale": [0.9, 1.1]}}, ["'masss'", "did you mean 'mass'"]),
    ({"mass": {"bodys": ["*"], "scale": [0.9, 1.1]}}, ["mass", "'bodys'", "bodies"]),
    ({"mass": {"scale": [1.2, 0.8]}}, ["mass.scale", "larger than high"]),
    ({"mass": {"scale": [0.0, 1.0]}}, ["mass.scale", "> 0"]),
    ({"mass": {"scale": [0.9, 1.1], "add": [0, 1]}}, ["exactly one of"]),
    ({"damping": {"scale": {"dist": "gaussian", "mean": 1.0}}}, ["damping.scale", "'std'"]),
    ({"damping": {"scale": {"dist": "beta", "a": 1}}}, ["damping.scale.dist", "'beta'"]),
    ({"joint_range": {"add": [0, 1]}}, ["joint_range", "'add'"]),
    ({"joint_range": {"scale": 0.9, "about": "middle"}}, ["joint_range.about", "'middle'"]),
    ({"every": 0}, ["every", "integer >= 1"]),
    ({"friction": "high"}, ["friction", "mapping"]),
])
def test_bad_config_raises_a_clear_error(cfg, words):
    with pytest.raises(RandomizationConfigError) as err:
        load_randomization(cfg, "Hopper")
    for word in words:
        assert word in str(err.value), (word, str(err.value))


def test_pattern_matching_nothing_is_an_error_naming_it():
    env = LocoEnv.make("Hopper.run.perfect", randomization={"mass": {"bodies": ["*wing*"], "scale": [0.9, 1.1]}})
    with pytest.raises(RandomizationConfigError, match=r"'\*wing\*'.*matches no bodies"):
        env.reset()
    relaxed = LocoEnv.make("Hopper.run.perfect", randomization={
        "strict": False, "mass": {"bodies": ["*wing*", "leg"], "scale": [0.9, 1.1]}})
    relaxed.reset()


def test_unknown_named_config_and_missing_file():
    with pytest.raises(RandomizationConfigError, match="Hopperr"):
        load_randomization("Hopperr")
    with pytest.raises(RandomizationConfigError, match="does not exist"):
        load_randomization("/nonexistent/dr.yaml")


def test_distributions_sample_within_support():
    rng = np.random.default_rng(0)
    for cfg in ([0.5, 1.5], {"dist": "loguniform", "low": 0.1, "high": 10},
                {"dist": "normal", "mean": 1, "std": 5, "clip": [0, 2]}, 3.0):
        dist = parse_distribution(cfg)
        lo, hi = dist.support
        x = dist.sample(rng, 1000)
        assert x.min() >= lo and x.max() <= hi and x.std() >= 0


def test_apply_works_on_a_plain_spec_without_warnings():
    spec = mujoco.MjSpec.from_file(str(gymnasium_asset("half_cheetah.xml")))
    rand = DomainRandomization.from_config({"mass": {"scale": [0.9, 1.1]}, "limb_length": {"bodies": ["fshin"],
                                                                                          "scale": 1.1}})
    with warnings.catch_warnings():
        warnings.simplefilter("error")   # settotalmass is rewritten as densities: no deprecation warning
        rand.apply(spec, np.random.default_rng(0))
        model = spec.compile()
    assert model.nbody == 8 and np.isfinite(model.body_mass).all()


def test_coefficient_helpers_handle_scalars_and_arrays():
    # joint.damping etc. are scalars in some mujoco versions and arrays in others
    from types import SimpleNamespace

    from loco_il.environments.randomization import get_first, scale_attr, set_first
    scalar, array = SimpleNamespace(damping=2.0), SimpleNamespace(damping=np.array([2.0, 1.0, 0.0]))
    scale_attr(scalar, "damping", 1.5)
    scale_attr(array, "damping", 1.5)
    assert scalar.damping == 3.0 and np.allclose(array.damping, [3.0, 1.5, 0.0])
    set_first(scalar, "damping", get_first(scalar, "damping") + 1)
    set_first(array, "damping", get_first(array, "damping") + 1)
    assert scalar.damping == 4.0 and np.allclose(array.damping, [4.0, 1.5, 0.0])
