"""Shared fixtures of the locap Python tests.

The tests compare the package with the `locap` binary built from the same checkout
(`target/release/locap`: `cargo build --release -p locap`) and read the shared capture data at
`../shared/data` beside the repository. Under CI (env `CI` set) a missing binary or data folder
fails the tests; elsewhere they are skipped with a message, like the Rust tests.
"""

import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
EXAMPLE = REPO / "examples" / "cmu_01_01_last10s.c3d"
SHARED = REPO.parent / "shared" / "data"


def _missing(what: str):
    if os.environ.get("CI"):
        pytest.fail(f"{what} (required under CI)")
    pytest.skip(f"skipping: {what}")


@pytest.fixture(scope="session")
def cli() -> Path:
    """The `locap` binary of this checkout."""
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    binary = target / "release" / "locap"
    if not binary.is_file():
        _missing(f"{binary} not found: cargo build --release -p locap")
    return binary


@pytest.fixture(scope="session")
def shared() -> Path:
    """The shared capture data."""
    if not SHARED.is_dir():
        _missing(f"{SHARED} not found")
    return SHARED


def run_cli(cli: Path, *args, check: bool = True) -> subprocess.CompletedProcess:
    """Runs the CLI; returns the finished process (stdout and stderr as text)."""
    done = subprocess.run([str(cli), *map(str, args)], capture_output=True, text=True, cwd=REPO)
    if check and done.returncode != 0:
        raise AssertionError(f"locap {' '.join(map(str, args))} failed ({done.returncode}):\n{done.stderr}")
    return done
