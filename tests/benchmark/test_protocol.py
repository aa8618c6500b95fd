"""Protocol files: the shipped ones load and expand to the documented grid; every mistake is one line that names
the problem and the fix."""
from __future__ import annotations

import pytest

from loco_il.benchmark import paths
from loco_il.benchmark.cells import Selection, all_cells, select
from loco_il.benchmark.protocol import ProtocolError, load_protocol
from benchmark_fixtures import tiny_protocol, write_protocol


def test_small_protocol_is_the_documented_grid():
    proto = load_protocol("small")
    assert proto.seeds == (0, 1, 2)
    assert proto.results_dir == paths.LOGS_DIR / "small"
    by_part = {p.name: p for p in proto.parts}
    assert by_part["real"].labels == ("gail", "vail", "gaifo", "lsiqfo")
    assert set(by_part["real"].tasks) == {"Atlas.walk", "UnitreeH1.walk", "UnitreeG1.walk", "Talos.walk",
                                          "HumanoidTorque.walk", "UnitreeA1.simple", "UnitreeA1.hard"}
    assert set(by_part["perfect"].labels) == {"gail", "vail", "gaifo", "iqlearn", "lsiq", "sqil", "bc",
                                              "lsiq_mixture_2critics_ln"}
    assert {"Hopper.run", "Walker2d.run", "HalfCheetah.run", "Ant.run", "Humanoid.run", "UnitreeA1.simple",
            "Atlas.walk", "Talos.walk", "UnitreeG1.walk", "HumanoidTorque.walk", "UnitreeH1.walk"} == set(by_part["perfect"].tasks)
    cells = all_cells(proto)
    assert len(cells) == 7 * 4 + 11 * 8 + 11 * 8
    assert {c.family.name: c.budget for c in cells} == {"onpolicy": 1_000_000, "sac": 200_000, "offline": 100_000}
    held = next(c for c in cells if c.label == "lsiq_mixture_2critics_ln")
    assert held.algo == "lsiq" and dict(held.overrides)["algo.params.critic_layer_norm"] is True


def test_paper_protocol_takes_small_grid_at_the_papers_budgets():
    small, paper = load_protocol("small"), load_protocol("paper")
    assert [(p.name, p.tasks, p.labels) for p in paper.parts] == [(p.name, p.tasks, p.labels) for p in small.parts]
    assert paper.family_of("gail").n_steps == 40_000_000 and paper.family_of("vail").n_steps == 40_000_000
    assert {paper.family_of(a).n_steps for a in ("iqlearn", "lsiq", "lsiqfo", "sqil")} == {1_500_000}
    assert paper.family_of("bc").n_steps == small.family_of("bc").n_steps
    assert paper.results_dir == paths.LOGS_DIR / "paper"      # a base protocol's run dirs are not inherited
    assert paper.family_of("bc").report_at == ()              # gradient steps: no env-step report points
    assert paper.family_of("lsiq").report_at == (100_000, 200_000, 1_000_000, 1_500_000)


def _error(tmp_path, **changes) -> str:
    path = write_protocol(tmp_path, "bad", tiny_protocol(**changes))
    with pytest.raises(ProtocolError) as info:
        load_protocol(path)
    message = str(info.value)
    assert "\n" not in message
    return message


def test_unknown_task_names_it_the_closest_task_and_the_listing_command(tmp_path):
    parts = {"real": {"dataset": "real", "tasks": ["UnitreeH1.wlak"], "algorithms": ["gail"]}}
    message = _error(tmp_path, parts=parts)
    assert "unknown task 'UnitreeH1.wlak'" in message and "did you mean UnitreeH1.walk.real" in message
    assert "get_all_task_names" in message


def test_unknown_algorithm_names_it_and_the_fix(tmp_path):
    parts = {"real": {"dataset": "real", "tasks": ["UnitreeH1.walk"], "algorithms": ["gial"]}}
    message = _error(tmp_path, parts=parts)
    assert "unknown algorithm 'gial'" in message and "did you mean gail" in message and "families" in message
    families = {"onpolicy": {"algos": ["trpo"], "n_steps": 10, "eval_every": 10}}
    assert "unknown algorithm 'trpo'" in _error(tmp_path, families=families)


def test_algorithm_that_cannot_learn_from_the_dataset_type(tmp_path):
    parts = {"real": {"dataset": "real", "tasks": ["UnitreeH1.walk"], "algorithms": ["bc"]}}
    assert "bc cannot learn from 'real' datasets" in _error(tmp_path, parts=parts)


@pytest.mark.parametrize("changes, expected", [
    ({"seeds": [0, 0]}, "repeat a seed"),
    ({"seeds": []}, "seeds must be a non-empty list"),
    ({"report_at": [150]}, "report_at 150 is not a multiple of families.onpolicy.eval_every"),
    ({"eval": {"every": 5}}, "eval.every is set per family"),
    ({"overrides": {"n_steps": 5}}, "sets 'n_steps', which the protocol itself decides"),
    ({"tasks": ["Hopper.run"]}, "unknown key 'tasks'"),
    ({"variants": {"gail": {"algo": "gail"}}}, "is an algorithm's name"),
])
def test_malformed_protocols(tmp_path, changes, expected):
    assert expected in _error(tmp_path, **changes)


def test_algorithm_in_two_families(tmp_path):
    families = tiny_protocol()["families"]
    families["offline"]["algos"] = ["bc", "gail"]
    assert "'gail' is in families onpolicy and offline" in _error(tmp_path, families=families)


def test_task_file_that_tunes_an_algorithm_is_refused(tmp_path):
    """experiment_configs/task/InvertedPendulum.balance.perfect.yaml tunes bc: a protocol runs defaults only."""
    parts = {"p": {"dataset": "perfect", "tasks": ["InvertedPendulum.balance"], "algorithms": ["bc"]}}
    message = _error(tmp_path, parts=parts)
    assert "InvertedPendulum.balance.perfect.yaml tunes bc" in message and "drop the task" in message


def test_unknown_protocol_lists_the_known_ones():
    with pytest.raises(ProtocolError, match="unknown protocol 'smal'; known: .*paper, small"):
        load_protocol("smal")


def test_base_protocol_is_merged_and_cycles_are_refused(tmp_path):
    write_protocol(tmp_path, "parent", tiny_protocol(results_dir="elsewhere"))
    child = write_protocol(tmp_path, "child", {"base": str(tmp_path / "parent.yaml"), "seeds": [4],
                                               "families": {"sac": {"n_steps": 400}}})
    proto = load_protocol(child)
    assert proto.seeds == (4,) and proto.family_of("lsiq").n_steps == 400 and proto.family_of("lsiq").eval_every == 100
    assert proto.results_dir == paths.LOGS_DIR / "child"
    write_protocol(tmp_path, "a", {"base": "b.yaml"})             # relative: next to the protocol naming it
    write_protocol(tmp_path, "b", {"base": str(tmp_path / "a.yaml")})
    with pytest.raises(ProtocolError, match="form a cycle"):
        load_protocol(tmp_path / "a.yaml")


def test_cell_expansion_and_selection(tmp_path):
    proto = load_protocol(write_protocol(tmp_path, "tiny", tiny_protocol()))
    cells = select(proto)
    assert [c.key for c in cells] == [
        "Hopper.run.perfect/gail", "Hopper.run.perfect/vail", "Hopper.run.perfect/lsiq",
        "Hopper.run.perfect/lsiq_twin", "Hopper.run.perfect/bc", "UnitreeH1.run.perfect/gail",
        "UnitreeH1.run.perfect/vail", "UnitreeH1.run.perfect/lsiq", "UnitreeH1.run.perfect/lsiq_twin",
        "UnitreeH1.run.perfect/bc", "UnitreeH1.walk.real/gail"]
    assert cells[0].run_dir(tmp_path, 2) == tmp_path / "Hopper.run.perfect" / "gail" / "seed2"
    assert cells[4].budget_label == "50 gradient steps" and cells[0].budget_label == "300 env steps"
    picked = select(proto, Selection(tasks=("Hopper.run",), algos=("lsiq",), seeds=(1,)))
    assert [(c.key, c.seeds) for c in picked] == [("Hopper.run.perfect/lsiq", (1,)),
                                                  ("Hopper.run.perfect/lsiq_twin", (1,))]
    assert [c.key for c in select(proto, Selection(datasets=("real",)))] == ["UnitreeH1.walk.real/gail"]
    assert [c.key for c in select(proto, Selection(tasks=("UnitreeH1.run.perfect",), algos=("lsiq_twin",)))] == [
        "UnitreeH1.run.perfect/lsiq_twin"]
    with pytest.raises(ProtocolError, match="no task 'Walker2d.run' in protocol tiny"):
        select(proto, Selection(tasks=("Walker2d.run",)))
    with pytest.raises(ProtocolError, match="no seed 7 in protocol tiny; its seeds: 0, 1, 2"):
        select(proto, Selection(seeds=(7,)))
