import os
from pathlib import Path

import pytest
from hypothesis import settings

REPO = Path(__file__).resolve().parents[1]

# Property tests are derandomized everywhere (make test, CI, a developer's run): the examples
# depend only on the test, so a suite never fails by chance, and with no example database a
# failure found once cannot be replayed into later runs (a fresh clone behaves like any other).
# A failure prints its reproduction (@reproduce_failure blob) instead. To hunt for new failures
# with random examples: QFG_HYPOTHESIS_PROFILE=explore pytest ...
settings.register_profile("ci", derandomize=True, database=None, print_blob=True)
settings.register_profile("explore", derandomize=False, database=None, print_blob=True)
settings.load_profile(os.environ.get("QFG_HYPOTHESIS_PROFILE", "ci"))


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
