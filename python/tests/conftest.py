"""Shared fixtures: the cantilever case precomputed once from Python and once by the ``ves``
command, so that tests compare the two."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

import ves

REPO = Path(__file__).resolve().parents[2]
CANTILEVER = REPO / "cases" / "cantilever" / "scene.toml"


def ves_command() -> Path:
    """The ``ves`` binary of this checkout (VES_BIN overrides): the reference the package is
    compared with. scripts/test builds it before running pytest."""
    path = Path(os.environ.get("VES_BIN", REPO / "target" / "release" / "ves"))
    if not os.access(path, os.X_OK):
        pytest.fail(f"{path}: no ves binary; build it with `cargo build --release -p ves-pipeline` or set VES_BIN")
    return path


@pytest.fixture(scope="session")
def cli():
    return ves_command()


@pytest.fixture(scope="session")
def work(tmp_path_factory):
    return tmp_path_factory.mktemp("ves")


@pytest.fixture(scope="session")
def cantilever(work):
    """The cantilever precomputed through the package."""
    return ves.precompute(CANTILEVER, work / "py.h5", progress=False)


@pytest.fixture(scope="session")
def cantilever_cli(cli, work):
    """The same scene precomputed by ``ves precompute --json``: (basis path, JSON summary)."""
    out = work / "cli.h5"
    run = subprocess.run(
        [str(cli), "precompute", str(CANTILEVER), "-o", str(out), "--json"],
        capture_output=True,
        text=True,
        check=True,
    )
    return out, json.loads(run.stdout.strip().splitlines()[-1])
