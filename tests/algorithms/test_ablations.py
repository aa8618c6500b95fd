"""The ablations of the SAC-based learners: flat `algo.params` keys gathered into one `Ablations` argument."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from mushroom_rl.core import MDPInfo
from mushroom_rl.utils.spaces import Box

from loco_il.algorithms.common.ablations import ABLATION_NAMES, Ablations, split_ablations
from loco_il.algorithms.common.agent_base import ILAgent
from loco_il.algorithms.factory import agent_kwargs, build_agent, get_algorithm

OBS_DIM, ACT_DIM = 3, 2
SMALL = {"policy": {"hidden": [8]}, "params": {"critic_hidden": [8], "initial_replay_size": 16, "batch_size": 8,
                                                "expert_batch_size": 8, "replay_capacity": 100}}


def _mdp_info() -> MDPInfo:
    return MDPInfo(Box(-np.ones(OBS_DIM), np.ones(OBS_DIM)), Box(-np.ones(ACT_DIM), np.ones(ACT_DIM)), 0.99, 100)


def _config(name: str, **params) -> dict:
    small = SMALL["params"] if name in ("lsiq", "sqil") else {}   # the SAC-based learners' small networks
    return {"name": name, "policy": SMALL["policy"], "params": {**small, **params}}


def test_every_ablation_is_off_by_default_and_the_names_are_the_fields():
    assert set(ABLATION_NAMES) == {"freeze_replay", "conservative_weight", "conservative_actions",
                                   "conservative_hinge", "actor_bc_alpha", "critic_layer_norm"}
    agent = build_agent("sqil", _mdp_info(), _config("sqil"), seed=0)
    assert agent.ablations == Ablations()


def test_flat_config_keys_reach_the_dataclass():
    cfg = _config("lsiq", conservative_weight=5, conservative_hinge=True, actor_bc_alpha=2.5, critic_lr=1e-4,
                  critic_layer_norm=True)
    kwargs = agent_kwargs(get_algorithm("lsiq"), cfg)
    assert kwargs["ablations"] == Ablations(conservative_weight=5.0, conservative_hinge=True, actor_bc_alpha=2.5,
                                            critic_layer_norm=True)
    assert not set(kwargs) & set(ABLATION_NAMES) and kwargs["critic_lr"] == 1e-4   # the method's own options stay
    agent = build_agent("lsiq", _mdp_info(), cfg, seed=0)
    assert agent.ablations.conservative_weight == 5.0 and isinstance(agent.ablations.conservative_weight, float)
    assert any(isinstance(m, torch.nn.LayerNorm) for m in agent.sac.critic.modules())


@pytest.mark.parametrize("name", ["lsiq", "gail"])
def test_an_unknown_ablation_key_is_a_one_line_error_naming_it(name):
    with pytest.raises(ValueError) as err:
        build_agent(name, _mdp_info(), _config(name, conservative_wieght=1.0), seed=0)
    message = str(err.value)
    assert "conservative_wieght" in message and "\n" not in message
    if name == "lsiq":   # the accepted keys list the ablations as the flat keys a config gives
        assert "conservative_weight" in message and "'ablations'" not in message


def test_an_ablation_for_a_learner_without_ablations_is_refused():
    with pytest.raises(ValueError, match=r"GAIL has no parameter\(s\) \['freeze_replay'\]"):
        build_agent("gail", _mdp_info(), _config("gail", freeze_replay=True), seed=0)


def test_ablations_are_not_a_config_mapping():
    with pytest.raises(ValueError, match=r"no parameter\(s\) \['ablations'\]"):
        build_agent("sqil", _mdp_info(), _config("sqil", ablations={"freeze_replay": True}), seed=0)


def test_values_are_checked_and_cast():
    assert Ablations(conservative_actions=4.0).conservative_actions == 4
    with pytest.raises(ValueError, match="conservative_weight=.*expected a number"):
        Ablations(conservative_weight="much")
    with pytest.raises(ValueError, match="actor_bc_alpha must be > 0"):
        split_ablations({"actor_bc_alpha": -1.0, "tau": 0.01})
    with pytest.raises(dataclasses.FrozenInstanceError):
        Ablations().freeze_replay = True


def test_an_agent_file_with_flat_ablation_arguments_still_loads(tmp_path):
    agent = build_agent("sqil", _mdp_info(), _config("sqil", conservative_weight=2.0), seed=0)
    path = tmp_path / "final_agent.pt"
    agent.save(path)
    data = torch.load(path, weights_only=False)
    flat = dict(data["init_kwargs"])
    flat.update(dataclasses.asdict(flat.pop("ablations")))   # the file layout of the separate keyword arguments
    torch.save(dict(data, init_kwargs=flat), path)
    loaded = ILAgent.load(path)
    assert loaded.ablations == Ablations(conservative_weight=2.0)
    for key, value in agent.policy_module.state_dict().items():
        assert torch.equal(value, loaded.policy_module.state_dict()[key])


def test_train_refuses_an_unknown_ablation_key_in_one_line_before_anything_slow(tmp_path, capsys):
    from loco_il.experiment.runner import run_job
    cfg = {"task_id": "InvertedPendulum.balance.perfect", "name": "lsiq", "seed": 0, "results_dir": str(tmp_path),
           "algo": {"name": "lsiq", "params": {"conservative_wieght": 1.0}}}
    outcome = run_job(cfg, tmp_path / "run")
    assert outcome.code == 2 and "conservative_wieght" in outcome.error and "\n" not in outcome.error
    assert capsys.readouterr().err.count("\n") == 1
    assert not (tmp_path / "run" / "config.yaml").exists()   # refused before the run dir was prepared
