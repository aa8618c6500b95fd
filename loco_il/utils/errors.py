"""Errors shared by several layers of loco_il.

`DatasetError` is raised wherever the data a dataset is made of is missing or unusable: a dataset file
(`loco_il.datasets`), but also the motion-capture files of `loco_il.motion` and the experts of
`loco_il.experts` that the datasets are built from. It is defined here, below those layers, so that
each can raise it and `train.py` reports all of them the same way.
"""
from __future__ import annotations


class DatasetError(ValueError):
    """A dataset is malformed, or a dataset file is missing, corrupt or mismatched."""


__all__ = ["DatasetError"]
