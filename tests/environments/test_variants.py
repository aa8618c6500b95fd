"""iMuJoCo-style morphology variants: counts, and that each category really changes the model."""
from __future__ import annotations

import mujoco
import numpy as np
import pytest

from loco_il.environments import LocoEnv, UnknownTaskError, parse_task_id
from loco_il.environments.randomization import lowest_point
from loco_il.environments.variants import (UnknownVariantError, apply_variant, list_variants, parse_variant)


def _id(model, kind, name):
    idx = mujoco.mj_name2id(model, kind, name)
    assert idx >= 0, name
    return idx


def _forward(model):
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return data


@pytest.fixture(scope="module")
def hopper_env():
    return LocoEnv.make("Hopper.run.perfect")


@pytest.fixture(scope="module")
def hopper(hopper_env):
    return hopper_env.model


def test_counts_match_imujoco():
    # iMuJoCo (Patacchiola et al. 2023): 37 Hopper, 53 HalfCheetah, 64 Walker2d variants (154 in total)
    counts = {b: len(list_variants(b)) for b in ("Hopper", "HalfCheetah", "Walker2d")}
    assert counts == {"Hopper": 37, "HalfCheetah": 53, "Walker2d": 64}
    for body in counts:
        names = list_variants(body)
        assert names == sorted(set(names))
    assert list_variants("Ant") == [] and list_variants("NoSuchBody") == []
    assert {"massdec_25_leg", "lendec_25_leg", "rangedec_50_thigh", "frictioninc_25_foot"} <= set(
        list_variants("Hopper"))


@pytest.mark.parametrize("variant, factor", [("lendec_25_leg", 0.75), ("leninc_25_leg", 1.25)])
def test_length_variant_changes_the_leg(hopper_env, variant, factor):
    hopper, hopper_spec = hopper_env.model, hopper_env.base_spec
    env = LocoEnv.make(f"Hopper-{variant}.run.perfect")
    model = env.model
    d0, d = _forward(hopper), _forward(model)
    leg_j, foot_j = (_id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in ("leg_joint", "foot_joint"))
    foot = _id(model, mujoco.mjtObj.mjOBJ_BODY, "foot")
    joint_dist0 = np.linalg.norm(d0.xanchor[leg_j] - d0.xanchor[foot_j])
    joint_dist = np.linalg.norm(d.xanchor[leg_j] - d.xanchor[foot_j])
    assert joint_dist == pytest.approx(factor * joint_dist0, rel=1e-9)
    body_dist0 = np.linalg.norm(d0.xanchor[leg_j] - d0.xpos[foot])
    body_dist = np.linalg.norm(d.xanchor[leg_j] - d.xpos[foot])
    assert (body_dist < body_dist0) if factor < 1 else (body_dist > body_dist0)
    leg_geom = _id(model, mujoco.mjtObj.mjOBJ_GEOM, "leg_geom")
    assert model.geom_size[leg_geom, 1] == pytest.approx(factor * hopper.geom_size[leg_geom, 1])
    leg = _id(model, mujoco.mjtObj.mjOBJ_BODY, "leg")
    assert (model.body_mass[leg] < hopper.body_mass[leg]) == (factor < 1)   # mass follows the volume
    # other limbs keep their size; the root is lifted/lowered by the change of the leg's length (0.5 m),
    # so that the lowest point (the foot) starts at the same height above the floor
    thigh_geom = _id(model, mujoco.mjtObj.mjOBJ_GEOM, "thigh_geom")
    np.testing.assert_allclose(model.geom_size[thigh_geom], hopper.geom_size[thigh_geom])
    assert model.qpos0[1] == pytest.approx(hopper.qpos0[1] + 0.5 * (factor - 1), abs=1e-9)
    assert lowest_point(env.base_spec.copy()) == pytest.approx(lowest_point(hopper_spec.copy()), abs=1e-9)


@pytest.mark.parametrize("body_name, variant, limb, factor", [
    ("Hopper", "massinc_25_leg", "leg", 1.25), ("Hopper", "massdec_50_torso", "torso", 0.5),
    ("Walker2d", "massinc_50_thigh_left", "thigh_left", 1.5),
    ("HalfCheetah", "massinc_25_bshin", "bshin", 1.25),   # HalfCheetah uses settotalmass: others must not move
])
def test_mass_variant_scales_mass_and_inertia_of_that_limb_only(body_name, variant, limb, factor):
    base = LocoEnv.make(f"{body_name}.run.perfect").model
    model = LocoEnv.make(f"{body_name}-{variant}.run.perfect").model
    b = _id(model, mujoco.mjtObj.mjOBJ_BODY, limb)
    assert model.body_mass[b] == pytest.approx(factor * base.body_mass[b], rel=1e-9)
    np.testing.assert_allclose(model.body_inertia[b], factor * base.body_inertia[b], rtol=1e-9)
    others = [i for i in range(model.nbody) if i != b]
    np.testing.assert_allclose(model.body_mass[others], base.body_mass[others], rtol=1e-9)


def test_range_variant_narrows_jnt_range(hopper):
    model = LocoEnv.make("Hopper-rangedec_50_thigh.run.perfect").model
    j = _id(model, mujoco.mjtObj.mjOBJ_JOINT, "thigh_joint")
    width0, width = np.ptp(hopper.jnt_range[j]), np.ptp(model.jnt_range[j])
    assert width == pytest.approx(0.5 * width0)
    assert model.jnt_range[j, 0] <= model.qpos0[model.jnt_qposadr[j]] <= model.jnt_range[j, 1]
    other = _id(model, mujoco.mjtObj.mjOBJ_JOINT, "leg_joint")
    np.testing.assert_array_equal(model.jnt_range[other], hopper.jnt_range[other])
    cheetah = LocoEnv.make("HalfCheetah-rangedec_75_thighs.run.perfect").model
    base = LocoEnv.make("HalfCheetah.run.perfect").model
    for name in ("bthigh", "fthigh"):
        j = _id(cheetah, mujoco.mjtObj.mjOBJ_JOINT, name)
        assert np.ptp(cheetah.jnt_range[j]) == pytest.approx(0.25 * np.ptp(base.jnt_range[j]))


def _foot_contact_friction(task_id, feet):
    env = LocoEnv.make(task_id, seed=0)
    env.reset()
    ids = {_id(env.model, mujoco.mjtObj.mjOBJ_GEOM, f) for f in feet}
    for _ in range(100):
        frictions = [c.friction[0] for c in env.data.contact[:env.data.ncon] if {c.geom1, c.geom2} & ids]
        if frictions:
            return frictions
        env.step(np.zeros(env.model.nu))
    raise AssertionError(f"{task_id}: the feet never touched the floor")


@pytest.mark.parametrize("body_name, variant, feet, factor", [
    ("Hopper", "frictiondec_50_foot", ["foot_geom"], 0.5),
    ("HalfCheetah", "frictiondec_50_feet", ["bfoot", "ffoot"], 0.5),   # floor and feet both 0.4
    ("HalfCheetah", "frictioninc_25_feet", ["bfoot", "ffoot"], 1.25),
])
def test_friction_variant_changes_the_contact_friction(body_name, variant, feet, factor):
    base = _foot_contact_friction(f"{body_name}.run.perfect", feet)
    changed = _foot_contact_friction(f"{body_name}-{variant}.run.perfect", feet)
    np.testing.assert_allclose(changed, factor * base[0])


def test_variant_env_steps_and_keeps_its_id():
    env = LocoEnv.make("Hopper-massdec_25_leg.run.perfect", seed=0)
    assert env.task_id == "Hopper-massdec_25_leg.run.perfect" and env.variant == "massdec_25_leg"
    obs = env.reset()
    for _ in range(30):
        obs, reward, absorbing, info = env.step(np.zeros(3))
        assert np.isfinite(obs).all() and not info["diverged"]


def test_unknown_variant_names_close_matches():
    with pytest.raises(UnknownTaskError) as err:
        parse_task_id("Hopper-massdec_30_leg.run.perfect")
    assert "massdec_25_leg" in str(err.value) or "massdec_50_leg" in str(err.value)
    spec = LocoEnv.make("Hopper.run.perfect").base_spec.copy()
    with pytest.raises(UnknownVariantError) as err:
        apply_variant(spec, "Hopper", "lendec_25_shin")
    assert "lendec_25_" in str(err.value) and "list_variants('Hopper')" in str(err.value)
    with pytest.raises(UnknownVariantError, match="category"):
        parse_variant("Hopper", "heavier_leg")
    with pytest.raises(UnknownVariantError, match="no morphology variants"):
        parse_variant("Ant", "massinc_25_torso")
    with pytest.raises(UnknownTaskError):
        LocoEnv.make("Ant-massinc_25_torso.run.perfect")


def test_parse_variant_describes_the_edit():
    v = parse_variant("Walker2d", "frictiondec_25_feet")
    assert (v.family, v.percent, v.factor) == ("friction", 25, 0.75)
    assert v.targets == ("foot_geom", "foot_left_geom")
