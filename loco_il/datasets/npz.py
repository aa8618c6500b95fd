"""Reading the `.npz` files of datasets (`Trajectories`) and of their initial states (`InitStates`).

Both loaders report every problem the same way: a `DatasetError` that names the file, says what is wrong
with it and how to rebuild it (`regenerate_hint`).
"""
from __future__ import annotations

import json
import os
import zipfile
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from loco_il.utils.errors import DatasetError

#: Hint appended to load errors when the caller gives none.
DEFAULT_REGENERATE_HINT = "delete it and call env.create_dataset() again to regenerate it"
#: What reading a damaged or truncated archive raises (anything else is a bug, not a bad file).
READ_ERRORS = (OSError, EOFError, ValueError, KeyError, zipfile.BadZipFile, json.JSONDecodeError)

LoadError = Callable[[str], DatasetError]


def load_error(path: str | os.PathLike, what: str, regenerate_hint: str | None = None) -> LoadError:
    """``fail(reason) -> DatasetError``: "cannot load <what> '<path>': <reason>. To fix this, <hint>."."""
    hint = regenerate_hint or DEFAULT_REGENERATE_HINT

    def fail(reason: str) -> DatasetError:
        return DatasetError(f"cannot load {what} '{path}': {reason}. To fix this, {hint}.")

    return fail


@contextmanager
def read_npz(path: Path, fail: LoadError) -> Iterator[np.lib.npyio.NpzFile]:
    """The opened archive (no pickles) for reading inside the ``with`` block. A missing file, and any read
    error of a truncated or corrupt one (in the block too), becomes ``fail(...)``; a `DatasetError` raised
    in the block passes unchanged."""
    if not path.is_file():
        raise fail("the file does not exist")
    try:
        with np.load(path, allow_pickle=False) as archive:
            yield archive
    except DatasetError:
        raise
    except READ_ERRORS as exc:
        raise fail(f"the file is truncated or corrupt ({type(exc).__name__}: {exc})") from exc


__all__ = ["DEFAULT_REGENERATE_HINT", "READ_ERRORS", "load_error", "read_npz"]
