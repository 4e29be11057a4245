"""Fixtures shared by the test files: the smoke reproduction and its shipped copy, each built once
per session (`pipeline_smoke.py` says what they hold)."""

from __future__ import annotations

import pytest
from pipeline_smoke import shipped_smoke, smoke_output


@pytest.fixture(scope="session")
def smoke(tmp_path_factory):
    return smoke_output(tmp_path_factory)


@pytest.fixture(scope="session")
def shipped(tmp_path_factory):
    return shipped_smoke(tmp_path_factory)
