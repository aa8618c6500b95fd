"""Plain data: configs and metadata (`loco_il.utils.plain`), run files (`loco_il.utils.fileio`)."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf

from loco_il.utils.fileio import jsonable, read_csv, write_json
from loco_il.utils.plain import UNRESOLVED, to_plain


def test_to_plain_resolves_configs_and_converts_numpy():
    cfg = OmegaConf.create({"a": 1, "b": "${a}", "c": {"d": [1, 2]}})
    assert to_plain(cfg) == {"a": 1, "b": 1, "c": {"d": [1, 2]}}
    meta = {"hidden": (64, 64), "mean": np.arange(2.0), "n": np.int64(3), 7: None, "path": object}
    plain = to_plain(meta)
    assert plain == {"hidden": [64, 64], "mean": [0.0, 1.0], "n": 3, "7": None, "path": str(object)}
    assert type(plain["n"]) is int


def test_to_plain_raises_on_a_missing_value_unless_loose():
    cfg = OmegaConf.create({"task_id": "???", "name": "bc", "algo": {"lr": "${missing}", "n": 2}})
    with pytest.raises(Exception, match="task_id"):
        to_plain(cfg)
    assert to_plain(cfg, loose=True) == {"task_id": UNRESOLVED, "name": "bc", "algo": {"lr": UNRESOLVED, "n": 2}}


def test_jsonable_and_json_files(tmp_path):
    assert jsonable({"loss": torch.tensor(0.5), "nan": math.nan, "x": np.float32(2.0), 3: (1, 2)}) == \
        {"loss": 0.5, "nan": None, "x": 2.0, "3": [1, 2]}
    write_json(tmp_path / "eval.json", {"score": np.float64(0.25), "inf": math.inf})
    assert json.loads((tmp_path / "eval.json").read_text()) == {"score": 0.25, "inf": None}


def test_read_csv(tmp_path):
    (tmp_path / "log.csv").write_text("step,score\n100,0.5\n200,\n")
    assert read_csv(tmp_path / "log.csv") == [{"step": 100.0, "score": 0.5}, {"step": 200.0, "score": None}]
    assert read_csv(tmp_path / "missing.csv") == []
