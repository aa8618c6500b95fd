"""RunLogger's files: log.jsonl keeps every key, log.csv the fixed CSV_COLUMNS, also across a column change."""
from __future__ import annotations

import csv
import json

from loco_il.experiment.logging import CSV_COLUMNS, RunLogger
from loco_il.utils.fileio import read_csv


def test_csv_written_by_an_older_version_is_rewritten_with_the_current_columns(tmp_path):
    old_columns = [c for c in CSV_COLUMNS if c != "normalized_score_ema"]
    old_rows = [{"step": 100, "eval_return_mean": 10.0, "normalized_score": 0.1, "fit/loss": 1.0},
                {"step": 200, "eval_return_mean": 20.0, "normalized_score": 0.2, "fit/loss": 0.5}]
    (tmp_path / "log.jsonl").write_text("".join(json.dumps(r) + "\n" for r in old_rows))
    with open(tmp_path / "log.csv", "w", newline="") as fh:   # as a run resumed from that version left it
        w = csv.DictWriter(fh, fieldnames=old_columns, extrasaction="ignore")
        w.writeheader()
        w.writerows(old_rows)
    logger = RunLogger(tmp_path, progress=False)
    logger.log({"step": 300, "eval_return_mean": 30.0, "normalized_score": 0.3, "normalized_score_ema": 0.35})
    with open(tmp_path / "log.csv", newline="") as fh:
        assert next(csv.reader(fh)) == list(CSV_COLUMNS)
    rows = read_csv(tmp_path / "log.csv")
    assert [r["step"] for r in rows] == [100, 200, 300]
    assert [r["normalized_score"] for r in rows] == [0.1, 0.2, 0.3]
    assert [r.get("normalized_score_ema") for r in rows] == [None, None, 0.35]
    logger.log({"step": 400, "normalized_score": 0.4})          # the current header: a plain append
    assert [r["step"] for r in read_csv(tmp_path / "log.csv")] == [100, 200, 300, 400]
    assert [json.loads(line)["step"] for line in (tmp_path / "log.jsonl").read_text().splitlines()] == [100, 200, 300, 400]
    assert json.loads((tmp_path / "log.jsonl").read_text().splitlines()[0])["fit/loss"] == 1.0


def test_rows_rewritten_on_resume_end_their_lines_like_the_appended_ones(tmp_path):
    # A resume truncates the logs to the checkpoint's step and rewrites log.csv; rows appended after it must not
    # end their lines differently from the rewritten ones (a mixed file diffs as wholly changed).
    logger = RunLogger(tmp_path, progress=False)
    for step in (100, 200, 300):
        logger.log({"step": step, "normalized_score": step / 1000})
    logger.truncate(200)
    RunLogger(tmp_path, progress=False).log({"step": 250, "normalized_score": 0.25})
    lines = (tmp_path / "log.csv").read_bytes().splitlines(keepends=True)
    assert len(lines) == 4                                        # header, 100, 200, 250
    assert {line[-2:] for line in lines} == {b"\r\n"}             # the csv module's line end, on every line
    assert [r["step"] for r in read_csv(tmp_path / "log.csv")] == [100, 200, 250]
