"""`table` on finished-run folders written here: the cells' rows with their statistics and commands, the scores along
the way, the missing and blocked runs, the CSV, the figures; and where each run stands (`status`)."""
from __future__ import annotations

import csv
import io
import math

import pytest
from benchmark_fixtures import finished_run, tiny_protocol, write_protocol

from loco_il.benchmark import __main__ as cli
from loco_il.benchmark import cost
from loco_il.benchmark.cells import select
from loco_il.benchmark.protocol import load_protocol
from loco_il.benchmark.status import FINISHED, NEW, OVER, RUNNING, UNFINISHED, run_state
from loco_il.benchmark.table import results_of, score_at, steps_label
from loco_il.evaluation import leaderboard
from loco_il.experiment.lock import run_dir_lock

T95_2 = 4.302652729911275       # Student-t 0.975 quantile, 2 degrees of freedom


def _ci(values):
    mean = sum(values) / len(values)
    sd = math.sqrt(sum((v - mean) ** 2 for v in values) / (len(values) - 1))
    return T95_2 * sd / math.sqrt(len(values))


def test_run_states(grid):
    path, logs, _ = grid
    cells = {c.key: c for c in select(load_protocol(path))}
    gail, bc, vail = cells["Hopper.run.perfect/gail"], cells["Hopper.run.perfect/bc"], cells["Hopper.run.perfect/vail"]
    assert run_state(gail, 0, logs).state == FINISHED and run_state(gail, 0, logs).step == 300
    assert (run_state(bc, 2, logs).state, run_state(bc, 2, logs).step) == (UNFINISHED, 20)
    assert "resumes at step 20 of 50" in run_state(bc, 2, logs).describe()
    assert run_state(vail, 0, logs).state == OVER and run_state(vail, 1, logs).state == NEW
    # an eval.json of another algorithm's run in the folder does not count
    other = cells["Hopper.run.perfect/lsiq"]
    finished_run(other.run_dir(logs, 0), "Hopper.run.perfect", "lsiq_other", 0, 200, 0.1, 1.0, [])
    assert run_state(other, 0, logs).state == UNFINISHED
    # a run dir that a train.py process holds is running: `run` leaves it to that process
    with run_dir_lock(bc.run_dir(logs, 2)):
        assert run_state(bc, 2, logs).state == RUNNING and "running now" in run_state(bc, 2, logs).describe()
    assert run_state(bc, 2, logs).state == UNFINISHED


def test_table_rows_statistics_and_commands(grid, capsys):
    path, logs, out = grid
    assert cli.main(["table", str(path), "--results-dir", str(logs), "--out", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    md = (out / "tiny.md").read_text()
    ci = _ci([0.8, 0.9, 1.0])
    cmd = (f"python train.py -m task=Hopper.run.perfect algo=gail seed=0,1,2 n_steps=300 eval.every=100 "
           f"eval.episodes=5 eval.final_episodes=10 logger=csv results_dir={logs}")
    assert (f"| Hopper.run.perfect | gail | 300 env steps | 3/3 | 0.90 ± {ci:.2f} | 0.30 ± {ci:.2f} | "
            f"0.60 ± {ci:.2f} | 900.0 ± {1000 * ci:.1f} | n/a | `{cmd}` |") in md
    assert "None exists for LocoMuJoCo's tasks" in md.split("## Part")[0]
    assert "| Hopper.run.perfect | bc | 50 gradient steps | 2/3 | 1.00 ± " in md and "| — | — | 3000.5 ± " in md
    assert "| UnitreeH1.walk.real | gail | 300 env steps | 1/3 | 523.4 (return) | 40.0 (return) | 60.0 (return) |" in md
    missing = md.split("## Missing runs")[1].split("## Settings")[0]
    # each missing cell carries its estimated single-core hours: the cost model's per-run figure x missing seeds
    cells = {c.key: c for c in select(load_protocol(path))}
    bc_hours, h1_hours = (cost.run_hours(load_protocol(path), cells[k])
                          for k in ("Hopper.run.perfect/bc", "UnitreeH1.walk.real/gail"))
    # the table reads results alone: bc seed 2's local checkpoint (step 20) and a live lock do not show
    row = (f"| Hopper.run.perfect | bc | 2 | not finished | {cost.hours_text(bc_hours)} | "
           f"`python train.py -m task=Hopper.run.perfect algo=bc seed=2 ")
    assert row in missing and "resumes at step" not in missing
    with run_dir_lock(cells["Hopper.run.perfect/bc"].run_dir(logs, 2)):
        assert cli.main(["table", str(path), "--results-dir", str(logs), "--out", str(out)]) == 0
        assert (out / "tiny.md").read_text() == md
    # the live state is `run`'s to say
    capsys.readouterr()
    assert cli.main(["run", str(path), "--results-dir", str(logs), "--tasks", "Hopper.run.perfect", "--algos", "bc",
                     "--dry-run"]) == 0
    assert "[benchmark] resumes Hopper.run.perfect/bc seed 2: unfinished, resumes at step 20 of 50" in \
        capsys.readouterr().out
    assert f"| UnitreeH1.walk.real | gail | 1 2 | not finished | {cost.hours_text(2 * h1_hours)} |" in missing
    total = sum(len(r.missing) * cost.run_hours(load_protocol(path), r.cell)
                for r in results_of(load_protocol(path), list(cells.values()), logs))
    assert f"runs, ~{cost.hours_text(total)} single-core hours by the cost model" in missing
    assert "past the budget 300" in missing and "seeds 1 2: not finished" in missing   # vail seed 0 trained to 5000
    assert ("| UnitreeH1.run.perfect | gail, vail, lsiq, lsiq_twin, bc | no expert for UnitreeH1.run" in missing
            and f"`python -m loco_il.benchmark run {path} --tasks UnitreeH1.run.perfect` |" in missing)
    assert "Hopper.run.perfect | gail |" not in missing
    assert "## Estimated cost" in md and "of these, blocked until their dataset exists: 15 runs" in md
    assert sorted(p.name for p in (out / "curves" / "tiny").iterdir()) == ["Hopper.run.perfect.png",
                                                                           "UnitreeH1.walk.real.png"]
    assert "[Hopper.run.perfect](curves/tiny/Hopper.run.perfect.png)" in md


def test_a_published_score_is_shown_beside_its_row_with_its_source(grid, tmp_path, monkeypatch):
    path, logs, out = grid
    published = tmp_path / "published.yaml"
    published.write_text("entries:\n  - {task: Hopper.run, dataset: perfect, algorithm: gail, value: '0.93 normalized',"
                         " source: 'Paper 2020, Table 2'}\n")
    monkeypatch.setattr(leaderboard, "PUBLISHED_FILE", published)
    cli.main(["table", str(path), "--results-dir", str(logs), "--out", str(out), "--no-plots"])
    md = (out / "tiny.md").read_text()
    gail_row = next(line for line in md.splitlines() if line.startswith("| Hopper.run.perfect | gail |"))
    bc_row = next(line for line in md.splitlines() if line.startswith("| Hopper.run.perfect | bc |"))
    assert "| 0.93 normalized (Paper 2020, Table 2) | `python train.py" in gail_row
    assert "| n/a | `python train.py" in bc_row
    rows = {(r["task"], r["algorithm"]): r for r in csv.DictReader(io.StringIO((out / "tiny.csv").read_text()))}
    assert rows[("Hopper.run.perfect", "gail")]["published"] == "0.93 normalized"


def test_table_csv(grid):
    path, logs, out = grid
    cli.main(["table", str(path), "--results-dir", str(logs), "--out", str(out), "--no-plots"])
    rows = {(r["task"], r["algorithm"]): r for r in csv.DictReader(io.StringIO((out / "tiny.csv").read_text()))}
    assert len(rows) == 11
    assert {k: r["status"] for k, r in rows.items() if r["status"] != "blocked"} == {
        ("Hopper.run.perfect", "gail"): "complete", ("Hopper.run.perfect", "bc"): "partial",
        ("Hopper.run.perfect", "vail"): "missing", ("Hopper.run.perfect", "lsiq"): "missing",
        ("Hopper.run.perfect", "lsiq_twin"): "missing", ("UnitreeH1.walk.real", "gail"): "partial"}
    gail = rows[("Hopper.run.perfect", "gail")]
    assert (gail["final_mean"], gail["at_100_mean"], gail["at_100_n"], gail["at_200_mean"]) == (
        "0.9000", "0.3000", "3", "0.6000")
    assert float(gail["at_100_ci95"]) == pytest.approx(_ci([0.2, 0.3, 0.4]), abs=1e-4)
    assert gail["seeds_finished"] == "0 1 2" and gail["metric"] == "normalized"
    assert rows[("UnitreeH1.walk.real", "gail")]["metric"] == "return"
    assert rows[("UnitreeH1.walk.real", "gail")]["missing_seeds"] == "1 2"
    assert rows[("UnitreeH1.run.perfect", "bc")]["blocked"].startswith("no expert for UnitreeH1.run")
    assert not (out / "curves").exists()


def test_finished_runs_seed_by_seed(grid):
    """Each finished cell's seeds: final score, falls, episode lengths, wall-time range per device, in the page and
    the CSV; what a run's eval.json does not hold is "?" (page) or "nan" (CSV), never a guess."""
    path, logs, out = grid
    cli.main(["table", str(path), "--results-dir", str(logs), "--out", str(out), "--no-plots"])
    md = (out / "tiny.md").read_text()
    section = md.split("## Finished runs, seed by seed")[1].split("## Missing runs")[0]
    rows = [line for line in section.splitlines() if line.startswith("| ") and not line.startswith("| task")]
    assert rows == [
        "| Hopper.run.perfect | gail | 0 1 2 | 0.80, 0.90, 1.00 | 3, 0, 1 | 812, 1000, 956 | 1200-1311 s, 95 s (cuda) |",
        "| Hopper.run.perfect | bc | 0 1 | 0.95, 1.05 | ?, 2/8 | ?, 700 | ? |",
        "| UnitreeH1.walk.real | gail | 0 | 523.4 (return) | ? | ? | ? |"]
    assert "of 10)" in section       # the protocol's final_episodes
    table_rows = {(r["task"], r["algorithm"]): r for r in csv.DictReader(io.StringIO((out / "tiny.csv").read_text()))}
    gail = table_rows[("Hopper.run.perfect", "gail")]
    assert (gail["final_per_seed"], gail["falls_per_seed"], gail["length_per_seed"], gail["wall_time_per_seed"],
            gail["device_per_seed"]) == ("0.8000 0.9000 1.0000", "3 0 1", "812.4 1000.0 955.5", "1200.4 1310.6 95.2",
                                         "cpu cpu cuda")
    assert table_rows[("Hopper.run.perfect", "bc")]["episodes_per_seed"] == "nan 8"
    assert table_rows[("Hopper.run.perfect", "vail")]["final_per_seed"] == ""      # no finished run


def test_score_along_the_way_is_the_first_evaluation_at_or_after_the_step():
    rows = [{"step": 50.0, "normalized_score": 0.1}, {"step": 104.0, "normalized_score": 0.4},
            {"step": 208.0, "normalized_score": 0.6}]
    assert score_at(rows, 100, 100, "normalized") == 0.4
    assert score_at(rows, 300, 100, "normalized") is None          # the run stopped before it
    assert score_at(rows, 100, 4, "normalized") is None            # no evaluation within the interval
    assert [steps_label(s) for s in (100, 100_000, 1_500_000, 40_000_000, 1234)] == ["100", "100k", "1.5M", "40M",
                                                                                    "1234"]


def test_overview_matrix_in_the_table_and_the_readme(grid):
    path, logs, out = grid
    doc = tiny_protocol()
    doc["parts"]["real"]["algorithms"] = ["gail", "vail"]
    write_protocol(path.parent, "tiny", doc)
    finished_run(logs / "UnitreeH1.walk.real" / "vail" / "seed0", "UnitreeH1.walk.real", "vail", 0, 300, None,
                 80.0, [(300, None, 80.0)])
    readme = out.parent / "README.md"
    readme.write_text("# Title\n\n<!-- leaderboard:tiny -->\nstale table\n<!-- /leaderboard:tiny -->\n\nafter\n")
    assert cli.main(["table", str(path), "--results-dir", str(logs), "--out", str(out), "--no-plots",
                     "--readme", str(readme)]) == 0
    text = readme.read_text()
    assert text.startswith("# Title\n\n<!-- leaderboard:tiny -->\n| task | gail | vail | bc |\n")
    assert "stale table" not in text and text.endswith("<!-- /leaderboard:tiny -->\n\nafter\n")
    ci = _ci([0.8, 0.9, 1.0])
    # a complete cell, a cell not run yet (Hopper vail: empty), partial cells with their seed counts, a cell
    # outside its part (BC on real data: n/a)
    assert f"| Hopper.run.perfect | 0.90 ± {ci:.2f} |  | 1.00 ± " in text and "(2/3 seeds) |" in text
    assert "| UnitreeH1.walk.real | 523.4 (return) (1/3 seeds) | 80.0 (return) (1/3 seeds) | n/a |" in text
    md = (out / "tiny.md").read_text()
    block = text.split("<!-- leaderboard:tiny -->\n")[1].split("<!-- /leaderboard:tiny -->")[0]
    assert "## Overview\n\n" + block in md


def test_readme_without_markers_is_refused_before_anything_is_written(grid, capsys):
    path, logs, out = grid
    readme = out.parent / "README.md"
    readme.write_text("# Title\n<!-- /leaderboard:tiny -->\n<!-- leaderboard:tiny -->\n")
    assert cli.main(["table", str(path), "--results-dir", str(logs), "--out", str(out), "--no-plots",
                     "--readme", str(readme)]) == 2
    err = capsys.readouterr().out
    assert "has no '<!-- leaderboard:tiny -->' ... '<!-- /leaderboard:tiny -->' block" in err
    assert readme.read_text() == "# Title\n<!-- /leaderboard:tiny -->\n<!-- leaderboard:tiny -->\n"
    assert not out.exists()
    assert cli.main(["table", str(path), "--results-dir", str(logs), "--out", str(out), "--readme",
                     str(out.parent / "missing.md")]) == 2
    assert "no such file" in capsys.readouterr().out


STALE = "stale leaderboard table: python -m loco_il.benchmark table small --readme README.md"


@pytest.fixture(scope="module")
def committed_small():
    """The `small` protocol, its cells and their results from the committed logs (read once for the tests below)."""
    proto = load_protocol("small")
    cells = select(proto)
    return proto, cells, results_of(proto, cells, proto.results_dir)


def test_the_readme_table_is_the_one_the_committed_logs_give(committed_small):
    """Adding runs to benchmarks/leaderboard/logs/ without `table small --readme README.md` fails here."""
    from loco_il.benchmark import overview, paths
    proto, _, results = committed_small
    readme = (paths.ROOT / "README.md").read_text()
    assert overview.replace_block(readme, "small", overview.matrix(proto, results), "README.md") == readme, STALE


def test_the_committed_tables_are_the_ones_the_committed_logs_give(committed_small):
    """small.md (its seed-by-seed section included) and small.csv are derived state: adding or changing runs in
    benchmarks/leaderboard/logs/ without `table small` fails here."""
    from loco_il.benchmark import overview, paths, table
    proto, cells, results = committed_small
    figures = {p.stem: str(p.relative_to(paths.TABLE_DIR))
               for p in (paths.TABLE_DIR / "curves" / proto.name).glob("*.png")}
    fresh_md = cli.table_page(proto, cells, results, figures, proto.results_dir, overview.matrix(proto, results))
    assert (paths.TABLE_DIR / "small.md").read_text() == fresh_md, STALE
    assert (paths.TABLE_DIR / "small.csv").read_text() == table.to_csv(proto, results), STALE
