"""Shared test fixtures and paths."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "configs"
DATA = Path(__file__).resolve().parent / "data"
BAD = DATA / "bad"


@pytest.fixture
def bad_dir() -> Path:
    """Folder of deliberately broken config files (``tests/data/bad``)."""
    return BAD


@pytest.fixture
def cli_runner():
    """A typer CliRunner; ``result.stdout`` and ``result.stderr`` are kept apart."""
    from typer.testing import CliRunner

    return CliRunner()
