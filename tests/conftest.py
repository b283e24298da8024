import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def shared_data_dir() -> Path:
    """../shared/data next to the repository (override with $QFG_SHARED_DATA)."""
    env = os.environ.get("QFG_SHARED_DATA")
    return Path(env) if env else REPO.parent / "shared" / "data"


@pytest.fixture
def shared_data():
    d = shared_data_dir()
    if not d.exists():
        pytest.skip(f"shared data not present at {d}")
    return d
