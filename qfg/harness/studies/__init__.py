"""The studies and their registry: one module each, exposing ``STUDY`` (a
:class:`qfg.harness.runner.Study`).

Their presets (the parameters of ``--preset quick|paper``) are in the repository's
``experiments/<name>.toml``. The registry lives here, not in the runner, so that the runner knows
nothing of the studies (every study imports the runner; the runner imports no study).
"""

from __future__ import annotations

import importlib
import pkgutil

from qfg.harness.runner import RunnerError, Study

__all__ = ["studies", "get_study"]


def studies() -> dict[str, Study]:
    """Every study module of this package, by study name."""
    found = {}
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        mod = importlib.import_module(f"{__name__}.{info.name}")
        st = getattr(mod, "STUDY", None)
        if isinstance(st, Study):
            found[st.name] = st
    return found


def get_study(name: str) -> Study:
    """The study called ``name``; RunnerError listing the known ones otherwise."""
    found = studies()
    if name not in found:
        raise RunnerError(f"study: unknown {name!r}; known: {', '.join(sorted(found)) or 'none'}")
    return found[name]
