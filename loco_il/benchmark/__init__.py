"""Leaderboard protocols: a YAML file names the tasks, algorithms, budgets, seeds and evaluation settings of a
leaderboard; `python -m loco_il.benchmark run <protocol>` runs or resumes its missing runs through train.py's Hydra
multirun, `table` writes the leaderboard from the finished runs. docs/leaderboard.md describes both.

Modules, one job each: `protocol` (reading and checking a protocol), `cells` (the grid and its selections),
`status` (where each run stands), `availability` (whether a cell's dataset can be built), `commands` (train.py
command lines and their grouping into sweeps), `launch` (running the sweeps), `table` and `curves` (the
leaderboard, with `loco_il.evaluation.leaderboard`'s statistics), `cost` (estimated compute), `paths`.
"""
from loco_il.benchmark.cells import Cell, Selection, select
from loco_il.benchmark.protocol import Protocol, ProtocolError, load_protocol

__all__ = ["Cell", "Selection", "select", "Protocol", "ProtocolError", "load_protocol"]
