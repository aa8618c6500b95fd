"""Fixtures of the reliability tests: the stand-in expert's environment, folders that cannot be written."""
from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
from train_helpers import make_env_vars  # tests/ is on sys.path


@pytest.fixture(scope="module")
def env_vars(tmp_path_factory) -> dict:
    return make_env_vars(tmp_path_factory.mktemp("reliability"))


def read_only(command: list[str], folders: list[Path]) -> list[str]:
    """`command` run with `folders` unwritable. A non-root user gets them chmod-ed to 0555 by the caller's
    `make_read_only`; root writes through permissions, so for root the folders are bind-mounted read-only
    in a private mount namespace (unshare -m), as on a read-only filesystem."""
    if os.geteuid() != 0:
        return command
    mounts = " && ".join(f"mount --bind -o ro '{f}' '{f}'" for f in folders)
    return ["unshare", "-m", "sh", "-c", f'{mounts} && exec "$@"', "sh", *command]


@pytest.fixture
def make_read_only():
    """Make folders unwritable for the test's subprocesses (see `read_only`); restored afterwards."""
    changed: list[Path] = []

    def apply(folder: Path) -> Path:
        folder.mkdir(parents=True, exist_ok=True)
        if os.geteuid() == 0:
            if shutil.which("unshare") is None or subprocess.run(
                    read_only(["true"], [folder]), capture_output=True).returncode != 0:
                pytest.skip("root without mount namespaces cannot make a folder read-only here")
        else:
            folder.chmod(0o555)
            changed.append(folder)
        return folder

    yield apply
    for folder in changed:
        folder.chmod(0o755)
