"""Fixtures of the Python package's tests: the `softjoint` program they
compare with (an independent path: the CLI as a subprocess, its CSV and
JSON files), the repository's files, and a law cache of their own."""
import json
import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DATA = REPO / "scenarios"


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


@pytest.fixture(scope="session")
def data() -> Path:
    return DATA


@pytest.fixture(scope="session", autouse=True)
def law_cache(tmp_path_factory):
    """Fitted estimation laws cached in a directory of the test session's
    own, shared by the package and the program it is compared with."""
    d = tmp_path_factory.mktemp("law-cache")
    os.environ["SOFTJOINT_CACHE_DIR"] = str(d)
    return d


@pytest.fixture(scope="session")
def softjoint_bin() -> str:
    """The program: $SOFTJOINT_BIN, or the workspace's ci-opt build
    (`cargo build --profile ci-opt -p host-tools --bin softjoint`)."""
    b = os.environ.get("SOFTJOINT_BIN") or str(REPO / "target" / "ci-opt" / "softjoint")
    if not Path(b).is_file():
        pytest.fail(f"no softjoint program at {b}: build it "
                    "(cargo build --profile ci-opt -p host-tools --bin softjoint) or set SOFTJOINT_BIN")
    return b


def run_cli(binary, *args, cwd=None, ok=True):
    p = subprocess.run([binary, *map(str, args)], capture_output=True, text=True, cwd=cwd)
    if ok and p.returncode != 0:
        raise AssertionError(f"softjoint {' '.join(map(str, args))} exited {p.returncode}: {p.stderr}")
    return p


def cli_json(binary, *args, cwd=None):
    return json.loads(run_cli(binary, *args, cwd=cwd).stdout)
