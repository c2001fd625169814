"""Shared fixtures: where setup put the generated models (scripts/setup.sh)."""
import os

import pytest

from unitac_tools import schema


@pytest.fixture(scope="session")
def models():
    """`$UNITAC_MODELS`, else the repository's .build/models: the trained models the tests
    check. Missing is a failure, not a skip: scripts/test runs these tests after setup."""
    d = os.environ.get("UNITAC_MODELS") or os.path.join(schema.ROOT, ".build", "models")
    if not os.path.isdir(d):
        pytest.fail(f"{d}: no generated models (run scripts/setup.sh first)")
    return d
