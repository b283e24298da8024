import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

REPO = Path(__file__).resolve().parents[1]

# Property tests are derandomized everywhere (make test, CI, a developer's run): the examples
# depend only on the test, so a suite never fails by chance, and with no example database a
# failure found once cannot be replayed into later runs (a fresh clone behaves like any other).
# Nothing may depend on the machine's speed either: no deadline, no too_slow health check.
# A failure prints its reproduction (@reproduce_failure blob) instead. To hunt for new failures
# with random examples: QFG_HYPOTHESIS_PROFILE=explore pytest ...
settings.register_profile("ci", derandomize=True, database=None, print_blob=True, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("explore", derandomize=False, database=None, print_blob=True,
                          deadline=None)
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
