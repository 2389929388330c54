"""Shared fixtures of the binding's tests: the repository's root and the `robopost` command
line, against which the binding's results are checked (an independent path to the same
numbers: the CLI reads the CSV file itself, the binding gets numpy arrays)."""

import json
import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _robopost_binary() -> pathlib.Path:
    given = os.environ.get("ROBOPOST_BIN")
    if given:
        return pathlib.Path(given)
    meta = subprocess.run(
        ["cargo", "metadata", "--format-version", "1", "--no-deps"],
        cwd=ROOT,
        check=True,
        capture_output=True,
        text=True,
    )
    return pathlib.Path(json.loads(meta.stdout)["target_directory"]) / "debug" / "robopost"


@pytest.fixture(scope="session")
def root() -> pathlib.Path:
    return ROOT


@pytest.fixture(scope="session")
def cli():
    """Runs the `robopost` command (ROBOPOST_BIN, else the one `cargo test` builds)."""
    binary = _robopost_binary()
    if not binary.is_file():
        pytest.fail(f"no robopost binary at {binary}: run `cargo test` (or `cargo build`) first, or set ROBOPOST_BIN")

    def run(*args, cwd=ROOT):
        done = subprocess.run([str(binary), *map(str, args)], cwd=cwd, capture_output=True)
        assert done.returncode == 0, done.stderr.decode(errors="replace")
        return done

    return run
